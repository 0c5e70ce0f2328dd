"""belt_drive node: the band velocity v_band(t) of a profile, for the plant.

Modes: `sim` publishes samples k = 1 … N, v_band(k / sample_rate), on <ns>/band_velocity_block
(BandVelocityBlock, up to `block_length` samples per message), strictly in order and never beyond
the slowest of the plant and the `required_consumers` plus `flow_window` samples, as they report
on <ns>/flow_progress (app/flow.py FlowGate; nothing is dropped, nothing skipped, a slow consumer
slows the run). It starts once the plant and every required consumer have reported, follows the
plant's segment (a plant reset: the profile restarts at t = 0 for the new segment) and stops
after the configured duration. The global /clock plays no part (two rigs on one domain stay
apart; every timer runs on the steady clock, so use_sim_time changes nothing here): a band block
is stamped with the rig time of its first sample on the plant's clock, which the plant's
flow_progress stamps give (it goes on across resets, nodes/plant.py). `realtime` sends the band
samples ahead of the plant, each with its sample index: on
every flow_progress of the plant (one per state_block, about 50 per second) the blocks that keep
`lookahead` samples ahead of it, v_band(k / sample_rate) for sample index k - 1 as in sim mode,
so the plant's sample k uses the profile at its own rig time whatever the delivery jitter; a
plant reset restarts the profile for the new segment; no end (the run's wall duration is the
launcher's). Profile parameters (`profile.*`) can be changed at run time;
invalid updates are rejected with the reason and the running profile kept.
"""

from __future__ import annotations

import array
import copy
import math
import time

import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

from lubrig_interfaces.msg import BandVelocityBlock, FlowProgress

from ..app import cdr
from ..app.contract import BELT_DRIVE_PARAMETERS, flow_window_problem
from ..app.flow import FlowGate, qualified_name
from ..core.params import ParameterError
from ..core.presets import RunConfig
from ..core.profiles import BandProfile, ProfileParameters, band_range_problem, profile_kinds, profile_to_dict
from . import common
from .interfaces import create_publisher, create_subscription


def _doubles(values: np.ndarray) -> array.array:
    """A float64 array as the array.array('d') rclpy takes for float64[] without a per-item check."""
    out = array.array("d")
    out.frombytes(np.ascontiguousarray(values, dtype=np.float64).tobytes())
    return out


class BeltDrive(Node):
    """Band velocity source (see module docstring)."""

    def __init__(self) -> None:
        super().__init__("belt_drive", namespace=common.DEFAULT_NAMESPACE)  # -r __ns:=... overrides
        config: RunConfig = common.declare_run_selection(self)
        specs = [p for p in BELT_DRIVE_PARAMETERS if not p.name.startswith("profile.")]  # below
        values = common.declare_parameters(
            self, specs, {"sample_rate": config.sample_rate, "duration": config.duration}
        )
        self.mode, self.sample_rate, self.duration = values["mode"], values["sample_rate"], values["duration"]
        self.flow_window, self.start_delay = values["flow_window"], values["start_delay"]
        self.block_length = values["block_length"]
        self.wait_for_subscriber = values["wait_for_subscriber"]
        # profile.* parameters: every registered kind's fields (core.profiles.ProfileParameters),
        # defaults from the selected configuration's band section.
        self.profile_parameters = ProfileParameters(config.band)
        self.declare_parameter(
            "profile.kind", config.band.kind, common.descriptor(" | ".join(profile_kinds()))
        )
        declared = self.profile_parameters.flat()
        for name, value in declared.items():
            kinds = self.profile_parameters.owners[name]
            self.declare_parameter(
                f"profile.{name}",
                value if isinstance(value, str) else float(value),
                common.descriptor(f"{'/'.join(kinds)} profile: {name}"),
            )
        # values given at start-up (parameter file, command line) apply as one update
        given = {"kind": self.get_parameter("profile.kind").value}
        for name, value in declared.items():
            current = self.get_parameter(f"profile.{name}").value
            if current != value:
                given[name] = current
        self.band_velocity_limit = values["band_velocity_limit"]
        profile = self.profile_parameters.apply(given)
        problem = self._band_problem(profile)
        if problem is not None:
            raise ParameterError(f"profile {profile_to_dict(profile)} refused: {problem}")
        self.profile: BandProfile = profile
        self.add_pre_set_parameters_callback(self._complete_profile_update)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        common.check_updates(self, specs)

        self.total = round(self.duration * self.sample_rate)
        self.next_k = 1  # next band sample of the current segment
        self.segment: int | None = None
        self.seen_at: float | None = None
        self.started = False
        # sim: (segment, ROS time in ns of its t = 0) from the plant's flow_progress; the band
        # blocks are stamped on the rig's clock, which runs on across resets (nodes/plant.py)
        self._origin: tuple[int, int] = (0, 0)
        if self.mode == "sim":
            problem = flow_window_problem(self.flow_window, self.block_length)
            if problem is not None:
                raise ParameterError(problem)
            namespace = self.get_namespace()
            plant = qualified_name(namespace, values["plant_node"])
            required = tuple(qualified_name(namespace, n) for n in values["required_consumers"])
            self.gate = FlowGate(self.flow_window, plant, required)
            self.publisher = create_publisher(self, "band_velocity_block")
            self._block = BandVelocityBlock()
            self._block.sample_period = 1.0 / self.sample_rate
            create_subscription(self, "flow_progress", self._on_progress)
            # steady clock: pacing is on flow_progress alone, never on /clock (use_sim_time or not)
            common.steady_timer(self, 0.05, self._pump)
            self._waiting_logged = 0.0
            self.get_logger().info(
                f"sim: paced by {plant} and required consumers {list(required) or 'none'}, "
                f"block_length {self.block_length}, flow_window {self.flow_window}"
            )
        else:
            namespace = self.get_namespace()
            self.lookahead = values["lookahead"]
            self.plant = qualified_name(namespace, values["plant_node"])
            self.publisher = create_publisher(self, "band_velocity_block")
            self._block = BandVelocityBlock()
            self._block.sample_period = 1.0 / self.sample_rate
            create_subscription(self, "flow_progress", self._on_realtime_progress)
            self.get_logger().info(
                f"realtime: band samples {self.lookahead} ahead of {self.plant} (its flow_progress)"
            )
        self.get_logger().info(
            f"belt_drive: mode={self.mode}, {self.sample_rate:g} Hz, "
            f"profile {profile_to_dict(self.profile)}, use_sim_time {str(common.uses_sim_time(self)).lower()}"
        )

    def _complete_profile_update(self, params: list[Parameter]) -> list[Parameter]:
        """A change of profile.kind also sets the new kind's own fields (no value of another kind)."""
        updates = {p.name.removeprefix("profile."): p.value for p in params if p.name.startswith("profile.")}
        if not isinstance(updates.get("kind"), str):
            return params  # no kind change, or a kind that is no string (refused with its reason)
        extra = self.profile_parameters.completed(updates)
        given = {p.name for p in params}
        return params + [
            Parameter(f"profile.{name}", value=value)
            for name, value in extra.items()
            if f"profile.{name}" not in given
            and self.has_parameter(f"profile.{name}")
            and self.get_parameter(f"profile.{name}").value != value
        ]

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        """Validate profile.* updates as a whole; swap the profile only when valid."""
        updates = {p.name.removeprefix("profile."): p.value for p in params if p.name.startswith("profile.")}
        if not updates:
            return SetParametersResult(successful=True)
        declared = self.profile_parameters.flat()
        for name, value in updates.items():
            if name == "kind" or isinstance(declared.get(name), str):
                if not isinstance(value, str):
                    return SetParametersResult(
                        successful=False,
                        reason=f"profile.{name}={value!r} is not valid; expected a string",
                    )
            elif not isinstance(value, float | int) or isinstance(value, bool) or not math.isfinite(value):
                return SetParametersResult(
                    successful=False,
                    reason=f"profile.{name}={value!r} is not valid; expected a finite number",
                )
        given = ", ".join(f"profile.{k}={v!r}" for k, v in updates.items())
        before = copy.deepcopy(self.profile_parameters)  # a refused update leaves no trace
        try:
            profile = self.profile_parameters.apply(updates)
        except (ParameterError, ValueError, TypeError) as exc:
            self.profile_parameters = before
            reason = f"{given} refused: {exc}"
            self.get_logger().warning(f"profile update rejected: {reason}")
            return SetParametersResult(successful=False, reason=reason)
        problem = self._band_problem(profile)
        if problem is not None:
            self.profile_parameters = before
            reason = f"{given} refused: profile {profile_to_dict(profile)}: {problem}"
            self.get_logger().warning(f"profile update rejected: {reason}")
            return SetParametersResult(successful=False, reason=reason)
        self.profile = profile
        self.get_logger().info(f"profile updated: {profile_to_dict(profile)}")
        return SetParametersResult(successful=True)

    def _band_problem(self, profile: BandProfile) -> str | None:
        """Cross-check with the plant: the profile over the run within band_velocity_limit."""
        return band_range_problem(profile, self.sample_rate, self.duration, self.band_velocity_limit)

    def _on_progress(self, msg: FlowProgress) -> None:
        if msg.participant == self.gate.plant and int(msg.segment) > self._origin[0]:
            self._origin = (int(msg.segment), self._segment_origin(msg))
        if not self.gate.report(msg.participant, int(msg.segment), int(msg.samples)):
            return
        if self.seen_at is None and self.gate.segment is not None:
            self.seen_at = time.monotonic()
            self.get_logger().info(f"plant seen: segment {self.gate.segment}")
        self._pump()

    def _segment_origin(self, msg: FlowProgress) -> int:
        """ROS time (ns) of t = 0 of the plant's segment: its stamp less the rig time it reports.

        The plant stamps flow_progress with the time of its newest sample, (samples - 1) / rate
        into the segment (0 before the first), on its clock that goes on across resets.
        """
        sec, nanosec = cdr.stamp_of(max(int(msg.samples) - 1, 0) / self.sample_rate)
        stamp = int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
        return stamp - (sec * 1_000_000_000 + nanosec)

    def _band_stamp(self, segment: int, k: int) -> tuple[int, int]:
        """(sec, nanosec) of band sample k of `segment`: rig time k / rate on the rig's clock."""
        sec, nanosec = cdr.stamp_of(k / self.sample_rate)
        origin = self._origin[1] if self._origin[0] == segment else 0
        return divmod(max(0, origin + sec * 1_000_000_000 + nanosec), 1_000_000_000)

    def _pump(self) -> None:
        """Sim flow control: publish band blocks up to the gate's limit, never beyond N."""
        segment = self.gate.segment
        if segment is None or self.seen_at is None:
            return
        if segment != self.segment:
            if self.segment is not None:
                self.get_logger().info(f"plant segment {segment}: profile restarts at t = 0")
            self.segment, self.next_k = segment, 1
        if self.next_k > self.total:
            return
        if not self.started and not self._may_start():
            return
        limit = self.gate.limit(self.total)
        msg = self._block
        msg.segment = segment
        while self.next_k <= limit:
            n = min(self.block_length, limit - self.next_k + 1)
            k = np.arange(self.next_k, self.next_k + n, dtype=float)
            msg.header.stamp.sec, msg.header.stamp.nanosec = self._band_stamp(segment, self.next_k)
            msg.first_sample_index = self.next_k - 1
            msg.band_velocity = _doubles(self._samples(k))
            self.publisher.publish(msg)
            self.next_k += n
        if self.next_k > self.total:
            self.get_logger().info(f"sim: all {self.total} band samples of segment {segment} published")

    def _may_start(self) -> bool:
        """Plant and required consumers reported, discovery time passed, the plant subscribed."""
        missing = self.gate.missing()
        now = time.monotonic()
        if missing:
            if now - self._waiting_logged > 5.0:
                self._waiting_logged = now
                self.get_logger().info(f"sim: waiting for flow_progress from {missing}")
            return False
        waiting = None
        if self.seen_at is None or now - self.seen_at < self.start_delay:
            return False
        if self.publisher.get_subscription_count() == 0:
            waiting = "the plant's subscription to the band blocks"
        elif not common.subscribed_by(self, [self.publisher.topic_name], self.wait_for_subscriber):
            waiting = f"a subscription of {self.wait_for_subscriber}* to the band blocks"
        if waiting is not None:
            if now - self._waiting_logged > 5.0:
                self._waiting_logged = now
                self.get_logger().info(f"sim: waiting for {waiting}")
            return False
        self.started = True
        self.get_logger().info("sim: every participant reported; sending band samples")
        return True

    def _samples(self, k: np.ndarray) -> np.ndarray:
        values = np.asarray(self.profile(k / self.sample_rate), dtype=float)
        return np.where(np.isfinite(values), values, 0.0)

    def _on_realtime_progress(self, msg: FlowProgress) -> None:
        """Realtime: the plant's next sample is msg.samples; keep `lookahead` band samples ahead."""
        if msg.participant != self.plant:
            return
        segment, needed = int(msg.segment), int(msg.samples)  # next output sample: band index - 1
        if segment != self.segment:
            if self.segment is not None:
                self.get_logger().info(f"plant segment {segment}: profile restarts at t = 0")
            self.segment, self.next_k = segment, 1
        # band index j = k - 1 integrates the plant's sample k; the plant needs index needed - 1
        # next. Every index is sent once, in order, from 0: those the plant has passed are late
        # (it counts them) but the band stream stays whole.
        first_k = self.next_k
        last_k = needed + self.lookahead - 1
        if last_k < first_k:
            return
        k = np.arange(first_k, last_k + 1, dtype=float)
        msg_out = self._block
        due = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec  # of the plant's sample needed - 1
        msg_out.header.stamp.sec, msg_out.header.stamp.nanosec = cdr.stamp_of(
            due + (first_k - needed + 1) / self.sample_rate
        )
        msg_out.segment = segment
        msg_out.first_sample_index = first_k - 1
        msg_out.band_velocity = _doubles(self._samples(k))
        self.publisher.publish(msg_out)
        self.next_k = last_k + 1


def main(args: list[str] | None = None) -> int:
    """Console script / ros2 run entry point."""
    return common.spin_node(BeltDrive, args)


if __name__ == "__main__":
    raise SystemExit(main())
