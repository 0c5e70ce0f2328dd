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
from dataclasses import fields
from typing import Any

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64

from ..app.contract import BELT_DRIVE_PARAMETERS
from ..core.params import ParameterError
from ..core.presets import RunConfig
from ..core.profiles import PROFILE_KINDS, BandProfile, profile_from_dict, profile_to_dict
from . import common
from .interfaces import create_publisher, create_subscription

#: profile.* parameters, their kind(s) and default values (units: m/s, s, Hz, rad), taken from the
#: core's profile classes; a table profile is given by the path of its CSV.
PROFILE_FIELDS: dict[str, tuple[tuple[str, ...], Any]] = {
    **{
        f.name: ((kind,), f.default)
        for kind in ("constant", "cycle", "sine")
        for f in fields(PROFILE_KINDS[kind])
    },
    "path": (("table",), ""),
}


def profile_from_values(values: dict[str, Any], fallback: BandProfile) -> BandProfile:
    """Build a profile from profile.* values (kind + its fields); table without path: fallback."""
    kind = values.get("kind")
    if kind == "table":
        if values.get("path"):
            return profile_from_dict({"kind": "table", "path": values["path"]})
        if fallback.kind == "table":
            return fallback
        raise ParameterError("profile.kind='table' needs profile.path (a CSV of time_s,band_velocity_m_s)")
    fields = {name: values[name] for name, (kinds, _) in PROFILE_FIELDS.items() if kind in kinds}
    return profile_from_dict({"kind": kind, **fields})


class BeltDrive(Node):
    """Band velocity source (see module docstring)."""

    def __init__(self) -> None:
        super().__init__("belt_drive")
        config: RunConfig = common.declare_run_selection(self)
        ns = self.get_parameter("topic_namespace").value
        specs = [p for p in BELT_DRIVE_PARAMETERS if not p.name.startswith("profile.")]  # below
        values = common.declare_parameters(
            self, specs, {"sample_rate": config.sample_rate, "duration": config.duration}
        )
        self.mode, self.sample_rate, self.duration = values["mode"], values["sample_rate"], values["duration"]
        self.flow_window, self.start_delay = values["flow_window"], values["start_delay"]
        self.wait_for_subscriber = values["wait_for_subscriber"]
        self.realtime_priority = values["realtime_priority"]
        # profile.* defaults come from the selected configuration's band section.
        band = profile_to_dict(config.band)
        self.declare_parameter(
            "profile.kind", band["kind"], common.descriptor("constant | cycle | sine | table")
        )
        for name, (kinds, default) in PROFILE_FIELDS.items():
            value = band.get(name, default) if band["kind"] in kinds else default
            if name == "path":
                value = str(band.get("source") or "")
            self.declare_parameter(
                f"profile.{name}",
                float(value) if name != "path" else value,
                common.descriptor(f"{'/'.join(kinds)} profile: {name}"),
            )
        self.profile: BandProfile = profile_from_values(self._profile_values(), config.band)
        self._config_band = config.band
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self.publisher = create_publisher(self, ns, "band_velocity")
        self.total = round(self.duration * self.sample_rate)
        self.next_k = 1
        self.plant_k: int | None = None
        self.seen_at: float | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        if self.mode == "sim":
            create_subscription(self, ns, "/clock", self._on_clock)
            self.create_timer(0.05, self._pump)
        else:
            common.enter_realtime(self.realtime_priority, self)
            self._thread = threading.Thread(target=self._realtime_loop, daemon=True)
            self._thread.start()
        self.get_logger().info(
            f"belt_drive: mode={self.mode}, {self.sample_rate:g} Hz, profile {profile_to_dict(self.profile)}"
        )

    def _profile_values(self, updates: dict[str, Any] | None = None) -> dict[str, Any]:
        values = {"kind": self.get_parameter("profile.kind").value}
        values.update({n: self.get_parameter(f"profile.{n}").value for n in PROFILE_FIELDS})
        values.update(updates or {})
        return values

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        """Validate profile.* updates as a whole; swap the profile only when valid."""
        updates = {p.name.removeprefix("profile."): p.value for p in params if p.name.startswith("profile.")}
        if not updates:
            return SetParametersResult(successful=True)
        for name, value in updates.items():
            if name == "kind" or name == "path":
                if not isinstance(value, str):
                    return SetParametersResult(
                        successful=False,
                        reason=f"profile.{name}={value!r} is not valid; expected a string",
                    )
            elif not isinstance(value, float | int) or isinstance(value, bool):
                return SetParametersResult(
                    successful=False, reason=f"profile.{name}={value!r} is not valid; expected a number"
                )
        values = self._profile_values(updates)
        try:
            profile = profile_from_values(values, self._config_band)
        except (ParameterError, ValueError, TypeError) as exc:
            self.get_logger().warning(f"profile update rejected: {exc}")
            return SetParametersResult(successful=False, reason=str(exc))
        self.profile = profile
        self.get_logger().info(f"profile updated: {profile_to_dict(profile)}")
        return SetParametersResult(successful=True)

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
