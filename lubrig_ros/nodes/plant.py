"""plant node: the rig integrated by the core RigIntegrator, driven by <ns>/band_velocity.

Modes:
* `sim`: rig time is the plant's own. Band samples are consumed strictly in order, one sample
  per received message; after each the plant publishes its outputs and /clock. The run is
  deterministic (equal to core.run.simulate, sample for sample); <ns>/run_complete turns true
  once `duration` is reached.
* `realtime`: a deadline loop advances one sample per period of the wall clock with the latest
  band velocity; late ticks (deadline misses) and band→state latency are reported in /diagnostics.
* `rig_in_loop`: as realtime, for an external band publisher; non-finite values or
  |v| > band_velocity_limit are rejected (counted, last one reported), the last good value is
  held and staleness (no good input for stale_timeout s) is reported.
Services: <ns>/plant/reset (Trigger), <ns>/plant/pause (SetBool).
"""

from __future__ import annotations

import math
import struct
import sys
import threading
import time
from collections import deque
from dataclasses import fields
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64, String
from std_srvs.srv import SetBool, Trigger

from ..core.integrator import RigIntegrator, Trajectory
from ..core.params import FrictionParameters, ParameterError
from ..core.presets import RunConfig, from_mapping
from ..core.run import integrator_for
from . import common

RIG_FIELDS = ("mass", "natural_frequency", "damping_ratio")
FRICTION_FIELDS = tuple(f.name for f in fields(FrictionParameters))


def _stamp(t: float) -> tuple[int, int]:
    sec = math.floor(t)
    return int(sec), min(round((t - sec) * 1e9), 999_999_999)


class Plant(Node):
    """The rig as a ROS node (see module docstring)."""

    def __init__(self) -> None:
        super().__init__("plant")
        base: RunConfig = common.declare_run_selection(self)
        ns = self.get_parameter("topic_namespace").value
        self.mode = common.check_mode(
            self.declare_parameter(
                "mode", "sim", common.descriptor("sim | realtime | rig_in_loop", read_only=True)
            ).value
        )
        d = common.descriptor
        self.declare_parameter("sample_rate", base.sample_rate, d("Hz", read_only=True))
        self.declare_parameter("duration", base.duration, d("s of rig time (sim mode)", read_only=True))
        self.declare_parameter("rtol", base.rtol, d("integrator relative tolerance [1e-13, 1e-2]"))
        self.declare_parameter("initial_perturbation", base.initial_perturbation, d("x(0) = (1 + this) x0"))
        self.declare_parameter(
            "convention", base.rig.convention, d("physical | paper; empty: the run configuration's")
        )
        for name in RIG_FIELDS:
            self.declare_parameter(f"rig.{name}", float(getattr(base.rig, name)), d(f"rig {name} (SI)"))
        self.declare_parameter("rig.normal_force", base.rig.friction.normal_force, d("normal force N, N"))
        for name in FRICTION_FIELDS:
            if name != "normal_force":
                self.declare_parameter(
                    f"friction.{name}",
                    float(getattr(base.rig.friction, name)),
                    d(f"friction law {name} (SI)"),
                )
        self.band_limit = float(
            self.declare_parameter(
                "band_velocity_limit",
                common.BAND_VELOCITY_LIMIT,
                d("largest accepted |v_band|, m/s", read_only=True),
            ).value
        )
        self.stale_timeout = float(
            self.declare_parameter(
                "stale_timeout", 0.05, d("s without good band input = stale", read_only=True)
            ).value
        )
        self.wait_for_subscriber = common.declare_wait_for_subscriber(self)
        self.realtime_priority = common.declare_realtime_priority(self)
        self.diagnostics_period = float(
            self.declare_parameter(
                "diagnostics_period", 1.0, d("s between /diagnostics", read_only=True)
            ).value
        )
        for name, value in (
            ("band_velocity_limit", self.band_limit),
            ("stale_timeout", self.stale_timeout),
            ("diagnostics_period", self.diagnostics_period),
        ):
            if not (common.finite(value) and value > 0.0):
                raise ParameterError(f"{name}={value!r} is not valid; expected a finite number > 0")
        self._base = base
        self.config = self._config_from(dict())
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self.lock = threading.Lock()
        self.integrator: RigIntegrator = integrator_for(self.config)
        self.initial_band = float(self.config.band(0.0))
        self.total = self.config.samples
        self.sample_index = 0
        self.paused = False
        self.complete = False
        # band input bookkeeping
        self.latest_band = self.initial_band
        self.latest_band_recv: float | None = None  # perf_counter of the latest good message
        self.new_band = False
        self.received = 0
        self.rejected = 0
        self.last_rejected: float | None = None
        self.rejected_since_report = 0
        self.ignored_after_end = 0
        self.integration_errors = 0
        # timing
        self.misses = 0
        self.ticks = 0
        self.latencies = common.LatencyHistogram()
        self.max_late = 0.0

        qos = common.STREAM_QOS
        self.pub_x = self.create_publisher(Float64, common.topic(ns, common.DISPLACEMENT), qos)
        self.pub_v = self.create_publisher(Float64, common.topic(ns, common.VELOCITY), qos)
        self.pub_mu = self.create_publisher(Float64, common.topic(ns, common.FRICTION_COEFFICIENT), qos)
        self.pub_state = self.create_publisher(JointState, common.topic(ns, common.STATE), qos)
        self.pub_clock = self.create_publisher(Clock, common.CLOCK, qos) if self.mode == "sim" else None
        self.pub_diag = self.create_publisher(DiagnosticArray, common.DIAGNOSTICS, common.ANALYSIS_QOS)
        self.pub_config = self.create_publisher(
            String, common.topic(ns, common.RUN_CONFIG), common.LATCHED_QOS
        )
        self.pub_complete = self.create_publisher(
            Bool, common.topic(ns, common.RUN_COMPLETE), common.LATCHED_QOS
        )
        self.pub_config.publish(String(data=self.config.to_yaml()))
        self.pub_complete.publish(Bool(data=False))
        # raw (serialized CDR) subscription: about 2x cheaper per message than a Float64 object
        self.create_subscription(
            Float64, common.topic(ns, common.BAND_VELOCITY), self._on_band_raw, qos, raw=True
        )
        self.create_service(Trigger, common.topic(ns, common.RESET_SERVICE), self._on_reset)
        self.create_service(SetBool, common.topic(ns, common.PAUSE_SERVICE), self._on_pause)
        self.create_timer(self.diagnostics_period, self._publish_diagnostics)
        self._queue: deque[float] = deque()
        self._published_initial = False
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._msgs = (Float64(), Float64(), Float64(), JointState(), Clock())
        self._msgs[3].name = ["mass", "band"]
        self.band_travel = 0.0  # m, integral of the band velocity since the last reset
        self._last_band: tuple[float, float] | None = None
        if self.mode == "sim":
            self.create_timer(0.2, self._heartbeat)
        else:
            sys.setswitchinterval(2e-4)  # let the loop thread take the GIL promptly
            common.enter_realtime(self.realtime_priority, self)
            self._thread = threading.Thread(target=self._realtime_loop, daemon=True)
            self._thread.start()
        self.get_logger().info(
            f"plant: mode={self.mode}, {self.config.sample_rate:g} Hz, convention "
            f"{self.config.rig.convention}, {self.total} samples per run (sim)"
        )

    # ---- configuration -------------------------------------------------------------------
    def _config_from(self, updates: dict[str, Any]) -> RunConfig:
        """The run configuration from the current parameters with `updates` applied."""

        def value(name: str) -> Any:
            return updates[name] if name in updates else self.get_parameter(name).value

        data = self._base.to_dict()
        data["rig"].update({n: value(f"rig.{n}") for n in RIG_FIELDS})
        data["rig"]["convention"] = value("convention") or self._base.rig.convention  # "" = config's
        friction = {n: value(f"friction.{n}") for n in FRICTION_FIELDS if n != "normal_force"}
        friction["normal_force"] = value("rig.normal_force")
        data["rig"]["friction"] = friction
        data["simulation"].update(
            {n: value(n) for n in ("duration", "sample_rate", "rtol", "initial_perturbation")}
        )
        return from_mapping(data)

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        """Validate rig/friction/integration updates; they take effect at the next reset."""
        names = {"convention", "rtol", "initial_perturbation"}
        updates = {
            p.name: p.value for p in params if p.name in names or p.name.startswith(("rig.", "friction."))
        }
        if not updates:
            return SetParametersResult(successful=True)
        try:
            self._config_from(updates)
        except (ParameterError, ValueError, TypeError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self.get_logger().info(f"parameters {sorted(updates)} accepted; applied at the next reset")
        return SetParametersResult(successful=True)

    # ---- services ------------------------------------------------------------------------
    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        try:
            config = self._config_from({})
        except ParameterError as exc:
            response.success, response.message = False, str(exc)
            return response
        with self.lock:
            self.config = config
            self.integrator = integrator_for(config)
            self.sample_index = 0
            self.complete = False
            self._queue.clear()
            self._published_initial = False
            self.initial_band = float(config.band(0.0))
            if self.mode != "sim":  # realtime / rig in the loop: keep the band input, start there
                self.integrator.reset(band_velocity=self.latest_band)
            self.band_travel, self._last_band = 0.0, None
            if self._thread is not None:
                self._restart_clock = True
        self.pub_complete.publish(Bool(data=False))
        self.get_logger().info("reset: rig time back to 0")
        response.success, response.message = True, "rig reset to t = 0 and the initial state"
        return response

    def _on_pause(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        with self.lock:
            was = self.paused
            self.paused = bool(request.data)
            if was and not self.paused and self._thread is not None:
                self._restart_clock = True
        if not self.paused:
            self._drain()
        response.success = True
        response.message = "paused" if self.paused else "running"
        self.get_logger().info(f"pause: {response.message}")
        return response

    # ---- band input ----------------------------------------------------------------------
    def _on_band_raw(self, data: bytes) -> None:
        """Decode a serialized std_msgs/Float64 (4-byte CDR header + double); bad sizes are rejected."""
        if len(data) < 12 or data[1] not in (0, 1):
            self._on_band_value(float("nan"))
            return
        self._on_band_value(struct.unpack_from("<d" if data[1] == 1 else ">d", data, 4)[0])

    def _on_band_value(self, value: float) -> None:
        now = time.perf_counter()
        self.received += 1
        if not (isinstance(value, float) and math.isfinite(value) and abs(value) <= self.band_limit):
            self.rejected += 1
            self.rejected_since_report += 1
            self.last_rejected = value
            return
        if self.mode == "sim":
            self._queue.append(value)
            self._drain()
        else:
            self.latest_band = value
            self.latest_band_recv = now
            self.new_band = True

    # ---- sim -----------------------------------------------------------------------------
    def _drain(self) -> None:
        """Sim: integrate queued band samples one by one, publishing after each."""
        if self.mode != "sim":
            return
        with self.lock:
            if not self._published_initial:
                self._publish(self.integrator.current(), 0)
                self._published_initial = True
            while self._queue and not self.paused:
                band = self._queue.popleft()
                if self.complete:
                    self.ignored_after_end += 1
                    continue
                traj = self._advance(band)
                self.sample_index += 1
                self._publish(traj, 0)
                if self.sample_index >= self.total:
                    self.complete = True
                    self.pub_complete.publish(Bool(data=True))
                    self.get_logger().info(f"sim: run complete at t = {self.integrator.time:g} s")

    def _heartbeat(self) -> None:
        """Sim: republish /clock so that a late belt_drive sees where the plant is.

        Until the awaited subscriber (the recorder) has subscribed to every output, the plant stays
        silent, so belt_drive does not start and no sample is published before it is recorded.
        """
        outputs = (self.pub_x, self.pub_v, self.pub_mu, self.pub_state, self.pub_clock)
        if not common.subscribed_by(self, [p.topic_name for p in outputs], self.wait_for_subscriber):
            return
        self.wait_for_subscriber = ""  # seen once: no need to ask the graph again
        t = self.integrator.time
        clock = Clock()
        clock.clock.sec, clock.clock.nanosec = _stamp(t)
        self.pub_clock.publish(clock)

    # ---- integration and output ----------------------------------------------------------
    def _advance(self, band: float) -> Trajectory:
        """One sample; a failed one restarts the rig at equilibrium at the next sample time.

        Restarting there (not at t = 0) keeps /clock monotonic and the sample count right, so a
        sim run still completes and belt_drive's flow control does not stall.
        """
        t_next = self.integrator.time + self.integrator.dt
        try:
            traj = self.integrator.advance(np.array([band]))
            if math.isfinite(traj.displacement[0]) and math.isfinite(traj.velocity[0]):
                return traj
            problem = "non-finite state"
        except (ValueError, ArithmeticError, RuntimeError) as exc:
            problem = str(exc)
        self.integration_errors += 1
        self.get_logger().error(
            f"integration failed at t = {t_next:.6g} s ({problem}); rig restarted at equilibrium "
            f"for band velocity {band!r} m/s"
        )
        self.integrator.reset(band_velocity=band, time=t_next)
        return self.integrator.current()

    def _publish(self, traj: Trajectory, i: int) -> None:
        mx, mv, mmu, state, clock = self._msgs
        x = float(traj.displacement[i])
        v = float(traj.velocity[i])
        mu = float(traj.friction_coefficient[i])
        if not (math.isfinite(x) and math.isfinite(v) and math.isfinite(mu)):
            return
        t, band = float(traj.time[i]), float(traj.band_velocity[i])
        if self._last_band is not None and t > self._last_band[0]:  # belt travel, trapezoid rule
            self.band_travel += 0.5 * (band + self._last_band[1]) * (t - self._last_band[0])
        self._last_band = (t, band)
        sec, nsec = _stamp(t)
        mx.data, mv.data, mmu.data = x, v, mu
        state.header.stamp.sec, state.header.stamp.nanosec = sec, nsec
        # joint "mass": x, ẋ, friction force; joint "band": belt travel, the band velocity this
        # sample was integrated with (so subscribers pair each state with its own v_band), 0
        state.position = [x, self.band_travel]
        state.velocity = [v, band]
        state.effort = [mu * self.config.rig.friction.normal_force, 0.0]
        self.pub_x.publish(mx)
        self.pub_v.publish(mv)
        self.pub_mu.publish(mmu)
        self.pub_state.publish(state)
        if self.pub_clock is not None:
            clock.clock.sec, clock.clock.nanosec = sec, nsec
            self.pub_clock.publish(clock)

    # ---- realtime / rig in the loop ------------------------------------------------------
    def _realtime_loop(self) -> None:
        period = 1.0 / self.config.sample_rate
        self._restart_clock = False
        loop = common.DeadlineLoop(period)
        k = 0
        with self.lock:
            self._publish(self.integrator.current(), 0)
        while not self._stop.is_set():
            if self.paused:
                time.sleep(0.01)
                continue
            if self._restart_clock:
                self._restart_clock = False
                loop = common.DeadlineLoop(period)
                k = 0
            k += 1
            late = loop.wait(k)
            try:
                with self.lock:
                    recv = self.latest_band_recv if self.new_band else None
                    self.new_band = False
                    self._publish(self._advance(self.latest_band), 0)
            except Exception as exc:
                if not self._stop.is_set() and self.context.ok():
                    self.get_logger().fatal(f"real-time loop stopped: {exc!r}")
                return
            done = time.perf_counter()
            self.ticks += 1
            if recv is not None:
                self.latencies.add(done - recv)
            late_done = done - loop.deadline(k)
            self.max_late = max(self.max_late, late)
            if late_done > period:
                self.misses += 1

    # ---- diagnostics ---------------------------------------------------------------------
    def _publish_diagnostics(self) -> None:
        array = DiagnosticArray()
        array.header.stamp = self.get_clock().now().to_msg()
        timing = DiagnosticStatus(name="lubrig/plant: timing", hardware_id="lubrig_plant")
        p50, p99 = self.latencies.percentiles()
        ticks = self.ticks if self.mode != "sim" else self.sample_index
        share = self.misses / ticks if ticks else 0.0
        timing.values = [
            KeyValue(key="mode", value=self.mode),
            KeyValue(key="rig_time_s", value=f"{self.integrator.time:.6f}"),
            KeyValue(key="samples", value=str(ticks)),
            KeyValue(key="deadline_misses", value=str(self.misses)),
            KeyValue(key="deadline_miss_share", value=f"{share:.6f}"),
            KeyValue(key="max_lateness_s", value=f"{self.max_late:.6f}"),
            KeyValue(key="latency_p50_s", value=f"{p50:.6f}"),
            KeyValue(key="latency_p99_s", value=f"{p99:.6f}"),
            KeyValue(key="latency_samples", value=str(self.latencies.count)),
            KeyValue(key="integration_errors", value=str(self.integration_errors)),
            KeyValue(key="paused", value=str(self.paused).lower()),
            KeyValue(key="run_complete", value=str(self.complete).lower()),
        ]
        timing.level = DiagnosticStatus.WARN if share > 1e-3 else DiagnosticStatus.OK
        timing.message = (
            f"{self.misses} deadline misses in {ticks} samples"
            if self.mode != "sim"
            else ("complete" if self.complete else "running")
        )
        band = DiagnosticStatus(name="lubrig/plant: band input", hardware_id="lubrig_plant")
        age = None
        if self.latest_band_recv is not None:
            age = time.perf_counter() - self.latest_band_recv
        stale = self.mode != "sim" and not self.paused and (age is None or age > self.stale_timeout)
        band.values = [
            KeyValue(key="received", value=str(self.received)),
            KeyValue(key="rejected", value=str(self.rejected)),
            KeyValue(key="rejected_since_last_report", value=str(self.rejected_since_report)),
            KeyValue(key="last_rejected_value", value=repr(self.last_rejected)),
            KeyValue(key="valid_range_m_s", value=f"finite, |v| <= {self.band_limit:g}"),
            KeyValue(key="held_band_velocity_m_s", value=repr(self.latest_band)),
            KeyValue(key="stale", value=str(stale).lower()),
            KeyValue(key="input_age_s", value="none" if age is None else f"{age:.4f}"),
            KeyValue(key="stale_timeout_s", value=f"{self.stale_timeout:g}"),
            KeyValue(key="ignored_after_run_end", value=str(self.ignored_after_end)),
        ]
        problems = []
        if stale:
            problems.append("stale input, holding last good value")
        if self.rejected_since_report:
            problems.append(f"{self.rejected_since_report} bad band value(s) rejected")
        band.level = DiagnosticStatus.WARN if problems else DiagnosticStatus.OK
        band.message = "; ".join(problems) or "ok"
        self.rejected_since_report = 0
        array.status = [timing, band]
        self.pub_diag.publish(array)

    def close(self) -> None:
        """Stop the loop thread."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)


def main(args: list[str] | None = None) -> int:
    """Console script / ros2 run entry point."""
    return common.spin_node(Plant, args)


if __name__ == "__main__":
    raise SystemExit(main())
