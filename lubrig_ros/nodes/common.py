"""Shared pieces of the lubrig_ros nodes: parameters from the contract, run selection, loops.

Topic names, types, QoS and the node parameters live in app/interface/contract.py (docs/topics.md,
docs/nodes.md); names there are relative to the node's namespace (DEFAULT_NAMESPACE /lubrig unless
the node is started with `--ros-args -r __ns:=/other`), except /clock and /diagnostics.
"""

from __future__ import annotations

import array
import contextlib
import math
import os
import signal
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from typing import Any

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter

from ..app.interface import contract
from ..app.interface.contract import DEFAULT_NAMESPACE, NodeParameter
from ..app.interface.diagnostics import Status
from ..app.processes import startup_trace
from ..app.selection import base_config
from ..app.timing import DeadlineLoop
from ..core.params import ParameterError
from ..core.presets import RunConfig
from .interfaces import qos_profile
from .script import bounded_teardown

#: rclpy QoS profiles of the contract's plain-data QoS (app/interface/contract.py).
STREAM_QOS = qos_profile(contract.STREAM_QOS)
ANALYSIS_QOS = qos_profile(contract.ANALYSIS_QOS)
LATCHED_QOS = qos_profile(contract.LATCHED_QOS)
_LEVELS = {"ok": DiagnosticStatus.OK, "warn": DiagnosticStatus.WARN, "error": DiagnosticStatus.ERROR}


def descriptor(
    text: str,
    *,
    read_only: bool = False,
    low: float | None = None,
    high: float | None = None,
    dynamic_typing: bool = False,
) -> ParameterDescriptor:
    """Parameter descriptor with a description and optional float range."""
    desc = ParameterDescriptor(description=text, read_only=read_only, dynamic_typing=dynamic_typing)
    if low is not None and high is not None:
        desc.floating_point_range = [FloatingPointRange(from_value=low, to_value=high, step=0.0)]
    return desc


_INT64 = (-(2**63), 2**63 - 1)


def describe(spec: NodeParameter, template: ParameterDescriptor | None = None) -> ParameterDescriptor:
    """The full descriptor of a contract parameter: description (unit, valid values), read-only, range.

    Numbers with a bound get `floating_point_range` / `integer_range` (a one-sided bound has the
    other end at ±inf, or the int64 limits), so `ros2 param describe` shows it and rclpy refuses
    values outside it. The range is closed; an open lower bound (`low_open`: "> 0") is refused
    at its end by the contract's own check (`check_updates`). `template` (the declared
    descriptor) keeps rclpy's type fields.
    """
    unit = f" [{spec.unit}]" if spec.unit and spec.unit not in ("1", "SI") else ""
    desc = ParameterDescriptor()
    if template is not None:
        desc.type, desc.dynamic_typing = template.type, template.dynamic_typing
    desc.name = spec.name
    desc.description = f"{spec.description}{unit}"
    desc.additional_constraints = f"valid: {spec.expected()}"
    desc.read_only = spec.read_only
    if spec.low is not None or spec.high is not None:
        if spec.type == "double":
            low = -math.inf if spec.low is None else float(spec.low)
            high = math.inf if spec.high is None else float(spec.high)
            desc.floating_point_range = [FloatingPointRange(from_value=low, to_value=high, step=0.0)]
        elif spec.type == "integer":
            low_i = _INT64[0] if spec.low is None else int(spec.low)
            high_i = _INT64[1] if spec.high is None else int(spec.high)
            desc.integer_range = [IntegerRange(from_value=low_i, to_value=high_i, step=0)]
    return desc


def declare(node: Node, spec: NodeParameter, default: Any = None) -> Any:
    """Declare one contract parameter (description, unit, range, read-only); return its checked value.

    `default` is used when the contract's default is None (a value from the run configuration).
    ParameterError (exit status 2 in spin_node) when the value is not valid for the contract.
    The given value is checked by the contract first (its message names the parameter, the value
    and what is valid), then the full descriptor with the range is applied (`describe`).
    """
    value = spec.default if spec.default is not None else default
    text = ParameterDescriptor(description=spec.description)
    if spec.type == "string_array":
        # an empty list would be declared as a byte array: declare the type, no value means []
        declared: Any = node.declare_parameter(spec.name, Parameter.Type.STRING_ARRAY, text)
        given = declared.value if declared.value is not None else list(value or ())
        checked = spec.check(list(given))
        if declared.value is None:  # not given: initialize it (an uninitialized one cannot be read)
            node.set_parameters([Parameter(spec.name, Parameter.Type.STRING_ARRAY, checked)])
        node.set_descriptor(spec.name, describe(spec, node.describe_parameter(spec.name)))
        return checked
    declared = node.declare_parameter(spec.name, value, text)
    checked = spec.check(declared.value)
    node.set_descriptor(spec.name, describe(spec, node.describe_parameter(spec.name)))
    return checked


def check_updates(node: Node, specs: Iterable[NodeParameter]) -> None:
    """Check run-time updates of the contract parameters with the contract's rules.

    rclpy refuses a value outside the descriptor's range first, with its own wording ("Parameter
    rtol out of range Min: 1e-13, Max: 0.01, value: 1.0": parameter, value and range); what the
    descriptor cannot say (an open bound, a non-finite value, the choices of a string) is refused
    here with the contract's message.
    """
    by_name = {spec.name: spec for spec in specs}

    def callback(params: list[Any]) -> SetParametersResult:
        for param in params:
            spec = by_name.get(param.name)
            if spec is None:
                continue
            try:
                spec.check(param.value)
            except ParameterError as exc:
                return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(callback)


def declare_parameters(
    node: Node, specs: Iterable[NodeParameter], defaults: Mapping[str, Any] | None = None
) -> dict[str, Any]:
    """Declare the contract parameters not declared yet; {name: checked value} of all of them."""
    defaults = defaults or {}
    values = {}
    for spec in specs:
        if node.has_parameter(spec.name):
            values[spec.name] = node.get_parameter(spec.name).value
        else:
            values[spec.name] = declare(node, spec, defaults.get(spec.name))
    return values


def select_run(case: int, config_file: str) -> RunConfig:
    """The run configuration of the node parameters: case 1..10, else config_file, else default.

    (app.selection.base_config: the one run selection rule; both given is an error.)
    """
    return base_config(case, config_file)


def declare_run_selection(node: Node) -> RunConfig:
    """Declare `case`, `config_file` and `topic_namespace`; return the selected run configuration.

    The launcher passes `config_file` = the resolved run's YAML in the run folder; `case` is for
    starting a node by hand. Raises ParameterError with the offending value.

    `topic_namespace` is the deprecated way of naming the namespace: topics follow the node's
    namespace now. Empty (the default) or the node's own namespace is accepted (the latter with a
    warning); anything else is refused with the way to set the namespace, rather than silently
    running in another namespace than asked.
    """
    values = declare_parameters(node, contract.RUN_SELECTION)
    check_topic_namespace(node, values["topic_namespace"])
    return select_run(values["case"], values["config_file"])


def check_topic_namespace(node: Node, value: str) -> None:
    """Refuse a `topic_namespace` other than '' or the node's namespace (ParameterError)."""
    if not value:
        return
    namespace = node.get_namespace()
    if value == namespace:
        node.get_logger().warning(
            f"topic_namespace={value!r} is deprecated (topics follow the node namespace); drop it"
        )
        return
    contract.validate_namespace(value, "topic_namespace")
    raise ParameterError(
        f"topic_namespace={value!r} is no longer supported: topics and services follow the node "
        f"namespace ({namespace!r}); start the node with --ros-args -r __ns:={value} "
        "(launch: namespace=) instead"
    )


class ProblemLog:
    """Warn/error diagnostics also go to the node log (and /rosout), rate-limited.

    A status is logged when it becomes a problem, when its problem text changes (numbers aside),
    and at most every `every` seconds while it lasts; its recovery is logged once.
    """

    def __init__(self, node: Node, every: float = 10.0) -> None:
        self.node, self.every = node, every
        self.last: dict[str, tuple[str, float]] = {}

    def log(self, statuses: list[Status]) -> None:
        """Log the statuses that need a person's attention (see class docstring)."""
        now = time.monotonic()
        for status in statuses:
            shape = "".join(c for c in status.message if not c.isdigit())
            previous = self.last.get(status.name)
            if status.level == "ok":
                if previous is not None:
                    self.node.get_logger().info(f"{status.name}: ok again ({status.message})")
                    del self.last[status.name]
                continue
            if previous is None or previous[0] != shape or now - previous[1] >= self.every:
                log = self.node.get_logger()
                text = f"{status.name}: {status.message}"
                if status.level == "error":  # one call site per severity (rclpy's rule)
                    log.error(text)
                else:
                    log.warning(text)
                self.last[status.name] = (shape, now)


def diagnostic_status(status: Status, node: Node) -> DiagnosticStatus:
    """The DiagnosticStatus message of a plain-data status, named "<node FQN>: <status>".

    The fully qualified name tells two rigs' statuses apart on the one /diagnostics topic
    (e.g. "/rigA/plant: timing" and "/rigB/plant: timing").
    """
    name = f"{node.get_fully_qualified_name()}: {status.name}"
    msg = DiagnosticStatus(name=name, hardware_id=status.hardware_id, message=status.message)
    msg.level = _LEVELS[status.level]
    msg.values = [KeyValue(key=k, value=v) for k, v in status.values]
    return msg


def doubles(values: Any) -> array.array:
    """A float64 array as the array.array('d') rclpy takes for float64[] without a per-item check."""
    out = array.array("d")
    out.frombytes(np.ascontiguousarray(values, dtype=np.float64).tobytes())
    return out


def log_at(node: Node, level: str, text: str) -> None:
    """Log text at level "error" | "warning" | anything else: info (a session's log callback).

    One call site per severity: rclpy refuses a call site whose severity changes.
    """
    logger = node.get_logger()
    if level == "error":
        logger.error(text)
    elif level == "warning":
        logger.warning(text)
    else:
        logger.info(text)


def end_when_acked(publishers: list[Any], wait: float) -> None:
    """End the node as on a Ctrl-C (spin_node, its exit status) once readers have the last samples.

    The samples left at publish; the writers stay for a retransmit until the readers acknowledge
    them, which RTPS readers do in answer to a writer heartbeat (every 0.25 s with the rig's
    Fast DDS profile, config/fastdds_localhost.xml; 3 s, Fast DDS's default, without it, and the
    node then usually ends `wait` s after the run). Polled without waiting: a waiting call keeps
    the GIL from the node's other threads for its whole timeout.
    """
    pending = list(publishers)
    end = time.monotonic() + wait
    with contextlib.suppress(Exception):  # a stop meanwhile: the context is gone
        while pending and time.monotonic() < end:
            pending = [p for p in pending if not p.wait_for_all_acked(Duration(seconds=0))]
            time.sleep(0.01)
    os.kill(os.getpid(), signal.SIGINT)


def steady_timer(node: Node, period: float, callback: Callable[[], None]) -> Any:
    """A timer of `node` on the steady clock: it fires every `period` s of wall time in every mode.

    The nodes' heartbeats, flow-control pumps, diagnostics and analysis updates use it, never the
    node's ROS clock: with use_sim_time that clock stands still until /clock moves, and in a sim
    rig /clock only moves once those timers have started the run (they announce the plant,
    start belt_drive); with --no-clock it never moves at all.

    A stop (SIGINT: rclpy shuts the context down under the running executor) can land inside a
    callback, whose next publish or graph query then raises RuntimeError ("context is invalid");
    that is the stop, not a failure of the callback, and it ends quietly (the executor would log
    it as FATAL). Any other RuntimeError is raised.
    """

    def tick() -> None:
        try:
            callback()
        except RuntimeError:
            if not _stopping(0.5, node.context):  # the shutdown may still be in flight for a moment
                raise

    return node.create_timer(period, tick, clock=Clock(clock_type=ClockType.STEADY_TIME))


def unspun_node(name: str, namespace: str, context: Any = None, overrides: Iterable[Parameter] = ()) -> Node:
    """A node that nothing spins all the time (the launcher's, the recorder's progress node): no services.

    A service nobody answers stalls its callers: `ros2 param list` waited forever on the
    recorder's node once it had found its parameter services. So neither those nor the type
    description service.
    """
    quiet = Parameter("start_type_description_service", Parameter.Type.BOOL, False)
    return Node(
        name,
        namespace=namespace,
        context=context,
        start_parameter_services=False,
        parameter_overrides=[*overrides, quiet],
    )


def uses_sim_time(node: Node) -> bool:
    """The node's standard use_sim_time parameter (its ROS clock follows /clock when true)."""
    return bool(node.get_parameter("use_sim_time").value)


def finite(value: float) -> bool:
    """True for a finite float."""
    return isinstance(value, float | int) and math.isfinite(value)


def _stopping(wait: float, context: Any = None) -> bool:
    """True once the rclpy context (default: rclpy's) is shut down, polling up to `wait` s."""
    end = time.monotonic() + wait
    while context.ok() if context is not None else rclpy.ok():
        if time.monotonic() >= end:
            return False
        time.sleep(0.01)
    return True


#: Longest a node's spin_once waits for work (s): how soon it sees its context shut down otherwise.
SPIN_WAIT_S = 0.5

#: Set while spin_node's executor loop runs (in this process).
SPINNING = threading.Event()


def interrupt(_signum: int, _frame: Any) -> None:
    """Python's SIGINT handler of a node process (rclpy's own handler runs first and chains to it).

    A KeyboardInterrupt, as Python's default handler raises, except while spin_node's executor
    loop runs: rclpy has then shut the node's context down already, which ends the loop and stops
    the node cleanly, whereas a KeyboardInterrupt would be raised inside whatever callback the
    executor is running (a plant integrating a block), which the executor reports as a failed
    callback and the node ends with status 1.
    """
    if not SPINNING.is_set():
        raise KeyboardInterrupt


def _ignore_sigint() -> None:
    """SIGINT ignored from now on; a KeyboardInterrupt already on its way is swallowed meanwhile."""
    for _ in range(10):
        try:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
            return
        except KeyboardInterrupt:
            continue
        except ValueError:  # not the main thread: nothing to change
            return


def load_numba_target() -> None:
    """Load numba's CPU target now (its registries: about 0.4 s of CPU, numba's BLAS check too).

    Loading the first cached kernel of a process does it otherwise. A node calls this in its
    `prepare` (nodes/entry.py), while `lubrig rig`'s start gate holds it; numba is imported here,
    not with this module (belt_drive and the recorder need none).
    """
    from numba.core.registry import cpu_target

    cpu_target.target_context.refresh()


def spin_node(make_node: Callable[[], Node], args: list[str] | None = None) -> int:
    """rclpy.init, build the node, spin until SIGINT/SIGTERM, destroy, shut down; exit status.

    The executor is rclpy's EventsExecutor (the C++ events queue: about a tenth of
    SingleThreadedExecutor's cost per message, which rebuilds its wait set in Python at every
    wake-up), driven by spin_once: its spin() fires no timer in this rclpy and keeps a core busy
    (../shared/ros2-interfaces-on-pip.md); the context's shutdown wakes spin_once.
    """
    node: Node | None = None
    executor: Any = None
    status = 0
    # A SIGINT while the node is being built (compiled kernels load then, through ctypes
    # callbacks that print and drop a KeyboardInterrupt) waits until it is built: then rclpy's
    # handler stops it cleanly. Threads started meanwhile keep it blocked (the main thread takes it).
    stopping = {signal.SIGINT, signal.SIGTERM}
    signal.pthread_sigmask(signal.SIG_BLOCK, stopping)
    try:
        rclpy.init(args=args)
        try:
            node = make_node()
        finally:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, stopping)
        startup_trace.mark(node.get_name(), "node created")
        executor = EventsExecutor(context=node.context)
        executor.add_node(node)
        SPINNING.set()
        while node.context.ok():
            executor.spin_once(timeout_sec=SPIN_WAIT_S)
    except (ParameterError, ParameterException) as exc:
        # ParameterException: e.g. `-p duration:=20` (an integer) for a double parameter
        (node.get_logger() if node else rclpy.logging.get_logger("lubrig")).fatal(str(exc))
        status = 2
    except (KeyboardInterrupt, ExternalShutdownException):
        _ignore_sigint()  # at once: one SIGINT can raise twice (rclpy's handler and Python's)
    except RuntimeError:
        # After SIGINT/SIGTERM rclpy shuts the context down under a running executor; a take on a
        # subscription whose handle is already gone then raises a RuntimeError ("Unable to convert
        # call argument"), which is part of stopping, not a failure. The shutdown may still be in
        # flight when the error comes (rclpy.ok() still true for a moment), so give it a moment;
        # anything else is re-raised.
        if not _stopping(0.5):
            raise
    finally:
        # stopping: a second SIGINT (a terminal's Ctrl-C reaches the whole process group, then the
        # launcher sends its own) must not interrupt the clean-up with a KeyboardInterrupt
        SPINNING.clear()
        _ignore_sigint()
        if node is not None:
            close = getattr(node, "close", None)
            if close is not None:
                close()
            status = status or int(getattr(node, "exit_status", 0))
        name = node.get_name() if node is not None else "lubrig"
        with bounded_teardown(name, lambda: status):
            if executor is not None:
                # first: the executor lets go of the node's handles it holds in use, so that
                # destroy_node destroys them itself (destroyed under the executor's release, a
                # handle's destruction once blocked for good); and while the context lives:
                # otherwise Executor.__del__ at exit prints an InvalidHandle traceback
                with contextlib.suppress(Exception):
                    executor.shutdown(timeout_sec=1.0)
            if node is not None:
                node.destroy_node()
            rclpy.try_shutdown()
    return status


__all__ = [
    "ANALYSIS_QOS",
    "DEFAULT_NAMESPACE",
    "LATCHED_QOS",
    "STREAM_QOS",
    "DeadlineLoop",  # from app.timing (belt_drive)
    "check_updates",
    "declare",
    "declare_parameters",
    "declare_run_selection",
    "describe",
    "diagnostic_status",
    "spin_node",
    "steady_timer",
    "uses_sim_time",
]
