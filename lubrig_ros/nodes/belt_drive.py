"""belt_drive node: publishes the band velocity v_band(t) of a profile on <ns>/band_velocity.

Modes: `sim` publishes sample k = v_band(k / sample_rate), k = 1 … N, strictly in order and only
while the plant's /clock is less than `flow_window` samples behind (flow control: nothing is
dropped, nothing skipped), then stops after the configured duration; `realtime` publishes
v_band(t_wall) at the sample rate from a deadline loop. Profile parameters (`profile.*`) can be
changed at run time; invalid updates are rejected with the reason and the running profile kept.
"""

from __future__ import annotations

import threading
import time

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64

from ..app.contract import BELT_DRIVE_PARAMETERS
from ..app.plant_session import band_range_problem
from ..core.params import ParameterError
from ..core.presets import RunConfig
from ..core.profiles import BandProfile, ProfileParameters, profile_kinds, profile_to_dict
from . import common
from .interfaces import create_publisher, create_subscription


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
        self.wait_for_subscriber = values["wait_for_subscriber"]
        self.realtime_priority = values["realtime_priority"]
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

        self.publisher = create_publisher(self, "band_velocity")
        self.total = round(self.duration * self.sample_rate)
        self.next_k = 1
        self.plant_k: int | None = None
        self.seen_at: float | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        if self.mode == "sim":
            create_subscription(self, "/clock", self._on_clock)
            self.create_timer(0.05, self._pump)
        else:
            common.enter_realtime(self.realtime_priority, self)
            self._thread = threading.Thread(target=self._realtime_loop, daemon=True)
            self._thread.start()
        self.get_logger().info(
            f"belt_drive: mode={self.mode}, {self.sample_rate:g} Hz, profile {profile_to_dict(self.profile)}"
        )

    def _complete_profile_update(self, params: list[Parameter]) -> list[Parameter]:
        """A change of profile.kind also sets the new kind's own fields (no value of another kind)."""
        updates = {p.name.removeprefix("profile."): p.value for p in params if p.name.startswith("profile.")}
        if "kind" not in updates:
            return params
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
            elif not isinstance(value, float | int) or isinstance(value, bool):
                return SetParametersResult(
                    successful=False, reason=f"profile.{name}={value!r} is not valid; expected a number"
                )
        try:
            profile = self.profile_parameters.apply(updates)
        except (ParameterError, ValueError, TypeError) as exc:
            self.get_logger().warning(f"profile update rejected: {exc}")
            return SetParametersResult(successful=False, reason=str(exc))
        problem = self._band_problem(profile)
        if problem is not None:
            reason = f"profile {profile_to_dict(profile)} refused: {problem}"
            self.get_logger().warning(f"profile update rejected: {reason}")
            return SetParametersResult(successful=False, reason=reason)
        self.profile = profile
        self.get_logger().info(f"profile updated: {profile_to_dict(profile)}")
        return SetParametersResult(successful=True)

    def _band_problem(self, profile: BandProfile) -> str | None:
        """Cross-check with the plant: the profile over the run within band_velocity_limit."""
        return band_range_problem(profile, self.sample_rate, self.duration, self.band_velocity_limit)

    def _sample(self, k: int) -> float:
        value = float(self.profile(k / self.sample_rate))
        return value if common.finite(value) else 0.0

    def _on_clock(self, msg: Clock) -> None:
        k = round((msg.clock.sec + msg.clock.nanosec * 1e-9) * self.sample_rate)
        if self.plant_k is None:
            self.seen_at = time.monotonic()
            self.get_logger().info(f"plant clock seen at sample {k}")
        self.plant_k = k if self.plant_k is None else max(self.plant_k, k)
        self._pump()

    def _pump(self) -> None:
        """Sim flow control: publish samples up to plant sample + flow_window, never beyond N."""
        if self.plant_k is None or self.next_k > self.total:
            return
        if (
            time.monotonic() - self.seen_at < self.start_delay
            or self.publisher.get_subscription_count() == 0
            or not common.subscribed_by(self, [self.publisher.topic_name], self.wait_for_subscriber)
        ):
            return
        self.wait_for_subscriber = ""  # seen once: no need to ask the graph again
        limit = min(self.total, self.plant_k + self.flow_window)
        msg = Float64()
        while self.next_k <= limit:
            msg.data = self._sample(self.next_k)
            self.publisher.publish(msg)
            self.next_k += 1
        if self.next_k > self.total:
            self.get_logger().info(f"sim: all {self.total} band samples published")

    def _realtime_loop(self) -> None:
        loop = common.DeadlineLoop(1.0 / self.sample_rate)
        msg = Float64()
        k = 0
        while not self._stop.is_set():
            loop.wait(k)
            msg.data = self._sample(k)
            try:
                self.publisher.publish(msg)
            except Exception as exc:
                if not self._stop.is_set() and self.context.ok():
                    self.get_logger().fatal(f"real-time loop stopped: {exc!r}")
                return
            k += 1

    def close(self) -> None:
        """Stop the realtime thread."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)


def main(args: list[str] | None = None) -> int:
    """Console script / ros2 run entry point."""
    return common.spin_node(BeltDrive, args)


if __name__ == "__main__":
    raise SystemExit(main())
