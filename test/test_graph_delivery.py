"""A sample published once `delivers_to` says so reaches the named node (nodes/graph.py).

The graph and a writer learn of a subscription each on its own; a sample published after the
graph shows a subscription but before the writer has matched it never reaches it (volatile
durability). `delivers_to` waits for both. Here, over real DDS between separate participants:

- nobody of the name subscribed: not yet; subscribed and matched: the very first sample published
  then arrives, for each of several fresh subscribers (the race is not forced, the promise is
  checked every time);
- a subscription that can never match (an incompatible QoS, another message type) is not waited
  for; a compatible one is counted once matched.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from lubrig_testkit.harness import Probe, wait_until
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64

from lubrig_interfaces.msg import BandVelocityBlock
from lubrig_ros.app.interface import contract
from lubrig_ros.nodes.graph import compatible_subscriptions, delivers_to, matched_every_subscription
from lubrig_ros.nodes.interfaces import message_type, qos_profile

pytestmark = pytest.mark.ros

TOPIC = "/graph_test/band_velocity_block"
QOS = qos_profile(contract.BLOCK_QOS)


@pytest.fixture
def writer(ros_domain: int) -> Iterator[Probe]:
    probe = Probe(ros_domain, "writer")
    yield probe
    probe.close()


def test_message_type_names_a_class_as_the_graph_does():
    assert message_type(BandVelocityBlock) == "lubrig_interfaces/msg/BandVelocityBlock"
    assert message_type(Float64) == "std_msgs/msg/Float64"


def test_the_first_sample_after_delivers_to_reaches_each_new_subscriber(writer: Probe, ros_domain: int):
    pub = writer.node.create_publisher(BandVelocityBlock, TOPIC, QOS)
    assert not delivers_to(writer.node, [pub], "reader")  # nobody of that name yet
    for i in range(4):
        reader = Probe(ros_domain, f"reader{i}")
        try:
            reader.subscribe(TOPIC, BandVelocityBlock, QOS)
            wait_until(lambda i=i: delivers_to(writer.node, [pub], f"reader{i}"), 60, "delivers_to")
            pub.publish(BandVelocityBlock(first_sample_index=100 + i))
            wait_until(lambda r=reader: r.messages[TOPIC], 30, "the first sample")
            assert [m.first_sample_index for m in reader.messages[TOPIC]] == [100 + i]
        finally:
            reader.close()


def test_subscriptions_that_cannot_match_are_not_waited_for(writer: Probe, ros_domain: int):
    best_effort = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
    pub = writer.node.create_publisher(BandVelocityBlock, TOPIC, best_effort)
    other = Probe(ros_domain, "other")
    typed = Probe(ros_domain, "typed")  # one participant holds one type per topic name
    try:
        other.subscribe(TOPIC, BandVelocityBlock, QOS)  # reliable: a best-effort writer cannot serve it
        typed.subscribe(TOPIC, Float64, best_effort)  # another type on the same name
        wait_until(lambda: len(writer.node.get_subscriptions_info_by_topic(TOPIC)) == 2, 60, "discovery")
        assert matched_every_subscription(writer.node, pub)
        # discovered (its node's name may reach the graph a moment later); nothing it could match
        wait_until(lambda: delivers_to(writer.node, [pub], "other"), 60, "delivers_to")
        assert pub.get_subscription_count() == 0 and compatible_subscriptions(writer.node, pub) == 0
        # a compatible one: waited for until matched, then counted
        other.subscribe(TOPIC, BandVelocityBlock, best_effort)
        wait_until(lambda: len(writer.node.get_subscriptions_info_by_topic(TOPIC)) == 3, 60, "discovery")
        assert compatible_subscriptions(writer.node, pub) == 1  # the third one alone
        wait_until(lambda: pub.get_subscription_count() == 1, 60, "the match")
        assert matched_every_subscription(writer.node, pub)
    finally:
        other.close()
        typed.close()


def test_a_use_sim_time_clock_reader_does_not_count_as_taking_every_clock(writer: Probe, ros_domain: int):
    """A node with use_sim_time holds a best-effort /clock reader (rclpy's TimeSource). To a
    reliable /clock publisher it is no subscriber that takes every sample: neither `delivers_to`
    nor a lossless replay's wait takes it for the recorder's /clock reader, which a worker node
    of the same name prefix holds; that reliable reader, once matched, does count."""
    from rclpy.parameter import Parameter
    from rosgraph_msgs.msg import Clock

    from lubrig_ros.nodes.replay import subscribed

    clock_qos = qos_profile(contract.documented_topics()["/clock"].qos)
    pub = writer.node.create_publisher(Clock, "/clock", clock_qos)
    timed = Probe(ros_domain, "recorder")
    worker = Probe(ros_domain, "recorder_w0")
    try:
        timed.node.set_parameters([Parameter("use_sim_time", Parameter.Type.BOOL, True)])
        wait_until(lambda: pub.get_subscription_count() == 1, 60, "the time source's reader matched")
        assert matched_every_subscription(writer.node, pub)
        assert subscribed(writer.node, [pub], lossless=False)  # a subscriber, all it may take
        assert not subscribed(writer.node, [pub], lossless=True)
        assert not delivers_to(writer.node, [pub], "recorder")
        worker.subscribe("/clock", Clock, clock_qos)
        wait_until(lambda: delivers_to(writer.node, [pub], "recorder"), 60, "delivers_to")
        assert pub.get_subscription_count() == 2
        assert subscribed(writer.node, [pub], lossless=True)
    finally:
        worker.close()
        timed.close()
