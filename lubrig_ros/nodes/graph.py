"""What a rig node sees of the ROS graph: who else holds its namespace, who publishes band input.

The rules are ROS-free (app/processes/discovery.py: `rig_occupants`, `extra_publishers`,
`band_source_problem`); this module asks rclpy for the graph and acts on the answer:

- `NamespaceGuard`: a node's start-up (the plant's). For `settle` s of discovery it looks for
  another node of its own name, another publisher of its outputs, or a `lubrig rig` launcher's
  node in its namespace (another rig there, or starting: two `lubrig rig` without --namespace).
  Found: one FATAL line naming them, and the node ends with exit status 2. Not found: `clear`
  is set, and the node's run may start. A settle of 0 is no check: `lubrig rig`'s plant, whose
  launcher has checked and holds the namespace.
- `band_source_status`: the "band sources" diagnostic status, WARN naming every publisher of
  band input besides the declared source (every mode; the plant's diagnostics carry it).
- `delivers_to`: whether a sample published now reaches a named node (its subscriptions
  discovered and matched by the publishers).
- `reads_source` / `await_source`: whether a sample of the declared band source reaches a band
  reader (the reader's half of a match); hold a wall-clock loop until it does.
- `await_subscriber`: hold a wall-clock loop until a named node has subscribed and reported.
- `CallerReports`: name the client node of every request a service receives.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from typing import Any

from rclpy.node import Node
from rclpy.qos import QoSCompatibility, ReliabilityPolicy, qos_check_compatible

from ..app.interface.diagnostics import Status
from ..app.processes.discovery import (
    CALLER_SETTLE_S,
    GRAPH_SETTLE_S,
    CallerQueue,
    ClientEndpoint,
    Endpoint,
    band_source_problem,
    extra_publishers,
    fully_qualified,
)
from ..app.processes.rig_plan import LAUNCHER_NODE
from .common import steady_timer
from .interfaces import message_type

#: Exit status of a node that would run where another rig runs (a user's choice of namespace).
EXIT_NAMESPACE_TAKEN = 2
#: s between looks at the graph while the guard waits for discovery to settle.
GUARD_PERIOD_S = 0.1
#: s between looks at the graph while a service request's client is not named yet.
CALLER_PERIOD_S = 0.05


def graph_publishers(node: Node, topics: Iterable[str]) -> dict[str, list[Endpoint]]:
    """Topic → (namespace, name) of every publisher the node sees on it (app.processes.discovery's input)."""
    return {
        t: [(i.node_namespace, i.node_name) for i in node.get_publishers_info_by_topic(t)] for t in topics
    }


def namespace_taken(node: Node, topics: Iterable[str]) -> str:
    """One line naming the other rig's nodes in `node`'s namespace, or "" if none is seen.

    Another rig: a second node of `node`'s fully qualified name, a publisher of one of `topics`
    (the node's own outputs, one publisher each) other than `node`, or a `lubrig rig` launcher's
    node (a rig started there, its nodes perhaps not yet on the graph).
    """
    own = node.get_fully_qualified_name()
    launcher = fully_qualified(node.get_namespace(), LAUNCHER_NODE)
    names = [fully_qualified(ns, n) for n, ns in node.get_node_names_and_namespaces()]
    others = set(extra_publishers(graph_publishers(node, topics), own))
    if names.count(own) > 1:
        others.add(own)
    if launcher in names:
        others.add(launcher)
    if not others:
        return ""
    return (
        f"namespace {node.get_namespace()} is taken on ROS_DOMAIN_ID {node.context.get_domain_id()}: "
        f"another rig runs there ({', '.join(sorted(others))}); this {node.get_name()} does not "
        "start (run the rig in another namespace: lubrig rig --namespace NS, or -r __ns:=NS)"
    )


class NamespaceGuard:
    """The start-up check of `node` (see module docstring); `clear` is set once it has passed."""

    def __init__(self, node: Node, topics: Iterable[str], settle: float = GRAPH_SETTLE_S) -> None:
        self.node, self.topics = node, tuple(topics)
        self.end = time.monotonic() + settle
        self.clear = threading.Event()
        if settle <= 0.0:  # no check: the launcher holds the namespace
            self.clear.set()
            return
        self._timer = steady_timer(node, GUARD_PERIOD_S, self._look)

    def _look(self) -> None:
        verdict = namespace_taken(self.node, self.topics)
        if not verdict and time.monotonic() < self.end:
            return  # discovery still settling
        self._timer.cancel()
        if not verdict:
            self.clear.set()
            return
        self.node.exit_status = EXIT_NAMESPACE_TAKEN  # type: ignore[attr-defined]
        self.node.get_logger().fatal(verdict)
        # the node ends as on a Ctrl-C (spin_node); sent once this callback has returned, so that
        # the interrupt does not land in it (the executor would report it as the callback's error)
        ender = threading.Timer(GUARD_PERIOD_S, os.kill, (os.getpid(), signal.SIGINT))
        ender.daemon = True
        ender.start()


def band_source_status(node: Node, readers: Iterable[Any], source: str, hardware_id: str) -> Status:
    """The "band sources" status: WARN naming each publisher of the `readers`' topics but `source`."""
    publishers = graph_publishers(node, (r.topic_name for r in readers))
    problem = band_source_problem(publishers, source, node.get_namespace())
    seen = sorted({fully_qualified(ns, n) for ends in publishers.values() for ns, n in ends})
    return Status(
        name="band sources",
        hardware_id=hardware_id,
        level="warn" if problem else "ok",
        message=problem or "ok",
        values=(("declared_source", source or "(any one)"), ("publishers", ", ".join(seen) or "none")),
    )


def takes_every_sample(subscription: Any, publisher: Any) -> bool:
    """True when a discovered subscription (graph info) can get every sample the publisher sends.

    For a reliable publisher only a reliable subscription can: a best-effort one takes what
    reaches it. Each node with use_sim_time holds such a best-effort /clock reader (rclpy's
    TimeSource); it is no sign that the node records /clock.
    """
    reliable = ReliabilityPolicy.RELIABLE
    return publisher.qos_profile.reliability != reliable or subscription.qos_profile.reliability == reliable


def subscribed_by(node: Node, publishers: Iterable[Any], prefix: str) -> bool:
    """True when every publisher's topic has a subscription from a node named prefix* that takes every sample.

    Discovered subscriptions only (`takes_every_sample`); with an empty prefix, from any node.
    """
    return all(
        any(
            info.node_name.startswith(prefix) and takes_every_sample(info, p)
            for info in node.get_subscriptions_info_by_topic(p.topic_name)
        )
        for p in publishers
    )


def compatible_subscriptions(node: Node, publisher: Any) -> int | None:
    """Discovered subscriptions to the publisher's topic that it can match; None before it is seen.

    Its type and a QoS it serves, compared as the graph holds both (a local profile's unset
    deadline reads 0 where the graph's reads infinite, and the two would not compare).
    """
    msgtype = message_type(publisher.msg_type)
    own = [
        info.qos_profile
        for info in node.get_publishers_info_by_topic(publisher.topic_name)
        if (info.node_name, info.node_namespace) == (node.get_name(), node.get_namespace())
        and info.topic_type == msgtype
    ]
    if not own:
        return None
    return sum(
        1
        for info in node.get_subscriptions_info_by_topic(publisher.topic_name)
        if info.topic_type == msgtype
        and qos_check_compatible(own[0], info.qos_profile)[0] != QoSCompatibility.ERROR
    )


def matched_every_subscription(node: Node, publisher: Any) -> bool:
    """True when the publisher has matched every discovered subscription it can match.

    The graph and the writer learn of a subscription each on its own: a subscription can be on the
    graph before the writer has matched it, and a sample published in between never reaches it
    (volatile durability; a reliable writer repairs only what it sent after the match). A
    subscription of another type, or with a QoS the publisher's cannot serve, never matches and
    is not waited for (`compatible_subscriptions`).
    """
    compatible = compatible_subscriptions(node, publisher)
    return compatible is not None and publisher.get_subscription_count() >= compatible


def delivers_to(node: Node, publishers: Sequence[Any], prefix: str) -> bool:
    """True when a sample published now on every publisher reaches a node named prefix*.

    Its subscription to each topic is discovered and takes every sample (`subscribed_by`), and
    each publisher has matched every subscription discovered (`matched_every_subscription`: a
    count of matched readers alone could be another node's). With an empty prefix: every
    discovered subscription matched, whoever holds it, and none need be there.
    """
    matched = all(matched_every_subscription(node, p) for p in publishers)
    return matched and (not prefix or subscribed_by(node, publishers, prefix))


def reads_source(node: Node, readers: Sequence[Any], source: str) -> bool:
    """True when a sample the declared band `source` sends now reaches one of the `readers`.

    `source`: a node name in `node`'s namespace or a fully qualified one. It publishes on the
    reader's topic, and the reader has matched every discovered publisher of it that it can
    match: a reader drops what a writer sends before the reader has matched that writer
    (volatile), whether or not the writer has matched the reader (the other half: the writer's
    `delivers_to`). Another publisher's match alone (a view's, a stray one's) does not pass.
    """
    expected = source if source.startswith("/") else fully_qualified(node.get_namespace(), source)
    own_name = (node.get_name(), node.get_namespace())
    for reader in readers:
        topic = reader.topic_name
        own = [
            i
            for i in node.get_subscriptions_info_by_topic(topic)
            if (i.node_name, i.node_namespace) == own_name
        ]
        writers = [
            i for i in node.get_publishers_info_by_topic(topic) if own and i.topic_type == own[0].topic_type
        ]
        if expected not in (fully_qualified(i.node_namespace, i.node_name) for i in writers):
            continue
        compatible = sum(
            1
            for i in writers
            if qos_check_compatible(i.qos_profile, own[0].qos_profile)[0] != QoSCompatibility.ERROR
        )
        if reader.get_publisher_count() >= compatible:
            return True
    return False


def await_source(node: Node, readers: Sequence[Any], source: str, stop: threading.Event) -> bool:
    """Hold a wall-clock loop until the band `source` reaches a reader (`reads_source`); False if `stop`."""
    waited = time.monotonic()
    while not reads_source(node, readers, source):
        if stop.wait(0.05):
            return False
        if time.monotonic() - waited > 5.0:
            waited = time.monotonic()
            node.get_logger().info(f"{node.get_name()}: waiting for band input from {source} (band_source)")
    return True


def await_subscriber(
    node: Node,
    publishers: Sequence[Any],
    prefix: str,
    stop: threading.Event,
    heard: Callable[[], bool],
    progress_wait: float,
) -> bool:
    """Hold a wall-clock loop until node prefix* takes every publisher's topic; False if `stop` meanwhile.

    Its subscriptions in the graph and matched by these publishers (samples published before the
    match would be lost; discovery matches each endpoint on its own, and under load one topic
    matched 1.2 s after another of the same subscriber process), then its flow_progress
    (`heard()`: the recorder reports once its own readers have matched, state_block's and those of
    its required streams: a writer's match alone is half of one); a consumer
    that reports none gets `progress_wait` s of discovery.
    """
    log = node.get_logger()
    names = [p.topic_name for p in publishers]
    log.info(
        f"realtime: waiting for {prefix}* to subscribe to {', '.join(n.rsplit('/', 1)[-1] for n in names)}"
    )
    while not delivers_to(node, publishers, prefix):
        if stop.wait(0.05):
            return False
    end = time.monotonic() + progress_wait
    while not heard() and time.monotonic() < end:
        if stop.wait(0.05):
            return False
    if not heard():
        log.warning(
            f"realtime: no flow_progress from {prefix}* within {progress_wait:g} s of its "
            "subscription; starting (its first samples may be lost)"
        )
    log.info(f"realtime: {prefix}* subscribed; the loop starts")
    return True


class CallerReports:
    """Name the client of every request `service` receives: report("/ns/node (request N)").

    rclpy hands a service callback the request only; the middleware knows the client's GID.
    Service introspection (metadata only: no request or response contents) publishes it on
    ``<service>/_service_event`` (what ``ros2 service echo`` reads); this subscribes to that
    topic and looks the GID up in the ROS graph: the client's request writer
    (``rq<service>Request``) or reply reader (``rr<service>Reply``), whichever the rmw puts in
    the request header, belongs to the client's node (app/processes/discovery.py: `client_name`).
    The report comes just after the callback (the event travels through DDS), or, while the graph
    does not know the client's node yet, up to CALLER_SETTLE_S later (`CallerQueue`).
    """

    def __init__(
        self, node: Node, service: Any, report: Callable[[str], None], settle: float = CALLER_SETTLE_S
    ) -> None:
        from rclpy.qos import qos_profile_services_default
        from rclpy.service_introspection import ServiceIntrospectionState
        from service_msgs.msg import ServiceEventInfo

        self._node, self._report, self._name = node, report, service.service_name
        self._received = ServiceEventInfo.REQUEST_RECEIVED
        self.queue = CallerQueue(settle)  # the requests whose client is not named yet
        self._lock = threading.Lock()  # flush() may come from another thread than the executor's
        self._timer: Any = None
        service.configure_introspection(
            node.get_clock(), qos_profile_services_default, ServiceIntrospectionState.METADATA
        )
        events = f"{self._name}/_service_event"
        self.subscription = node.create_subscription(
            service.srv_type.Event, events, self._on_event, qos_profile_services_default
        )

    def _on_event(self, event: Any) -> None:
        if event.info.event_type == self._received:
            with self._lock:
                self.queue.add(bytes(event.info.client_gid), event.info.sequence_number, time.monotonic())
            self._drain()

    def _endpoints(self) -> list[ClientEndpoint]:
        """The service's client endpoints in the graph now (request writers, reply readers)."""
        infos = [
            *self._node.get_publishers_info_by_topic(f"rq{self._name}Request", no_mangle=True),
            *self._node.get_subscriptions_info_by_topic(f"rr{self._name}Reply", no_mangle=True),
        ]
        return [(bytes(i.endpoint_gid), i.node_namespace, i.node_name) for i in infos]

    def _drain(self) -> None:
        endpoints = self._endpoints()
        with self._lock:
            lines = self.queue.ready(endpoints, time.monotonic())
        for line in lines:
            self._report(line)
        if not self.queue:
            if self._timer is not None:
                self._timer.cancel()
        elif self._timer is None:
            self._timer = steady_timer(self._node, CALLER_PERIOD_S, self._drain)
        elif self._timer.is_canceled():
            self._timer.reset()

    def flush(self) -> None:
        """Report every request still waiting for its client's name (the node stops)."""
        try:
            endpoints: list[ClientEndpoint] | None = self._endpoints()
        except RuntimeError:  # the context is shut down (a stop by signal): no graph to ask
            endpoints = None
        with self._lock:
            lines = self.queue.flush(endpoints)
        for line in lines:
            self._report(line)
