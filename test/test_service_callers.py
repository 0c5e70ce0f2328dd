"""The client of every service request named (nodes/graph.py `CallerReports`), over real DDS.

The plant logs the caller of every reset and pause this way (docs/security.md). Here a server
node and callers on the test's domain, each in its own rclpy context (its own DDS participant):

- a caller is named by its node, one report per request, in order;
- a request event whose client GID is in no graph entry (published by hand on the service's
  `_service_event` topic, as any participant on the domain can) is reported as from an unknown
  client, and only once the wait for the graph is over;
- a node that stops reports what still waits: as unknown while the graph can be asked, as "not
  named" once its context is shut down.
The rules on plain graph data: test_discovery_graph.py.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator

import pytest
from lubrig_testkit.harness import Probe, wait_until
from rclpy.qos import qos_profile_services_default
from service_msgs.msg import ServiceEventInfo
from std_srvs.srv import Trigger

from lubrig_ros.nodes.graph import CallerReports

pytestmark = pytest.mark.ros

SERVICE = "/callers_test/reset"
STRANGER = bytes(range(50, 66))  # a client GID no participant has


@pytest.fixture
def server(ros_domain: int) -> Iterator[Probe]:
    probe = Probe(ros_domain, "server")
    yield probe
    probe.close()


def _serve(server: Probe, settle: float) -> tuple[list[tuple[float, str]], CallerReports]:
    reports: list[tuple[float, str]] = []

    def answer(request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        response.success = True
        return response

    service = server.node.create_service(Trigger, SERVICE, answer)
    callers = CallerReports(
        server.node, service, lambda line: reports.append((time.monotonic(), line)), settle
    )
    return reports, callers


def _fake_event(ros_domain: int, sequence: int, arrived: Callable[[], object]) -> float:
    """Publish a REQUEST_RECEIVED event from STRANGER, the sender kept until `arrived()`; when sent."""
    sender = Probe(ros_domain, "sender")
    try:
        publisher = sender.node.create_publisher(
            Trigger.Event, f"{SERVICE}/_service_event", qos_profile_services_default
        )
        wait_until(lambda: publisher.get_subscription_count() > 0, 60, "the server's event subscription")
        event = Trigger.Event()
        event.info.event_type = ServiceEventInfo.REQUEST_RECEIVED
        event.info.client_gid = list(STRANGER)
        event.info.sequence_number = sequence
        sent = time.monotonic()
        publisher.publish(event)
        wait_until(arrived, 60, "the event at the server")  # (a reliable writer until delivered)
        return sent
    finally:
        sender.close()


def test_each_request_is_reported_with_its_callers_node_in_order(server: Probe, ros_domain: int):
    reports, _ = _serve(server, settle=30.0)
    caller = Probe(ros_domain, "caller")
    try:
        for _ in range(3):
            assert caller.call(Trigger, SERVICE, Trigger.Request()).success
    finally:
        caller.close()
    wait_until(lambda: len(reports) == 3, 60, "three reports")
    # a new client per call (Probe.call): request 1 of each
    assert [line for _, line in reports] == ["/caller (request 1)"] * 3


def test_a_client_of_no_node_is_reported_unknown_once_the_wait_is_over(server: Probe, ros_domain: int):
    reports, callers = _serve(server, settle=0.5)
    sent = _fake_event(ros_domain, 7, lambda: reports or callers.queue)
    wait_until(lambda: reports, 60, "the report")
    at, line = reports[0]
    assert line == f"an unknown client (GID {STRANGER.hex()}, of no node the ROS graph knows) (request 7)"
    assert at - sent >= 0.5  # not before the settle (counted from the event's arrival, after `sent`)
    assert len(reports) == 1 and len(callers.queue) == 0


def test_a_stopping_node_reports_what_still_waits(server: Probe, ros_domain: int):
    reports, callers = _serve(server, settle=600.0)  # never reported while the test runs
    _fake_event(ros_domain, 8, lambda: callers.queue)
    assert reports == []
    callers.flush()  # the graph can still be asked: its final answer
    assert [line for _, line in reports] == [
        f"an unknown client (GID {STRANGER.hex()}, of no node the ROS graph knows) (request 8)"
    ]
    _fake_event(ros_domain, 9, lambda: callers.queue)
    server.close()  # the context shut down, as by SIGINT before Plant.close()
    callers.flush()
    assert [line for _, line in reports[1:]] == [
        f"a client not named before the node stopped (GID {STRANGER.hex()}) (request 9)"
    ]
    assert len(callers.queue) == 0
