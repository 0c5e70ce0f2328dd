"""The nodes' steady timers (nodes/common.py `steady_timer`): a stop inside a callback is no failure.

SIGINT shuts rclpy's context down under the running executor; a timer callback in flight then
fails on its next publish ("publisher's context is invalid") and the executor logged that as a
FATAL line in the log of a cleanly stopped node. Real rclpy: the timer's own callback is called
as the executor calls it, once with the context shut down inside it, once with a failure of the
callback itself, which must still be raised.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from std_msgs.msg import Float64

from lubrig_ros.nodes.common import steady_timer

pytestmark = pytest.mark.ros


@pytest.fixture
def node(ros_domain: int) -> Iterator[Any]:
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node

    context = Context()
    rclpy.init(context=context, domain_id=ros_domain)
    made = Node("timer_test", context=context)
    yield made
    made.destroy_node()
    context.try_shutdown()


def test_a_stop_inside_a_timer_callback_ends_it_quietly(node) -> None:
    publisher = node.create_publisher(Float64, "/timer_test/out", 10)
    calls = []

    def beat() -> None:
        calls.append(1)
        node.context.shutdown()  # the stop lands here: the next publish fails
        publisher.publish(Float64(data=1.0))

    timer = steady_timer(node, 0.1, beat)
    timer.callback()  # no exception: the stop, not a failure
    assert calls == [1]


def test_a_failure_of_the_callback_itself_is_raised(node) -> None:
    def broken() -> None:
        raise RuntimeError("the callback's own failure")

    timer = steady_timer(node, 0.1, broken)
    with pytest.raises(RuntimeError, match="the callback's own failure"):
        timer.callback()
