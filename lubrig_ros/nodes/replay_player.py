"""The replay node's ROS side: publishers, the player's services and parameters, the playing loop.

Glue only: every decision is the session's (app/recording/replay.py, app/recording/replay_flow.py). An
executor thread serves the services, the parameters and the subscribers' flow_progress; the
main thread plays. Both change the session under one lock; a control wakes the playing loop.

Services (std_srvs/srv/Trigger, relative to the node: /lubrig_replay/pause, ...): ``~/pause``,
``~/resume``, ``~/toggle_paused``, ``~/is_paused`` (success: paused) and ``~/play_next`` (paused:
publish the next message at once; the answer names it); ``~/seek`` (lubrig_interfaces/srv/Seek)
and ``~/set_rate`` (lubrig_interfaces/srv/SetRate), as rosbag2's player has them. Seek and rate
are also the parameters ``seek`` (bag time in s from the bag's first log time: the next message
is the first at or after it) and ``rate`` (time scale, in (0, MAX_RATE]); the two services set
those parameters, so `ros2 param get` shows the current rate and the parameters' checks are the
one place a value is judged. Both take an integer too (`ros2 param set ... rate 2`); a value
outside its range, or not a number, is refused with the reason, and the player is unchanged.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

from rcl_interfaces.msg import SetParametersResult
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from std_srvs.srv import Trigger

from lubrig_interfaces.srv import Seek, SetRate
from lubrig_ros.app.recording.replay import MAX_RATE, Done, Entry, Publish, ReplaySession
from lubrig_ros.core.errors import InputError

from .common import descriptor

#: A block held this long by flow control is reported (once per reason).
HELD_NOTICE_S = 5.0
#: Longest sleep of the playing loop between looks at the stop flag (s).
POLL_S = 0.1


class Player:
    """The session behind a node: controls from services and parameters, the playing loop."""

    def __init__(
        self,
        node: Node,
        session: ReplaySession,
        pubs: dict[str, Any],
        clock_pub: Any,
        stop: list[bool],
    ) -> None:
        self.node, self.session, self.pubs, self.clock_pub, self.stop = node, session, pubs, clock_pub, stop
        self.cond = threading.Condition()
        self.clock = Clock()
        low, high = session.bounds_s()
        node.declare_parameter(
            "rate",
            session.rate,
            descriptor(
                f"time scale (2 = twice as fast), in (0, {MAX_RATE:g}]",
                low=0.0,
                high=MAX_RATE,
                dynamic_typing=True,
            ),
        )
        node.declare_parameter(
            "seek",
            session.seconds(session.start_ns),
            descriptor(
                "bag time to go to, s from the bag's first log time: the next message is the first at "
                "or after it",
                low=low,
                high=high,
                dynamic_typing=True,
            ),
        )
        node.add_on_set_parameters_callback(self._on_parameters)
        services: dict[str, Callable[[], tuple[bool, str]]] = {
            "pause": self._pause,
            "resume": self._resume,
            "toggle_paused": self._toggle,
            "is_paused": self._is_paused,
            "play_next": self._play_next,
        }
        for name, handler in services.items():
            node.create_service(Trigger, f"~/{name}", self._trigger(handler))
        node.create_service(Seek, "~/seek", lambda req, res: self._set("seek", req.time, res))
        node.create_service(SetRate, "~/set_rate", lambda req, res: self._set("rate", req.rate, res))

    def _set(self, name: str, value: float, response: Any) -> Any:
        """A Seek or SetRate request: the parameter of that name set (its check decides)."""
        result = self.node.set_parameters([Parameter(name, value=float(value))])[0]
        response.success = bool(result.successful)
        response.message = f"{name} {value:g}" if result.successful else str(result.reason)
        return response

    # ---- controls (executor thread) -----------------------------------------------------
    def _trigger(self, handler: Callable[[], tuple[bool, str]]) -> Callable[[Any, Any], Any]:
        def serve(_request: Any, response: Any) -> Any:
            with self.cond:
                response.success, response.message = handler()
                self.cond.notify_all()
            return response

        return serve

    def _where(self) -> str:
        return f"{self.session.seconds(self.session.bag_time_ns(time.monotonic())):.9g} s"

    def _pause(self) -> tuple[bool, str]:
        done = self.session.pause(time.monotonic())
        return done, f"{'paused' if done else 'already paused'} at {self._where()}"

    def _resume(self) -> tuple[bool, str]:
        where = self._where()
        done = self.session.resume(time.monotonic())
        return done, f"playing from {where}" if done else f"not paused (playing at {where})"

    def _toggle(self) -> tuple[bool, str]:
        paused = self.session.toggle(time.monotonic())
        return True, f"{'paused' if paused else 'playing'} at {self._where()}"

    def _is_paused(self) -> tuple[bool, str]:
        paused = self.session.paused
        return paused, f"{'paused' if paused else 'playing'} at {self._where()}"

    def _play_next(self) -> tuple[bool, str]:
        entry = self.session.step(time.monotonic())
        if isinstance(entry, str):
            return False, entry
        self._publish(entry)
        return True, f"published {entry.topic} at {self.session.seconds(entry.time_ns):.9g} s"

    def _on_parameters(self, params: list[Any]) -> SetParametersResult:
        with self.cond:
            now = time.monotonic()
            try:
                for p in params:
                    if p.name == "rate":
                        self.session.set_rate(p.value, now)
                    elif p.name == "seek":
                        self.session.seek(p.value, now)
            except InputError as exc:
                return SetParametersResult(successful=False, reason=str(exc))
            self.cond.notify_all()
        return SetParametersResult(successful=True)

    def on_progress(self, msg: Any) -> None:
        """A flow_progress message: to the lossless flow control."""
        flow = self.session.flow
        if flow is None:
            return
        with self.cond:
            if flow.report(str(msg.participant), int(msg.segment), int(msg.samples)):
                self.cond.notify_all()

    # ---- the playing loop (main thread) -------------------------------------------------
    def _publish(self, entry: Entry) -> None:
        if self.clock_pub is not None:
            self.clock.clock.sec, self.clock.clock.nanosec = divmod(entry.time_ns, 1_000_000_000)
            self.clock_pub.publish(self.clock)
        self.pubs[entry.topic].publish(entry.data)

    def play(self) -> None:
        """Play until the session is done or stop[0] is set."""
        held_since, told = 0.0, ""
        with self.cond:
            while not self.stop[0]:
                now = time.monotonic()
                action = self.session.next(now)
                if isinstance(action, Done):
                    return
                if isinstance(action, Publish):
                    self._publish(action.entry)
                    held_since = 0.0
                    continue
                if action.reason:
                    held_since = held_since or now
                    if now - held_since >= HELD_NOTICE_S and action.reason != told:
                        print(f"replay: held by flow control: {action.reason}", flush=True)
                        told = action.reason
                wait = POLL_S if action.seconds is None else min(action.seconds, POLL_S)
                self.cond.wait(wait)


class Spinner:
    """An executor serving a node in a thread of its own until `stop` (which joins the thread).

    Spun in slices, so the thread has ended before the node and the context are destroyed (a
    thread still waiting in the middleware while they go ends the process with SIGABRT).
    """

    def __init__(self, node: Node) -> None:
        self.executor = SingleThreadedExecutor(context=node.context)
        self.executor.add_node(node)
        self.running = True
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        while self.running:
            try:
                self.executor.spin_once(timeout_sec=POLL_S)
            except Exception:  # the context shut down while spinning: the node is ending
                return

    def stop(self) -> None:
        """End the thread (after its current slice), then the executor."""
        self.running = False
        self.thread.join(timeout=5.0)
        self.executor.shutdown(timeout_sec=1.0)
