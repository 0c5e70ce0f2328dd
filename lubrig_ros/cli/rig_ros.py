"""`lubrig rig`'s own ROS participant: is the namespace free (before the nodes start), is the run over.

`LauncherPresence` is the launcher's node, <namespace>/LAUNCHER_NODE (app/processes/rig_plan.py),
on the graph from the namespace check until the rig's nodes have stopped. `namespace_taken` looks
at the graph after GRAPH_SETTLE_S (app/processes/discovery.py): another rig's nodes in the
namespace (plant, belt_drive, analysis, the recorder's), another launcher's node (a rig starting
there), or any publisher of a topic in it, make the namespace taken, and `lubrig rig` refuses to
start there (two rigs in one namespace would both run, each bag holding both rigs' samples).
Whatever starts in the namespace later sees this launcher's node: another launcher in its own
check, a plant in its start-up check (nodes/graph.py); so the rig's own plant needs no check.

`wait_complete` (sim) waits for the plant's latched run_complete, gives up on a stalled run.
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Callable
from typing import Any

from ..app.processes.discovery import GRAPH_SETTLE_S, fully_qualified, rig_occupants
from ..app.processes.rig_plan import LAUNCHER_NODE, NODES, RECORDER_NODE_PREFIX
from .progress import Progress

#: Sim: end the run (non-zero) once the plant has reported it stalled this long without a break
#: (a run that cannot progress; a loaded machine's pauses of a few seconds are not one).
STALL_GIVE_UP_S = 15.0
#: Sim, recorded: after run_complete, longest wait (s) for the recorder to hold every sample.
RECORDER_HOLD_S = 5.0


class LauncherPresence:
    """The launcher's context and node in `namespace`, made on first use, until `close`.

    The node is <namespace>/LAUNCHER_NODE: rigs in other namespaces on the domain each have
    their own launcher node, not one name shared by several. No services (nodes/common.py
    `unspun_node`): nothing spins it during the check, nor while the rig runs in wall-clock modes.

    Without rclpy's signal handlers: a Ctrl-C reaches the launcher's Python handler directly (a
    KeyboardInterrupt in its main thread, which stops the rig). With them installed by the graph
    guard's context, a launcher in its realtime wait (plain sleeps, no rclpy) once did not see a
    SIGINT within 60 s.
    """

    def __init__(self, namespace: str) -> None:
        self.namespace = namespace
        self._made: tuple[Any, Any] | None = None
        self.made_at = 0.0  # time.monotonic() when the node was made

    def _make(self) -> tuple[Any, Any]:
        if self._made is None:
            import rclpy
            from rclpy.context import Context
            from rclpy.signals import SignalHandlerOptions

            from ..nodes.common import unspun_node

            context = Context()
            rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
            self._made = (context, unspun_node(LAUNCHER_NODE, self.namespace, context))
            self.made_at = time.monotonic()
        return self._made

    def make(self) -> None:
        """Make the context and the node now (a no-op once made)."""
        self._make()

    @property
    def context(self) -> Any:
        """The launcher's rclpy context (made with the node)."""
        return self._make()[0]

    @property
    def node(self) -> Any:
        """The launcher's node."""
        return self._make()[1]

    def close(self) -> None:
        """Leave the graph (a no-op if the node was never made)."""
        if self._made is not None:
            context, node = self._made
            self._made = None
            node.destroy_node()
            context.try_shutdown()


def _occupants(node: Any, namespace: str) -> list[str]:
    """Who the launcher's node sees holding `namespace` (app.processes.discovery.rig_occupants).

    Another launcher's node has this one's name: it shows as a second node of that name.
    """
    prefix = namespace.rstrip("/") + "/"
    names = (t for t, _types in node.get_topic_names_and_types())
    topics = [t for t in names if t.startswith(prefix) and "/" not in t[len(prefix) :]]
    publishers = {
        t: [(i.node_namespace, i.node_name) for i in node.get_publishers_info_by_topic(t)] for t in topics
    }
    nodes = [(ns, n) for n, ns in node.get_node_names_and_namespaces()]
    own = fully_qualified(node.get_namespace(), LAUNCHER_NODE)
    held = [
        h for h in rig_occupants(namespace, nodes, publishers, (*NODES, RECORDER_NODE_PREFIX)) if h != own
    ]
    if [fully_qualified(ns, n) for ns, n in nodes].count(own) > 1:
        held.append(own)
    return sorted(held)


def namespace_taken(presence: LauncherPresence, settle: float = GRAPH_SETTLE_S) -> str:
    """One line naming the rig that holds the presence's namespace on this domain, or "" (after `settle` s).

    The graph is read once the presence's node has existed for `settle` s of discovery (rmw's
    discovery keeps the graph up to date meanwhile; a rig seen then is named with all of its
    nodes discovered by then): `lubrig rig` makes the node before it starts the node processes
    (cli/rig.py), so that their imports do not delay it and the wait counts from then.
    One look, not a poll: the node processes import beside this wait (cli/rig_gate.py), and CPU
    spent here is taken from them. The presence stays on the graph either way (`close` ends it).
    """
    node, namespace = presence.node, presence.namespace
    time.sleep(max(0.0, settle - (time.monotonic() - presence.made_at)))
    held = _occupants(node, namespace)
    if not held:
        return ""
    return (
        f"--namespace {namespace} is taken on ROS_DOMAIN_ID {node.context.get_domain_id()}: another "
        f"rig runs there ({', '.join(held)}); give this rig a namespace of its own (e.g. --namespace "
        f"{namespace.rstrip('/')}_2) or stop that rig"
    )


def wait_complete(
    presence: LauncherPresence,
    deadline: float,
    procs: dict[str, subprocess.Popen],
    progress: Progress | None = None,
    stall: list[str] | None = None,
    interrupted: Callable[[], bool] = lambda: False,
    recorder: str = "",
) -> bool:
    """Sim: wait for <ns>/run_complete = true (latched) from the plant (rig time from /clock).

    Gives up early when the plant has reported its run stalled (timing status ERROR) for
    STALL_GIVE_UP_S without a break; the plant's line is appended to `stall`; returns at once
    when `interrupted()` (the launcher's Ctrl-C). With `recorder` (its participant name), then
    `_await_recorder`: the nodes are stopped only once the bag holds what they sent.
    """
    from std_msgs.msg import Bool

    from ..app.interface import contract
    from ..nodes.interfaces import message_class, qos_profile

    namespace, context, node = presence.namespace, presence.context, presence.node
    spec = contract.topic("run_complete").resolved(namespace)
    done = []
    node.create_subscription(
        Bool, spec.name, lambda m: done.append(True) if m.data else None, qos_profile(spec.qos)
    )
    if progress is not None and progress.enabled:  # rig time on a terminal: the plant's /clock
        from rosgraph_msgs.msg import Clock

        node.create_subscription(
            Clock,
            "/clock",
            lambda m: progress.update(m.clock.sec + 1e-9 * m.clock.nanosec),
            qos_profile(contract.topic("/clock").qos),
        )
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus

    timing = f"{contract.resolve(namespace, 'plant')}: timing"
    stalled_since: list[float] = []
    stall_text: list[str] = []

    def on_diagnostics(array: DiagnosticArray) -> None:
        for status in array.status:
            if status.name != timing:
                continue
            if status.level == DiagnosticStatus.ERROR and status.message.startswith("stalled"):
                stalled_since[:] = stalled_since or [time.monotonic()]
                stall_text[:] = [status.message]
            else:
                stalled_since.clear()

    node.create_subscription(
        DiagnosticArray, "/diagnostics", on_diagnostics, qos_profile(contract.topic("/diagnostics").qos)
    )
    reports: dict[str, tuple[int, int]] = {}  # participant -> its newest (segment, samples)
    after_complete: list[str] = []  # participants heard from once run_complete had come

    def on_progress(msg: Any) -> None:
        newest = (int(msg.segment), int(msg.samples))
        reports[msg.participant] = max(reports.get(msg.participant, newest), newest)
        if done:
            after_complete.append(msg.participant)

    if recorder:
        flow = contract.topic("flow_progress").resolved(namespace)
        node.create_subscription(message_class(flow.msgtype), flow.name, on_progress, qos_profile(flow.qos))
    from rclpy.executors import SingleThreadedExecutor

    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        while not done and time.monotonic() < deadline and not interrupted():
            if any(p.poll() is not None for p in procs.values()):
                break
            if stalled_since and time.monotonic() - stalled_since[0] >= STALL_GIVE_UP_S:
                if stall is not None:
                    stall.append(f"{timing}: {stall_text[0]}")
                break
            _spin_once(executor, 0.1, interrupted)  # a Ctrl-C: KeyboardInterrupt when the wait ends
        if done and recorder:
            hold = (recorder, contract.resolve(namespace, "plant"))
            _await_recorder(hold, reports, after_complete, executor, procs, interrupted)
    finally:
        executor.shutdown(timeout_sec=1.0)  # before the context: no Executor.__del__ traceback
        for subscription in list(node.subscriptions):  # the node stays until the rig has stopped
            node.destroy_subscription(subscription)
    return bool(done)


def _spin_once(executor: Any, timeout: float, interrupted: Callable[[], bool]) -> None:
    """executor.spin_once; a Ctrl-C inside it comes out as KeyboardInterrupt.

    The launcher's SIGINT handler raises KeyboardInterrupt (cli/rig_supervisor.catch_ctrl_c). Raised
    while rclpy's C++ code takes a message, pybind11 turns it into a RuntimeError ("Unable to
    convert call argument"); with the Ctrl-C seen (`interrupted`) that is the interrupt.
    """
    try:
        executor.spin_once(timeout_sec=timeout)
    except RuntimeError:
        if interrupted():
            raise KeyboardInterrupt from None
        raise


def holds_all(hold: tuple[str, str], reports: dict[str, tuple[int, int]], after_complete: list[str]) -> bool:
    """True when the recorder's newest (segment, samples) reaches the plant's, one sent after run_complete."""
    recorder, plant = hold
    return plant in after_complete and reports.get(recorder, (-1, -1)) >= reports[plant]


def _await_recorder(
    hold: tuple[str, str],
    reports: dict[str, tuple[int, int]],
    after_complete: list[str],
    executor: Any,
    procs: dict[str, subprocess.Popen],
    interrupted: Callable[[], bool],
) -> None:
    """After run_complete: spin until the recorder reports every sample the plant reported.

    `hold`: the (recorder, plant) participant names; `reports`: the newest (segment, samples) of
    each; the plant's count must be one sent after run_complete (`after_complete`). A copy of a
    block lost on the way is sent again when the reader answers the writer's next heartbeat
    (config/fastdds_localhost.xml), and a writer stopped before that takes the sample with it:
    the recorder's FlowProgress counts only samples it holds of band and state
    (bag/recording.py `reach`). RECORDER_HOLD_S at most; then one line, and the nodes are
    stopped (the recorder's accounting then names what the bag lacks).
    """
    recorder, plant = hold
    end = time.monotonic() + RECORDER_HOLD_S
    while not holds_all(hold, reports, after_complete):
        if interrupted() or any(p.poll() is not None for p in procs.values()):
            return
        if time.monotonic() >= end:
            print(
                f"lubrig rig: {RECORDER_HOLD_S:g} s after run_complete the recorder holds (segment, "
                f"samples) {reports.get(recorder)} of the plant's {reports.get(plant)}; stopping the nodes",
                file=sys.stderr,
                flush=True,
            )
            return
        _spin_once(executor, 0.05, interrupted)
