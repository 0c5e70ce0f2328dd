"""belt_drive node: the band velocity v_band(t) of a profile, for the plant.

Parameters and topics around the belt session (app/belt_session.py, which says what is sent when).
Modes: `sim` publishes samples k = 1 … N, v_band(k / sample_rate), on <ns>/band_velocity_block
(BandVelocityBlock, up to `block_length` samples per message), strictly in order and never beyond
the slowest of the plant and the `required_consumers` plus `flow_window` samples, as they report
on <ns>/flow_progress (app/flow.py FlowGate; nothing is dropped, nothing skipped, a slow consumer
slows the run). It starts once the plant and every required consumer have reported, follows the
plant's segment (a plant reset: the profile restarts at t = 0 for the new segment) and stops
after the configured duration. The global /clock plays no part (two rigs on one domain stay
apart; every timer runs on the steady clock, so use_sim_time changes nothing here): a band block
is stamped with the rig time of its first sample on the plant's clock. `realtime` sends the band
samples ahead of the plant, each with its sample index: on every flow_progress of the plant (one
per state_block, about 50 per second) the blocks that keep `lookahead` samples ahead of it; a
plant reset restarts the profile for the new segment; no end (the run's wall duration is the
launcher's). The first block waits until the band blocks' subscriptions (the plant's, and that
of `wait_for_subscriber`) are matched; a sample sent before would never reach them. Profile
parameters (`profile.*`) can be changed at run time; invalid updates are rejected with the
reason and the running profile kept.
"""

from __future__ import annotations

import array
import time

import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

from lubrig_interfaces.msg import BandVelocityBlock, FlowProgress

from ..app.belt_session import AheadSchedule, BandBlock, ProfileState, SimSchedule
from ..app.flow import FlowGate, flow_window_problem, qualified_name
from ..app.interface.contract import BELT_DRIVE_PARAMETERS, profile_parameter
from ..app.processes.discovery import fully_qualified
from ..core.params import ParameterError
from ..core.presets import RunConfig
from ..core.profiles import BandProfile, profile_kinds, profile_to_dict
from . import common
from .graph import delivers_to
from .interfaces import create_publisher, create_subscription


def _doubles(values: np.ndarray) -> array.array:
    """A float64 array as the array.array('d') rclpy takes for float64[] without a per-item check."""
    out = array.array("d")
    out.frombytes(np.ascontiguousarray(values, dtype=np.float64).tobytes())
    return out


def _stamp_ns(msg: FlowProgress) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


class BeltDrive(Node):
    """Band velocity source (see module docstring)."""

    def __init__(self) -> None:
        super().__init__("belt_drive", namespace=common.DEFAULT_NAMESPACE)  # -r __ns:=... overrides
        config: RunConfig = common.declare_run_selection(self)
        specs = [p for p in BELT_DRIVE_PARAMETERS if not p.name.startswith("profile.")]  # below
        values = common.declare_parameters(
            self, specs, {"sample_rate": config.sample_rate, "duration": config.duration}
        )
        self.mode, self.sample_rate = values["mode"], values["sample_rate"]
        self.start_delay = values["start_delay"]
        self.wait_for_subscriber = values["wait_for_subscriber"]
        self.band = ProfileState(
            config.band, self.sample_rate, values["duration"], values["band_velocity_limit"]
        )
        self._declare_profile_parameters(config)
        self.add_pre_set_parameters_callback(self._complete_profile_update)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        common.check_updates(self, specs)
        self.publisher = create_publisher(self, "band_velocity_block")
        self._block = BandVelocityBlock()
        self._block.sample_period = 1.0 / self.sample_rate
        namespace = self.get_namespace()
        plant = qualified_name(namespace, values["plant_node"])
        self.sim: SimSchedule | None = None
        self.ahead: AheadSchedule | None = None
        self.plant = plant
        self.seen_at: float | None = None  # the plant's band subscription first discovered
        self._waiting_logged = 0.0
        if self.mode == "sim":
            problem = flow_window_problem(values["flow_window"], values["block_length"])
            if problem is not None:
                raise ParameterError(problem)
            required = tuple(qualified_name(namespace, n) for n in values["required_consumers"])
            gate = FlowGate(values["flow_window"], plant, required)
            self.sim = SimSchedule(gate, self.sample_rate, values["duration"], values["block_length"])
            self._reported = False  # the plant's first flow_progress (its segment) logged
            self.started = False
            create_subscription(self, "flow_progress", self._on_progress)
            # steady clock: pacing is on flow_progress alone, never on /clock (use_sim_time or not)
            common.steady_timer(self, 0.05, self._pump)
            self.get_logger().info(
                f"sim: paced by {plant} and required consumers {list(required) or 'none'}, "
                f"block_length {values['block_length']}, flow_window {values['flow_window']}"
            )
        else:
            self.ahead = AheadSchedule(plant, self.sample_rate, values["lookahead"])
            self._delivering = False  # the band blocks' subscriptions matched: sending
            create_subscription(self, "flow_progress", self._on_realtime_progress)
            self.get_logger().info(
                f"realtime: band samples {values['lookahead']} ahead of {plant} (its flow_progress)"
            )
        self.get_logger().info(
            f"belt_drive: mode={self.mode}, {self.sample_rate:g} Hz, "
            f"profile {profile_to_dict(self.profile)}, "
            f"use_sim_time {str(common.uses_sim_time(self)).lower()}"
        )

    @property
    def profile(self) -> BandProfile:
        """The running band profile."""
        return self.band.profile

    def _declare_profile_parameters(self, config: RunConfig) -> None:
        """profile.kind and every registered kind's fields, defaults from the run's band section."""
        self.declare_parameter(
            "profile.kind", config.band.kind, common.descriptor(" | ".join(profile_kinds()))
        )
        declared = self.band.parameters.flat()
        for name, value in declared.items():
            kinds = self.band.parameters.owners[name]
            self.declare_parameter(
                f"profile.{name}",
                value if isinstance(value, str) else float(value),
                common.descriptor(f"{'/'.join(kinds)} profile: {name}"),
            )
        # values given at start-up (parameter file, command line) apply as one update
        given: dict[str, object] = {"kind": self.get_parameter("profile.kind").value}
        for name, value in declared.items():
            current = self.get_parameter(f"profile.{name}").value
            if current != value:
                given[name] = current
        self.band.start(given)
        for name in declared:  # the contract's descriptors: unit and physical range
            spec = profile_parameter(name)
            if spec is not None:
                self.set_descriptor(spec.name, common.describe(spec, self.describe_parameter(spec.name)))

    def _complete_profile_update(self, params: list[Parameter]) -> list[Parameter]:
        """A change of profile.kind also sets the new kind's own fields (no value of another kind)."""
        updates = {p.name.removeprefix("profile."): p.value for p in params if p.name.startswith("profile.")}
        if not isinstance(updates.get("kind"), str):
            return params  # no kind change, or a kind that is no string (refused with its reason)
        extra = self.band.completed(updates)
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
        reason = self.band.update(updates)
        if reason is not None:
            self.get_logger().warning(f"profile update rejected: {reason}")
            return SetParametersResult(successful=False, reason=reason)
        self.get_logger().info(f"profile updated: {profile_to_dict(self.profile)}")
        return SetParametersResult(successful=True)

    def _publish(self, block: BandBlock) -> None:
        msg = self._block
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(block.stamp_ns, 1_000_000_000)
        msg.segment = block.segment
        msg.first_sample_index = block.first_sample_index
        msg.band_velocity = _doubles(block.band_velocity)
        self.publisher.publish(msg)

    def _on_progress(self, msg: FlowProgress) -> None:
        assert self.sim is not None
        if not self.sim.progress(str(msg.participant), int(msg.segment), int(msg.samples), _stamp_ns(msg)):
            return
        if not self._reported and self.sim.gate.segment is not None:
            self._reported = True
            self.get_logger().info(f"plant seen: segment {self.sim.gate.segment}")
        self._pump()

    def _pump(self) -> None:
        """Sim flow control: publish band blocks up to the gate's limit, never beyond N."""
        sim = self.sim
        assert sim is not None
        if not self._plant_discovered() or sim.gate.segment is None:
            return
        restarted = sim.restarted()
        if restarted is not None:
            self.get_logger().info(f"plant segment {restarted}: profile restarts at t = 0")
        if sim.done or (not self.started and not self._may_start()):
            return
        for block in sim.blocks(self.band):
            self._publish(block)
        if sim.done:
            self.get_logger().info(f"sim: all {sim.total} band samples of segment {sim.segment} published")

    def _plant_discovered(self) -> bool:
        """The plant's subscription to the band blocks is on the graph; `seen_at`: since when.

        The start delay counts from here, not from the plant's first flow_progress: a plant
        announces itself only after its own start-up check, which the delay then overlaps.
        """
        if self.seen_at is None:
            infos = self.get_subscriptions_info_by_topic(self.publisher.topic_name)
            if any(fully_qualified(i.node_namespace, i.node_name) == self.plant for i in infos):
                self.seen_at = time.monotonic()
        return self.seen_at is not None

    def _may_start(self) -> bool:
        """Plant and required consumers reported, discovery time passed, the plant subscribed."""
        assert self.sim is not None
        missing = self.sim.gate.missing()
        now = time.monotonic()
        if missing:
            self._waiting(f"flow_progress from {missing}", now)
            return False
        if self.seen_at is None or now - self.seen_at < self.start_delay:
            return False
        if not self._reaches_subscribers(now):
            return False
        self.started = True
        self.get_logger().info("sim: every participant reported; sending band samples")
        return True

    def _reaches_subscribers(self, now: float) -> bool:
        """A band block sent now reaches the plant and the awaited node (`wait_for_subscriber`).

        The plant's subscription is discovered, and the publisher has matched every discovered
        subscription (nodes/graph.delivers_to): a block sent before the match never reaches it.
        """
        if self._plant_discovered() and delivers_to(self, [self.publisher], self.wait_for_subscriber):
            return True
        awaited = f" and {self.wait_for_subscriber}*" if self.wait_for_subscriber else ""
        self._waiting(f"the band blocks' subscriptions of the plant{awaited} to be matched", now)
        return False

    def _waiting(self, what: str, now: float) -> None:
        if now - self._waiting_logged > 5.0:
            self._waiting_logged = now
            self.get_logger().info(f"{self.mode}: waiting for {what}")

    def _on_realtime_progress(self, msg: FlowProgress) -> None:
        """Realtime: keep `lookahead` band samples ahead of the plant's next sample.

        Nothing is sent until the subscriptions are matched (`_delivering`): the schedule then
        sends every index from 0, those the plant has passed late (it counts them).
        """
        assert self.ahead is not None
        if not self._delivering:
            self._delivering = self._reaches_subscribers(time.monotonic())
            if not self._delivering:
                return
        block = self.ahead.progress(
            str(msg.participant), int(msg.segment), int(msg.samples), _stamp_ns(msg), self.band
        )
        if self.ahead.restarted_segment is not None:
            self.get_logger().info(f"plant segment {self.ahead.restarted_segment}: profile restarts at t = 0")
        if block is not None:
            self._publish(block)


def main(args: list[str] | None = None) -> int:
    """Console script / ros2 run entry point."""
    return common.spin_node(BeltDrive, args)


if __name__ == "__main__":
    raise SystemExit(main())
