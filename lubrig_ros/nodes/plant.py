"""plant node: the rig (app.plant.session.PlantSession) on ROS topics.

Band input in every mode: <ns>/band_velocity_block (lubrig_interfaces/BandVelocityBlock: what
belt_drive sends, with the sample index of each value) and <ns>/band_velocity (std_msgs/Float64,
one value per message: foreign rig software). Modes sim | lockstep | realtime | rig_in_loop;
their rules live in app/plant/session.py (unit-tested without DDS):

* sim integrates every band block in order with the core stepper (equal to core.run.simulate
  whatever the block length) and publishes one <ns>/state_block (RigStateBlock) per band block,
  then <ns>/flow_progress (FlowProgress: this node's fully qualified name, segment, samples
  published in the segment) that paces belt_drive (app/flow.py); with `publish_clock` also
  /clock per block and as a 5 Hz heartbeat. Stamps (and /clock) are rig time, also its
  /diagnostics; every timer runs on the steady clock, so the node runs with use_sim_time.
* lockstep is sim for rig software that answers each state: the initial state at once, then one
  sample per band value, each as <ns>/state (RigState, rig-time stamp) and in state_block; a
  state not answered within the heartbeat period is published again (the answer to a repeated
  state is dropped by its sample index).
* realtime / rig_in_loop tick from a deadline loop on a thread of their own: one <ns>/state per
  sample (state_per_sample; stamped with the node clock when it was computed; only while the
  topic has a subscriber, checked with every block; serialized by hand,
  app/interface/cdr.StampedEncoder), and one <ns>/state_block per output_block_length samples
  (stamp: the due time of its first sample, node clock; each sample's lateness; a declared gap in
  `skipped`), followed by flow_progress, which belt_drive follows to send band samples ahead.
  Falling behind real time: lag_policy.

`scalar_topics` adds std_msgs/Float64 displacement, velocity and friction_coefficient per
sample. `shadow` (rig_in_loop): the real rig's <ns>/measured_displacement (std_msgs/Float64, one
value per message) is paired with the published samples (app/plant/session.py, "Shadow") and the
pairs go out as <ns>/shadow_block (ShadowBlock) after each state_block; the publishers and
messages are nodes/plant_outputs.py's. A reset (<ns>/plant/reset) starts a new segment at t = 0
(stepped modes: its stamps and /clock go on from the old segment's end, never back) and reports
it on flow_progress at once; <ns>/plant/pause pauses. Exit status 3 (EXIT_REAL_TIME_NOT_HELD)
when a wall-clock run did not hold real time. Start-up: nothing runs for `namespace_settle` s;
another rig in the namespace ends the node (exit 2); band publishers besides `band_source` are
WARNed (nodes/graph.py). Topics, QoS, parameters: app/interface/contract.py.
"""

from __future__ import annotations

import dataclasses
import functools
import os
import signal
import sys
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Bool, String
from std_srvs.srv import SetBool, Trigger

from lubrig_interfaces.msg import BandVelocityBlock, FlowProgress

from ..app.interface import cdr, contract
from ..app.plant.diagnostics import HARDWARE_ID
from ..app.plant.session import (
    PlantBlock,
    PlantSample,
    PlantSession,
    PlantSettings,
    config_from,
    config_parameters,
    law_of,
    parameter_defaults,
    runtime_parameters,
)
from ..core.params import ParameterError
from . import common, graph, scheduling
from .graph import NamespaceGuard, await_source, await_subscriber, band_source_status, delivers_to
from .interfaces import create_service, create_subscription
from .plant_outputs import PlantOutputs

HEARTBEAT_S = 0.2  # sim: flow_progress (and /clock) republished at 5 Hz
#: Stepped modes, until announced: the announcement's checks this often (s), so the run starts
#: once they pass, not at the heartbeat's next beat (the start-up's critical path).
ANNOUNCE_POLL_S = 0.05
#: Wall-clock modes: flow_progress at most this often (with a state_block; belt_drive sends its
#: lookahead, 200 samples, ahead of it, so 0.1 s of progress leaves 0.1 s of band in hand).
PROGRESS_PERIOD_S = 0.1
#: Wall-clock modes with wait_for_subscriber: longest wait for that node's flow_progress (s).
AWAIT_PROGRESS_S = 5.0
#: Exit status of a wall-clock plant that did not hold real time (lag_policy skip or stop).
EXIT_REAL_TIME_NOT_HELD = contract.EXIT_REAL_TIME_NOT_HELD
#: exit_when_complete: longest wait (s) for the readers of the outputs to acknowledge the last samples.
ACK_WAIT_S = 1.0


def _nothing(_sample: PlantSample) -> None:
    return None


class Plant(Node):
    """The rig as a ROS node (see module docstring)."""

    def __init__(self) -> None:
        super().__init__("plant", namespace=common.DEFAULT_NAMESPACE)  # -r __ns:=... overrides
        base = common.declare_run_selection(self)
        # the friction law first: its parameter dataclass decides the friction.<field> parameters
        law = common.declare(self, contract.FRICTION_LAW, law_of(base))
        self.config_names = config_parameters(law)
        self.runtime_names = runtime_parameters(law)
        values = common.declare_parameters(
            self, contract.plant_parameters(law), parameter_defaults(base, law)
        )
        self.mode = values["mode"]
        self.wall_clock = self.mode not in contract.STEPPED_MODES
        self.wait_for_subscriber = values["wait_for_subscriber"]
        self.state_subscribers = tuple(values["state_subscribers"])
        self.band_source = values["band_source"]
        self.scalar_topics = bool(values["scalar_topics"])
        self.publish_clock = bool(values["publish_clock"]) and self.mode == "sim"
        self.exit_when_complete = bool(values["exit_when_complete"])
        self._ending = False  # exit_when_complete: the run is over, the node is ending
        self.exit_status = 0
        if values["publish_clock"] and self.mode != "sim":
            self.get_logger().warning("publish_clock applies to sim mode only; no /clock published")
        self.shadow = bool(values["shadow"]) and self.mode == "rig_in_loop"
        if values["shadow"] and not self.shadow:
            self.get_logger().warning("shadow applies to rig_in_loop mode only; no shadow_block published")
            values["shadow"] = False
        self.sim_time = common.uses_sim_time(self)
        if self.sim_time and self.wall_clock:
            self.get_logger().warning(
                f"use_sim_time true in {self.mode} mode: the node clock follows /clock, which this "
                "rig does not publish; its wall-clock stamps come from that clock (use it in sim only)"
            )
        # stepped modes: ROS time (ns) of the current segment's t = 0. Rig time restarts at 0 with
        # every reset (sample_index, the profile); the stamps and /clock go on from where the old
        # segment ended, so the ROS clock of a use_sim_time node never goes back (_on_reset).
        self._origin_ns = 0
        # the session's settings are the parameters of the same names
        settings = PlantSettings(**{f.name: values[f.name] for f in dataclasses.fields(PlantSettings)})
        self.participant = self.get_fully_qualified_name()
        self.out = PlantOutputs(
            self,
            self.participant,
            per_sample_state=self.mode != "sim" and bool(values["state_per_sample"]),
            scalar_topics=self.scalar_topics,
            publish_clock=self.publish_clock,
            shadow=self.shadow,
        )
        self._announced = False  # stepped: first flow_progress sent (the awaited subscriber is there)
        self._state_sent = 0.0  # lockstep: monotonic time the newest state was published
        self._progress_sent = 0.0  # wall-clock modes: monotonic time of the newest flow_progress
        # wall-clock modes: state (one message per sample, the loop's largest cost) only while
        # something subscribes to it (checked with every block); lockstep: always
        self._state_wanted = self.mode == "lockstep"
        # wall-clock stamps: the node clock at a session clock() time (both advance at the same rate)
        self._clock_offset_ns = self.get_clock().now().nanoseconds - time.monotonic_ns()
        per_sample = self.out.state is not None or self.scalar_topics
        self.session = PlantSession(
            base,
            settings,
            config=config_from(base, self._config_values()),
            on_sample=self._publish_sample if per_sample else _nothing,
            on_block=self._publish_block,
            on_complete=self._on_complete,
            on_fault=self._on_fault,
            on_failure=self._on_failure,
            log=functools.partial(common.log_at, self),
        )
        self.add_on_set_parameters_callback(self._on_set_parameters)
        common.check_updates(self, contract.plant_parameters(law))
        self.out.config.publish(String(data=self.session.config.to_yaml()))
        self.out.complete.publish(Bool(data=False))
        # raw (serialized CDR) subscription: about 2x cheaper per message than a Float64 object
        self._band_readers = [
            create_subscription(self, n, cb, raw=n == "band_velocity")
            for n, cb in (("band_velocity", self._on_band_raw), ("band_velocity_block", self._on_band_block))
        ]
        if self.shadow:  # raw as band_velocity: a malformed payload is NaN, rejected and counted
            create_subscription(self, "measured_displacement", self._on_measured_raw, raw=True)
        # nothing runs before this namespace is known to be this rig's (another rig's plant, or a
        # publisher of the outputs, there: the node ends, exit status 2)
        owned = [p.topic_name for p in self.out.owned()]
        self._clear = NamespaceGuard(self, owned, values["namespace_settle"]).clear
        self._heard_awaited = False  # wall clock: the awaited subscriber's flow_progress arrived
        if self.wall_clock and self.wait_for_subscriber:
            create_subscription(self, "flow_progress", self._on_progress)
        self._callers = []  # every reset/pause is logged with its caller; rclpy does not tell the callback
        for name, callback in (("plant/reset", self._on_reset), ("plant/pause", self._on_pause)):
            service = create_service(self, name, callback)
            log = functools.partial(self._log_caller, service.service_name)
            self._callers.append(graph.CallerReports(self, service, log))
        # steady clock, as the heartbeat: with use_sim_time the node clock stands until /clock moves
        common.steady_timer(self, values["diagnostics_period"], self._publish_diagnostics)
        self._stop = threading.Event()
        self._log_problems = common.ProblemLog(self)  # warn/error statuses also to the log
        self._thread: threading.Thread | None = None
        config = self.session.config
        if self.wall_clock:
            sys.setswitchinterval(2e-4)  # let the loop thread take the GIL promptly
            scheduling.serve_realtime(int(values["realtime_priority"]))  # this (the executor) thread
            self._thread = threading.Thread(target=self._realtime_loop, daemon=True)
            self._thread.start()
            runs = (
                f"{1e3 * self.session.period:g} ms per sample, state_block every "
                f"{settings.output_block_length} samples, lag_policy {settings.lag_policy} "
                f"beyond {1e3 * settings.max_lag:g} ms"
            )
        else:
            # the heartbeat announces the plant, which starts the run: it must not wait for /clock
            common.steady_timer(self, HEARTBEAT_S, self._heartbeat)
            self._announce_poll = common.steady_timer(self, ANNOUNCE_POLL_S, self._poll_announcement)
            runs = f"{config.samples} samples per run"
        self.get_logger().info(
            f"plant: mode={self.mode}, {config.sample_rate:g} Hz, {config.rig.coupling_label}, "
            f"friction law {law}, {runs}, use_sim_time {str(self.sim_time).lower()}"
        )

    def _on_band_raw(self, data: bytes) -> None:
        self.session.band_input(cdr.float64_value(data))  # malformed payload: NaN, rejected

    def _on_measured_raw(self, data: bytes) -> None:
        self.session.measured_input(cdr.float64_value(data))

    def _on_band_block(self, msg: BandVelocityBlock) -> None:
        # foreign senders: a block without a positive period or of another rate is still taken
        # sample by sample at the plant's own rate (the values are what counts)
        self.session.band_block(msg.band_velocity, int(msg.segment), int(msg.first_sample_index))

    def _on_progress(self, msg: FlowProgress) -> None:
        name = str(msg.participant).rsplit("/", 1)[-1]
        if name.startswith(self.wait_for_subscriber):
            self._heard_awaited = True

    def _config_values(self) -> dict[str, object]:
        return {name: self.get_parameter(name).value for name in self.config_names}

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        """Validate rig/friction/integration updates; they take effect at the next reset."""
        updates = {p.name: p.value for p in params}
        reason = self.session.check_update(self._config_values(), updates)
        if reason is not None:
            return SetParametersResult(successful=False, reason=reason)
        if set(updates) & self.runtime_names:
            self.get_logger().info(f"parameters {sorted(updates)} accepted; applied at the next reset")
        return SetParametersResult(successful=True)

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        try:
            config = config_from(self.session.base, self._config_values())
        except ParameterError as exc:
            response.success, response.message = False, str(exc)
            return response
        with self.session.lock:
            if not self.wall_clock:  # the new segment's t = 0 is one sample after the old one's last
                self._origin_ns = self._stamp_ns(self.session.published * self.session.integrator.dt)
            self.session.reset(config)
            segment = self.session.segment
            self.out.config.publish(String(data=config.to_yaml()))
            if self.wall_clock or self._announced:  # belt_drive restarts its profile for the new segment
                self._publish_progress(self._now_s() if self.wall_clock else self._rig_now())
        self.get_logger().info(f"reset: rig time back to 0, segment {segment}")
        response.success = True
        response.message = f"rig reset to t = 0 and the initial state; segment {segment}"
        return response

    def _log_caller(self, service: str, who: str) -> None:
        self.get_logger().info(f"{service} called by {who}")

    def _on_pause(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        response.success, response.message = True, self.session.set_paused(bool(request.data))
        self.get_logger().info(f"pause: {response.message}")
        return response

    def _poll_announcement(self) -> None:
        """Stepped modes, until announced: the heartbeat's checks (it announces once they pass)."""
        if self._announced:
            self._announce_poll.cancel()
            return
        self._heartbeat()

    def _heartbeat(self) -> None:
        """Stepped modes: republish flow_progress (and /clock) so that a late belt_drive sees where we are.

        Silent until the awaited subscriber (the recorder) has subscribed to every output, each of
        `state_subscribers` to state_block, and band_source reaches a band reader: belt_drive does
        not start, and no sample is unrecorded, unanalysed or unread. Lockstep: the initial state
        once announced, and the newest state again while unanswered.
        """
        if not self._announced:
            if not self._clear.is_set():
                return
            if not delivers_to(self, self.out.recorded(), self.wait_for_subscriber):
                return
            blocks = [self.out.block]
            if not all(delivers_to(self, blocks, n) for n in self.state_subscribers):
                return
            if self.band_source and not graph.reads_source(self, self._band_readers, self.band_source):
                return  # the declared source starts on the announcement: its first block must arrive
            self._announced = True
            self.get_logger().info(f"{self.mode}: flow_progress as {self.participant}")
            if self.mode == "lockstep":
                self.session.emit_initial()
        with self.session.lock:
            self._publish_progress(self._rig_now())
            self.out.publish_clock(self._stamp(self._rig_now()))
            unanswered = time.monotonic() - self._state_sent >= HEARTBEAT_S
            lockstep = self.mode == "lockstep" and not self.session.complete
            resend = self.out.state_payload
            if lockstep and self.out.state is not None and unanswered and resend is not None:
                self.out.state.publish(resend)  # the answer may have been lost
                self._state_sent = time.monotonic()

    def _rig_now(self) -> float:
        """Stepped modes: rig time of the newest sample published (0 before the first).

        As its block has it, sample index x dt (the integrator's own clock sums dt and may lie a
        nanosecond behind, which would put /clock back by one).
        """
        return max(self.session.published - 1, 0) * self.session.integrator.dt

    def _stamp_ns(self, t: float) -> int:
        """Stepped modes: the ROS time (ns) of rig time t of the current segment."""
        sec, nanosec = cdr.stamp_of(t)
        return self._origin_ns + sec * 1_000_000_000 + nanosec

    def _stamp(self, t: float) -> tuple[int, int]:
        """(sec, nanosec) of a stamp of time t (s).

        Stepped modes: rig time t of the segment on the rig's ROS clock (equal to t until the
        first reset); wall-clock modes: node-clock time t.
        """
        if self.wall_clock:
            return cdr.stamp_of(t)
        return divmod(self._stamp_ns(t), 1_000_000_000)

    def _publish_progress(self, t: float) -> None:
        """flow_progress: samples published in the segment; stamp t (rig time, or node time in s)."""
        self.out.publish_progress(self._stamp(t), self.session.segment, self.session.published)

    def _now_s(self) -> float:
        return float(self.get_clock().now().nanoseconds) * 1e-9

    def _wall_time(self, due: float) -> float:
        """Node-clock time (s) of a session clock() time (wall-clock modes)."""
        return (self._clock_offset_ns + due * 1e9) * 1e-9

    def _block_start(self, block: PlantBlock) -> float:
        """Stamp of a block's first sample: rig time (stepped), its due time on the node clock (else)."""
        if not self.wall_clock:
            return float(block.time[0])
        start = self.session.segment_start or 0.0
        return self._wall_time(start + block.first_sample_index * block.sample_period)

    def _publish_block(self, block: PlantBlock) -> None:
        """One RigStateBlock (shadow: then the new pairs), flow_progress and /clock (session lock held)."""
        first = self._block_start(block)
        self.out.publish_block(block, self._stamp(first))
        if self.shadow:
            pairs = self.session.shadow_take()
            if pairs is not None:
                stamp = divmod(self.get_clock().now().nanoseconds, 1_000_000_000)
                self.out.publish_shadow(pairs, stamp, block.sample_period)
        if self.wall_clock and self.out.state is not None:
            self._state_wanted = self.out.state.get_subscription_count() > 0
        now = time.monotonic()
        due = now - self._progress_sent >= PROGRESS_PERIOD_S
        if not self.wall_clock or block.first_sample_index == 0 or due:
            self._progress_sent = now
            self._publish_progress(first + (len(block) - 1) * block.sample_period)
        if self.out.clock is not None:
            self.out.publish_clock(self._stamp(float(block.time[-1])))
        last = block.first_sample_index + len(block) - 1
        if self.exit_when_complete and self.wall_clock and last >= self.session.total:
            duration = self.session.config.duration
            self._end_of_run(f"{self.mode}: sample {self.session.total} published ({duration:g} s)")

    def _on_complete(self, done: bool) -> None:
        """run_complete (latched); stepped modes with exit_when_complete: the run is over."""
        self.out.complete.publish(Bool(data=done))
        if done and self.exit_when_complete:
            self._end_of_run(f"{self.mode}: run complete")

    def _end_of_run(self, why: str) -> None:
        """exit_when_complete: stop the loop, let the readers take the last samples, end (status 0)."""
        if self._ending:
            return
        self._ending = True
        self._stop.set()  # wall clock: the loop ends after this block (its last samples are flushed)
        self.get_logger().info(f"{why}: the node ends (exit_when_complete)")
        threading.Thread(target=self._exit_when_acked, name="end_of_run", daemon=True).start()

    def _exit_when_acked(self) -> None:
        if self._thread is not None:
            self._thread.join(timeout=1.0)
        # the outputs (flow_progress only paces the band source: over with the run)
        outputs = (self.out.block, self.out.complete, self.out.state, self.out.shadow)
        common.end_when_acked([p for p in outputs if p is not None], ACK_WAIT_S)

    def _publish_sample(self, s: PlantSample) -> None:
        """One RigState per sample (wall-clock modes: node clock now; lockstep: rig time); scalars."""
        if self.scalar_topics:
            self.out.publish_scalars(s)
        if self.out.state is None or not self._state_wanted:
            return
        if self.wall_clock:
            stamp = divmod(self.get_clock().now().nanoseconds, 1_000_000_000)
        else:
            stamp = self._stamp(s.time)
        self.out.publish_state(stamp, s)
        self._state_sent = time.monotonic()

    def _await_subscriber(self) -> bool:
        """Wall-clock modes: hold the loop until band_source reaches it, wait_for_subscriber reports."""
        if self.band_source and not await_source(self, self._band_readers, self.band_source, self._stop):
            return False
        if not self.wait_for_subscriber:
            return True
        waiting = (self.out.blocks(), self.wait_for_subscriber, self._stop, lambda: self._heard_awaited)
        return await_subscriber(self, *waiting, AWAIT_PROGRESS_S)

    def _realtime_loop(self) -> None:
        priority = int(self.get_parameter("realtime_priority").value)
        scheduling.enter_realtime(priority, self)  # this thread only
        try:
            while not self._clear.wait(0.05):
                if self._stop.is_set():
                    return
            if not self._await_subscriber():
                return
            self.session.run_realtime(self._stop.is_set)
        except Exception as exc:
            if not self._stop.is_set() and self.context.ok():
                self.get_logger().fatal(f"real-time loop stopped: {exc!r}")
                self.exit_status = 1
                os.kill(os.getpid(), signal.SIGINT)  # the node ends (spin_node) instead of idling

    def _on_fault(self, reason: str) -> None:
        """lag_policy stop: the rig stopped; the node ends with EXIT_REAL_TIME_NOT_HELD."""
        self.exit_status = EXIT_REAL_TIME_NOT_HELD
        self.get_logger().fatal(f"{reason}; stopping (lag_policy stop)")
        self._publish_diagnostics()
        os.kill(os.getpid(), signal.SIGINT)

    def _on_failure(self, reason: str) -> None:
        """A sample could not be integrated (the session logged it): a sim run ends, the rest waits.

        Stepped modes: the run cannot complete; the node ends with EXIT_INTEGRATION_FAILED once
        what was published is out. Wall-clock modes: no output until a reset (the timing status
        is ERROR with the reason); the node stays up for it.
        """
        self._publish_diagnostics()
        if not self.wall_clock:
            self.exit_status = contract.EXIT_INTEGRATION_FAILED
            self.get_logger().fatal(f"the run ends (exit status {self.exit_status}): {reason}")
            # not from here (a callback, the session's lock held, the last samples not yet out):
            # the readers take what was published, then the node ends as on a Ctrl-C
            threading.Thread(target=self._exit_when_acked, name="end_of_run", daemon=True).start()

    def _publish_diagnostics(self) -> None:
        array = DiagnosticArray()
        if self.wall_clock:
            array.header.stamp = self.get_clock().now().to_msg()
        else:  # the rig's time, not the node clock (that is /clock's echo, or 0 with --no-clock)
            array.header.stamp.sec, array.header.stamp.nanosec = self._stamp(self._rig_now())
        statuses = self.session.diagnostics()
        statuses.append(band_source_status(self, self._band_readers, self.band_source, HARDWARE_ID))
        array.status = [common.diagnostic_status(s, self) for s in statuses]
        self.out.diagnostics.publish(array)
        self._log_problems.log(statuses)

    def close(self) -> None:
        """Stop the loop thread; a run that did not hold real time sets the exit status."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
        for callers in self._callers:
            callers.flush()
        session = self.session
        if self.wall_clock and not session.held_real_time:
            self.exit_status = self.exit_status or EXIT_REAL_TIME_NOT_HELD
            self.get_logger().error(
                f"the rig did not hold real time: {session.skipped} samples skipped in "
                f"{session.skip_events} gaps, worst lateness {1e3 * session.max_late:.1f} ms "
                f"(max_lag {1e3 * session.settings.max_lag:g} ms, lag_policy "
                f"{session.settings.lag_policy}); exit status {self.exit_status}"
            )


def prepare() -> None:
    """Before the node is built (nodes/entry.py): numba's CPU target.

    Loading the integrator's cached kernels needs it first; done here, it is off the node's building.
    """
    common.load_numba_target()


def main(args: list[str] | None = None) -> int:
    """Console script / ros2 run entry point."""
    return common.spin_node(Plant, args)


if __name__ == "__main__":
    raise SystemExit(main())
