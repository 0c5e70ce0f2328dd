"""Shared pieces of the lubrig_ros nodes: parameters from the contract, run selection, loops.

Topic names, types, QoS and the node parameters live in app/contract.py (docs/topics.md,
docs/nodes.md); names there are relative to the node's namespace (DEFAULT_NAMESPACE /lubrig unless
the node is started with `--ros-args -r __ns:=/other`), except /clock and /diagnostics.
"""

from __future__ import annotations

import gc
import math
import os
from collections.abc import Callable, Iterable, Mapping
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

from ..app import contract
from ..app.contract import DEFAULT_NAMESPACE, NodeParameter
from ..app.diagnostics import Status
from ..app.selection import base_config
from ..app.timing import DeadlineLoop
from ..core.params import ParameterError
from ..core.presets import RunConfig
from .interfaces import qos_profile

#: rclpy QoS profiles of the contract's plain-data QoS (app/contract.py).
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


def declare(node: Node, spec: NodeParameter, default: Any = None) -> Any:
    """Declare one contract parameter (description, unit, read-only) and return its checked value.

    `default` is used when the contract's default is None (a value from the run configuration).
    ParameterError (exit status 2 in spin_node) when the value is not valid for the contract.
    (Ranges are checked here, with the contract's message, not in the descriptor.)
    """
    value = spec.default if spec.default is not None else default
    text = spec.description + (f" [{spec.unit}]" if spec.unit and spec.unit not in ("1", "SI") else "")
    declared = node.declare_parameter(spec.name, value, descriptor(text, read_only=spec.read_only))
    return spec.check(declared.value)


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


def diagnostic_status(status: Status) -> DiagnosticStatus:
    """The DiagnosticStatus message of a plain-data status."""
    msg = DiagnosticStatus(name=status.name, hardware_id=status.hardware_id, message=status.message)
    msg.level = _LEVELS[status.level]
    msg.values = [KeyValue(key=k, value=v) for k, v in status.values]
    return msg


def enter_realtime(priority: int, node: Node) -> None:
    """Put every thread of this process under SCHED_FIFO; without the privilege, warn and go on.

    All threads, not only the loop: the loop needs the GIL, and a normal-priority thread that
    holds it while preempted by another process would delay the loop by a whole time slice
    (priority inversion; measured up to 18 ms late ticks). Threads started later inherit it.
    """
    if priority <= 0:
        return
    try:
        for tid in os.listdir("/proc/self/task"):
            os.sched_setscheduler(int(tid), os.SCHED_FIFO, os.sched_param(priority))
    except (PermissionError, OSError, AttributeError) as exc:
        node.get_logger().warning(
            f"realtime_priority={priority}: SCHED_FIFO not available ({exc}); ticks may be late "
            "under load (grant CAP_SYS_NICE or an rtprio limit, or set realtime_priority:=0)"
        )
        return
    gc.freeze()  # objects made so far are never scanned again: shorter collector pauses


def subscribed_by(node: Node, topics: Iterable[str], prefix: str) -> bool:
    """True when every topic has a discovered subscription from a node named prefix*."""
    if not prefix:
        return True
    return all(
        any(info.node_name.startswith(prefix) for info in node.get_subscriptions_info_by_topic(t))
        for t in topics
    )


def finite(value: float) -> bool:
    """True for a finite float."""
    return isinstance(value, float | int) and math.isfinite(value)


def spin_node(make_node: Callable[[], Node], args: list[str] | None = None) -> int:
    """rclpy.init, build the node, spin until SIGINT/SIGTERM, destroy, shut down; exit status."""
    rclpy.init(args=args)
    node: Node | None = None
    status = 0
    try:
        node = make_node()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        executor.spin()
    except (ParameterError, ParameterException) as exc:
        # ParameterException: e.g. `-p duration:=20` (an integer) for a double parameter
        (node.get_logger() if node else rclpy.logging.get_logger("lubrig")).fatal(str(exc))
        status = 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RuntimeError:
        # After SIGINT/SIGTERM rclpy shuts the context down under a running executor; a take on a
        # subscription whose handle is already gone then raises a RuntimeError ("Unable to convert
        # call argument"), which is part of stopping, not a failure. Anything else is re-raised.
        if rclpy.ok():
            raise
    finally:
        if node is not None:
            close = getattr(node, "close", None)
            if close is not None:
                close()
            node.destroy_node()
        rclpy.try_shutdown()
    return status


__all__ = [
    "ANALYSIS_QOS",
    "DEFAULT_NAMESPACE",
    "LATCHED_QOS",
    "STREAM_QOS",
    "DeadlineLoop",  # from app.timing (belt_drive)
    "declare",
    "declare_parameters",
    "declare_run_selection",
    "diagnostic_status",
    "spin_node",
]
