"""analysis node: online wavelet analysis of the plant's displacement and stability flags.

Subscribes to <ns>/state (x, ẋ) and <ns>/band_velocity, pushes the samples received since the
last tick into core.online.OnlineWaveletAnalyzer every `publish_period` s (wall) and publishes
the dominant frequency, the newest wavelet power columns (Float64MultiArray, dims
["frequency", "time"]), an rgb8 image of the window's power, the linear zone and ζ_crit at the
current band velocity, the stability flags on /diagnostics (one status per flag group) and
<ns>/oscillation_growing. The rig comes from case/config_file and is replaced by the plant's
latched <ns>/run_config when it arrives.
"""

from __future__ import annotations

import math

import numpy as np
import yaml
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node
from sensor_msgs.msg import Image, JointState
from std_msgs.msg import Bool, Float64, Float64MultiArray, MultiArrayDimension, String, UInt8

from ..core.flags import StabilityFlags
from ..core.online import OnlineUpdate, OnlineWaveletAnalyzer
from ..core.params import ParameterError
from ..core.presets import RunConfig, from_mapping
from ..core.stability import linear_stability
from . import common

#: Flag groups of core.flags.StabilityFlags, one DiagnosticStatus each.
FLAG_GROUPS: dict[str, tuple[str, ...]] = {
    "linear": (
        "band_velocity_m_s",
        "zone",
        "zone_name",
        "linear_stable",
        "effective_damping",
        "critical_damping_ratio",
    ),
    "oscillation": ("oscillation", "growth_rate_per_s", "growth_fit_r2"),
    "stick": ("stick_threshold_m_s", "stick_share", "stick_episodes", "longest_stick_s"),
    "resonance": ("resonance", "resonance_harmonic", "resonance_detail"),
}
#: Colormap anchors (viridis-like), low → high power.
_ANCHORS = np.array([[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]], dtype=float)


def render_power(power: np.ndarray, width: int, decades: float = 4.0) -> np.ndarray:
    """rgb8 image (H = scales, high frequency on top; W = width columns) of log power."""
    power = np.asarray(power, dtype=float)
    columns = np.linspace(0, power.shape[1] - 1, width).round().astype(int)
    p = power[::-1, columns]  # row 0 = smallest scale = highest frequency
    top = float(np.max(p)) if p.size and np.max(p) > 0 else 1.0
    level = np.clip((np.log10(np.maximum(p, top * 10**-decades) / top) + decades) / decades, 0.0, 1.0)
    pos = level * (len(_ANCHORS) - 1)
    i = np.minimum(pos.astype(int), len(_ANCHORS) - 2)
    frac = (pos - i)[..., None]
    rgb = _ANCHORS[i] * (1.0 - frac) + _ANCHORS[i + 1] * frac
    return np.ascontiguousarray(rgb.round().astype(np.uint8))


def flag_statuses(flags: StabilityFlags) -> list[DiagnosticStatus]:
    """One DiagnosticStatus per flag group with its values as KeyValues."""
    values = flags.to_dict()
    statuses = []
    for group, keys in FLAG_GROUPS.items():
        status = DiagnosticStatus(name=f"lubrig/analysis: {group}", hardware_id="lubrig_analysis")
        status.values = [KeyValue(key=k, value=str(values.get(k))) for k in keys]
        warn = {
            "linear": values.get("linear_stable") is False,
            "oscillation": values.get("oscillation") == "growing",
            "stick": bool(values.get("stick_share")),
            "resonance": bool(values.get("resonance")),
        }[group]
        status.level = DiagnosticStatus.WARN if warn else DiagnosticStatus.OK
        status.message = {
            "linear": f"zone {values.get('zone')}, linearly {'unstable' if warn else 'stable'}"
            if values.get("zone") is not None
            else "no band velocity yet",
            "oscillation": f"oscillation {values.get('oscillation')}",
            "stick": f"stick share {values.get('stick_share')}",
            "resonance": str(values.get("resonance_detail") or "n/a"),
        }[group]
        statuses.append(status)
    return statuses


class Analysis(Node):
    """Online analysis node (see module docstring)."""

    def __init__(self) -> None:
        super().__init__("analysis")
        config = common.declare_run_selection(self)
        ns = self.get_parameter("topic_namespace").value
        d = common.descriptor
        convention = self.declare_parameter(
            "convention", "", d("physical | paper (empty: from the configuration)", read_only=True)
        ).value
        if convention:
            config = config.with_overrides(convention=convention)
        self.window = int(self.declare_parameter("window", 2048, d("samples analysed", read_only=True)).value)
        self.n_scales = int(self.declare_parameter("n_scales", 32, d("wavelet scales", read_only=True)).value)
        self.period = float(
            self.declare_parameter("publish_period", 0.2, d("s (wall) between updates", read_only=True)).value
        )
        self.image_width = int(self.declare_parameter("image_width", 256, d("pixels", read_only=True)).value)
        self.max_columns = int(
            self.declare_parameter(
                "max_columns", 64, d("newest power columns per message", read_only=True)
            ).value
        )
        if self.window < 64:
            raise ParameterError(f"window={self.window!r} is not valid; expected an integer >= 64")
        if not 2 <= self.n_scales <= 256:
            raise ParameterError(f"n_scales={self.n_scales!r} is not valid; expected 2..256")
        if not (common.finite(self.period) and 0.01 <= self.period <= 60.0):
            raise ParameterError(f"publish_period={self.period!r} is not valid; expected 0.01..60 s")
        if not 8 <= self.image_width <= 4096:
            raise ParameterError(f"image_width={self.image_width!r} is not valid; expected 8..4096")
        if self.max_columns < 1:
            raise ParameterError(f"max_columns={self.max_columns!r} is not valid; expected >= 1")
        self._configure(config)
        self.x: list[float] = []
        self.vrel: list[float] = []
        self.band: float | None = None
        self.bad_messages = 0
        self.bad_updates = 0  # analysis updates skipped on input it cannot analyse
        q = common.ANALYSIS_QOS
        self.pub_freq = self.create_publisher(Float64, common.topic(ns, common.DOMINANT_FREQUENCY), q)
        self.pub_power = self.create_publisher(Float64MultiArray, common.topic(ns, common.WAVELET_POWER), q)
        self.pub_image = self.create_publisher(Image, common.topic(ns, common.WAVELET_IMAGE), q)
        self.pub_zone = self.create_publisher(UInt8, common.topic(ns, common.LINEAR_ZONE), q)
        self.pub_zeta = self.create_publisher(Float64, common.topic(ns, common.CRITICAL_DAMPING_RATIO), q)
        self.pub_growing = self.create_publisher(Bool, common.topic(ns, common.OSCILLATION_GROWING), q)
        self.pub_diag = self.create_publisher(DiagnosticArray, common.DIAGNOSTICS, q)
        s = common.STREAM_QOS
        self.create_subscription(JointState, common.topic(ns, common.STATE), self._on_state, s)
        self.create_subscription(Float64, common.topic(ns, common.BAND_VELOCITY), self._on_band, s)
        self.create_subscription(
            String, common.topic(ns, common.RUN_CONFIG), self._on_run_config, common.LATCHED_QOS
        )
        self.create_timer(self.period, self._tick)
        self.get_logger().info(f"analysis: window {self.window} samples, {self.n_scales} scales")

    def _configure(self, config: RunConfig) -> None:
        self.config = config
        self.gamma = config.rig.velocity_factor
        self.analyzer = OnlineWaveletAnalyzer(
            1.0 / config.sample_rate,
            window=self.window,
            n_scales=self.n_scales,
            fundamental_hz=config.band.fundamental_hz,
            analysis_every=max(1, self.window // 8),
            rig=config.rig,
        )

    def _on_run_config(self, msg: String) -> None:
        try:
            data = yaml.safe_load(msg.data)
            config = from_mapping(data)
        except (ParameterError, ValueError, TypeError, AttributeError, yaml.YAMLError) as exc:
            self.get_logger().warning(f"ignoring an invalid run_config message: {exc}")
            return
        self._configure(config)
        self.x.clear()
        self.vrel.clear()
        self.get_logger().info(f"analysis: run configuration {config.name!r} from the plant")

    def _on_band(self, msg: Float64) -> None:
        if math.isfinite(msg.data):
            self.band = msg.data
        else:
            self.bad_messages += 1

    def _on_state(self, msg: JointState) -> None:
        if not (msg.position and msg.velocity):
            self.bad_messages += 1
            return
        x, v = msg.position[0], msg.velocity[0]
        if not (math.isfinite(x) and math.isfinite(v)):
            self.bad_messages += 1
            return
        # the plant's state carries the band velocity of its own sample (joint "band"); pair with
        # it, not with the latest band message, which in sim mode runs up to flow_window ahead
        band = msg.velocity[1] if len(msg.velocity) > 1 and math.isfinite(msg.velocity[1]) else None
        if band is not None:
            self.band = band
        self.x.append(x)
        self.vrel.append((self.band or 0.0) - self.gamma * v)

    def _tick(self) -> None:
        try:
            self._analyse()
        except (ParameterError, ValueError, ArithmeticError) as exc:  # never die on odd input
            self.bad_updates += 1
            self.get_logger().warning(f"analysis update skipped: {exc}", throttle_duration_sec=5.0)

    def _analyse(self) -> None:
        if self.band:  # a band at rest has no sliding equilibrium, hence no zone or ζ_crit
            verdict = linear_stability(abs(self.band), self.config.rig)
            self.pub_zone.publish(UInt8(data=int(verdict.zone)))
            if math.isfinite(verdict.critical_damping_ratio):
                self.pub_zeta.publish(Float64(data=float(verdict.critical_damping_ratio)))
        if not self.x:
            return
        x, vrel = self.x, self.vrel
        self.x, self.vrel = [], []
        update = self.analyzer.push(x, vrel, band_velocity=self.band)
        if update.ready:
            self._publish(update)

    def _publish(self, update: OnlineUpdate) -> None:
        power = update.power[:, -self.max_columns :]
        if power.size and np.isfinite(power).all():
            msg = Float64MultiArray()
            rows, cols = power.shape
            msg.layout.dim = [
                MultiArrayDimension(label="frequency", size=rows, stride=rows * cols),
                MultiArrayDimension(label="time", size=cols, stride=cols),
            ]
            msg.data = power.ravel().tolist()
            self.pub_power.publish(msg)
        if update.components:
            f = update.components[0].frequency_hz
            if math.isfinite(f):
                self.pub_freq.publish(Float64(data=float(f)))
        if update.window is not None and np.isfinite(update.window.power).all():
            rgb = render_power(update.window.power, self.image_width)
            image = Image()
            image.header.stamp = self.get_clock().now().to_msg()
            image.header.frame_id = "wavelet"
            image.height, image.width = rgb.shape[0], rgb.shape[1]
            image.encoding = "rgb8"
            image.step = 3 * rgb.shape[1]
            image.data = rgb.tobytes()
            self.pub_image.publish(image)
        if update.flags is not None:
            self.pub_growing.publish(Bool(data=update.flags.oscillation == "growing"))
            array = DiagnosticArray()
            array.header.stamp = self.get_clock().now().to_msg()
            array.status = flag_statuses(update.flags)
            self.pub_diag.publish(array)


def main(args: list[str] | None = None) -> int:
    """Console script / ros2 run entry point."""
    return common.spin_node(Analysis, args)


if __name__ == "__main__":
    raise SystemExit(main())
