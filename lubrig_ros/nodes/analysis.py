"""analysis node: online wavelet analysis of the plant's displacement and stability flags.

Subscribes to <ns>/state_block (RigStateBlock: the plant publishes it in every mode, in the
wall-clock modes one per output_block_length samples) and, with `per_sample_input`, to
<ns>/state (RigState, one message per sample: for a plant that publishes only those); the band
velocity comes with each sample. Every `publish_period` s of wall time (a steady-clock timer in
every mode, so the analysis never waits for /clock) the samples received since the last update go
into app.analysis.session.AnalysisSession, and the node publishes what it returns: the dominant
frequency, the newest wavelet power columns (Float64MultiArray, dims ["frequency", "time"], and
WaveletFrame with its frequency and time axes), an rgb8 image of the window's power, the linear
zone and ζ_crit at the current band velocity, every stability flag with its values
(StabilityFlags; also on /diagnostics, one status per flag group) and <ns>/oscillation_growing.
Header stamps: with use_sim_time (a sim rig) the rig time of the newest sample analysed (the
stamp of the plant's samples, not the node clock: they hold with --no-clock and however far the
rig has run on meanwhile; before the first sample the node clock), without it (realtime) the node
clock at publication; WaveletFrame's start/end are the stamps of its first and last column.
The rig comes from case/config_file and is replaced by the plant's latched <ns>/run_config when
it arrives.

Shadow (a rig_in_loop plant with `shadow` true): once <ns>/shadow_block (ShadowBlock) arrives, a
second session analyses the real rig's measured displacement the same way, and every update
also publishes <ns>/measured/dominant_frequency, measured/wavelet_frame and measured/stability
beside the model's (so an instability growing on the rig shows next to the model's zones). The
rig sends no velocity: ẋ is the measured displacement's backward difference over consecutive
sample indices (app/plant/shadow.measured_velocity), and v_rel = v_band − γ ẋ of the run's γ.
Without shadow blocks nothing of this exists (no publisher, no session). Topics, QoS, parameters:
app/interface/contract.py.
"""

from __future__ import annotations

import array
import math
from collections.abc import Sequence

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.publisher import Publisher
from sensor_msgs.msg import Image
from std_msgs.msg import Bool, Float64, Float64MultiArray, MultiArrayDimension, String, UInt8

from lubrig_interfaces.msg import RigState, RigStateBlock, ShadowBlock, StabilityFlags, WaveletFrame

from ..app.analysis.session import AnalysisOutput, AnalysisSession, AnalysisSettings
from ..app.interface import cdr
from ..app.interface.contract import ANALYSIS_PARAMETERS
from ..app.plant.shadow import measured_velocity
from ..core import flags as core_flags
from . import common
from .interfaces import create_publisher, create_subscription

OUTPUTS = (
    "dominant_frequency",
    "wavelet_power",
    "wavelet_image",
    "linear_zone",
    "critical_damping_ratio",
    "oscillation_growing",
    "/diagnostics",
    "wavelet_frame",
    "stability",
)
#: The outputs of the measured signal's analysis (shadow), each under measured/.
MEASURED_OUTPUTS = ("dominant_frequency", "wavelet_frame", "stability")
OSCILLATION = {
    "unknown": StabilityFlags.OSCILLATION_UNKNOWN,
    "steady": StabilityFlags.OSCILLATION_STEADY,
    "decaying": StabilityFlags.OSCILLATION_DECAYING,
    "growing": StabilityFlags.OSCILLATION_GROWING,
}

Samples = Sequence[float] | np.ndarray  # one of a block's arrays, or one sample's value in a list


def _number(value: float | int | None) -> float:
    """A flag value for a message field: 0 for None or a non-finite value (never NaN)."""
    return float(value) if value is not None and math.isfinite(value) else 0.0


def stability_message(flags: core_flags.StabilityFlags, damping_ratio: float) -> StabilityFlags:
    """The StabilityFlags message of core.flags.StabilityFlags (field meanings in the .msg)."""
    msg = StabilityFlags()
    if flags.zone is not None and flags.band_velocity_m_s:
        msg.linear_zone = int(flags.zone)
        msg.band_velocity = _number(flags.band_velocity_m_s)
        msg.damping_ratio = _number(damping_ratio)
        msg.critical_damping_ratio = _number(flags.critical_damping_ratio)
        msg.effective_damping = _number(flags.effective_damping)
        msg.linear_stable = bool(flags.linear_stable)
    msg.oscillation = OSCILLATION.get(flags.oscillation, StabilityFlags.OSCILLATION_UNKNOWN)
    if msg.oscillation != StabilityFlags.OSCILLATION_UNKNOWN:
        msg.growth_rate = _number(flags.growth_rate_per_s)
        msg.growth_fit_r2 = _number(flags.growth_fit_r2)
    msg.oscillation_growing = msg.oscillation == StabilityFlags.OSCILLATION_GROWING
    if flags.stick_threshold_m_s:
        msg.stick_threshold = _number(flags.stick_threshold_m_s)
        msg.stick_share = _number(flags.stick_share)
        msg.sticking = msg.stick_share > 0.0
        msg.stick_episodes = int(flags.stick_episodes or 0)
        msg.longest_stick = _number(flags.longest_stick_s)
    msg.resonance = bool(flags.resonance)
    msg.resonance_harmonic = int(flags.resonance_harmonic or 0)
    return msg


class Analysis(Node):
    """Online analysis node (see module docstring)."""

    def __init__(self) -> None:
        super().__init__("analysis", namespace=common.DEFAULT_NAMESPACE)  # -r __ns:=... overrides
        config = common.declare_run_selection(self)
        values = common.declare_parameters(self, ANALYSIS_PARAMETERS)
        common.check_updates(self, ANALYSIS_PARAMETERS)
        if values["convention"]:
            config = config.with_overrides(convention=values["convention"])
        settings = AnalysisSettings(
            values["window"], values["n_scales"], values["image_width"], values["max_columns"]
        )
        self.settings = settings
        self.session = AnalysisSession(config, settings)
        self.pubs = {name: create_publisher(self, name) for name in OUTPUTS}
        # shadow: made when the first shadow_block arrives
        self.measured: AnalysisSession | None = None
        self.measured_pubs: dict[str, Publisher] = {}
        self._measured_last: tuple[int, int, float] | None = None  # segment, index, x of the newest
        create_subscription(self, "state_block", self._on_state_block)
        create_subscription(self, "shadow_block", self._on_shadow_block)
        if values["per_sample_input"]:
            create_subscription(self, "state", self._on_state)
        create_subscription(self, "run_config", self._on_run_config)
        self.sim_time = common.uses_sim_time(self)
        common.steady_timer(self, values["publish_period"], self._tick)
        self.get_logger().info(
            f"analysis: window {settings.window} samples, {settings.n_scales} scales, "
            f"use_sim_time {str(self.sim_time).lower()}"
        )

    def _on_run_config(self, msg: String) -> None:
        problem = self.session.run_config_input(msg.data)
        if problem is not None:
            self.get_logger().warning(f"ignoring an invalid run_config message: {problem}")
            return
        if self.measured is not None:
            self.measured.run_config_input(msg.data)
        self.get_logger().info(f"analysis: run configuration {self.session.config.name!r} from the plant")

    def _on_state_block(self, msg: RigStateBlock) -> None:
        n = len(msg.displacement)
        start = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        newest = start + (n - 1) * msg.sample_period if n else None
        self._take(
            self.session,
            msg.displacement,
            msg.velocity,
            msg.band_velocity,
            msg.relative_velocity,
            newest=newest,
        )

    def _on_shadow_block(self, msg: ShadowBlock) -> None:
        """The measured displacement of the pairs into the measured signal's session (shadow)."""
        index = np.asarray(msg.sample_index, dtype=np.int64)
        x = np.asarray(msg.measured_displacement, dtype=float)
        band = np.asarray(msg.band_velocity, dtype=float)
        if not index.size or not (index.size == x.size == band.size) or not msg.sample_period > 0:
            return
        if self.measured is None:
            self.measured = AnalysisSession(self.session.config, self.settings)
            self.measured_pubs = {n: create_publisher(self, f"measured/{n}") for n in MEASURED_OUTPUTS}
            self.get_logger().info("analysis: shadow blocks arrive; the measured signal is analysed too")
        last = self._measured_last
        previous = (last[1], last[2]) if last is not None and last[0] == msg.segment else None
        velocity = measured_velocity(index, x, msg.sample_period, previous)
        self._measured_last = (int(msg.segment), int(index[-1]), float(x[-1]))
        relative = self.measured.config.rig.relative_velocity(band, velocity)
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        self._take(self.measured, x, velocity, band, relative, newest=stamp)

    def _on_state(self, msg: RigState) -> None:
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        self._take(
            self.session,
            [msg.displacement],
            [msg.velocity],
            [msg.band_velocity],
            [msg.relative_velocity],
            newest=stamp,
        )

    def _take(self, session: AnalysisSession, *samples: Samples, newest: float | None) -> None:
        """Samples (x, ẋ, v_band, v_rel) into a session; the ones it skips as malformed are logged."""
        before = session.bad_messages
        x, velocity, band, relative = samples
        session.samples_input(x, velocity, band, relative, newest)
        if session.bad_messages > before:
            self.get_logger().warning(
                f"analysis: {session.bad_messages} malformed or non-finite samples skipped so far",
                throttle_duration_sec=5.0,
            )

    def _tick(self) -> None:
        out = self.session.tick()
        self._publish(out, self.pubs)
        if out.skipped is not None:
            self.get_logger().warning(f"analysis update skipped: {out.skipped}", throttle_duration_sec=5.0)
        if self.measured is not None:
            self._publish(self.measured.tick(), self.measured_pubs)

    def _stamp(self, out: AnalysisOutput) -> Time:
        """The stamp of an update's outputs (module docstring): rig time of its data, or now."""
        if self.sim_time and out.newest_time is not None:
            stamp = Time()
            stamp.sec, stamp.nanosec = cdr.stamp_of(max(0.0, out.newest_time))
            return stamp
        return self.get_clock().now().to_msg()

    def _publish(self, out: AnalysisOutput, p: dict[str, Publisher]) -> None:
        """The outputs of one update on the publishers `p` has (by output name)."""
        if out.linear_zone is not None and "linear_zone" in p:
            p["linear_zone"].publish(UInt8(data=out.linear_zone))
        if out.critical_damping_ratio is not None and "critical_damping_ratio" in p:
            p["critical_damping_ratio"].publish(Float64(data=out.critical_damping_ratio))
        if out.power is not None and "wavelet_power" in p:
            msg = Float64MultiArray()
            rows, cols = out.power.shape
            msg.layout.dim = [
                MultiArrayDimension(label="frequency", size=rows, stride=rows * cols),
                MultiArrayDimension(label="time", size=cols, stride=cols),
            ]
            msg.data = common.doubles(out.power.ravel())  # a list would be checked item by item
            p["wavelet_power"].publish(msg)
        now = self._stamp(out)
        if out.power is not None and out.frequencies is not None:
            frame = WaveletFrame()
            frame.header.stamp = now
            rows, cols = out.power.shape
            frame.rows, frame.cols = rows, cols
            frame.frequency = array.array("d", out.frequencies.astype(np.float64).tobytes())
            start = out.power_start if out.power_start is not None else 0.0
            end = out.power_end if out.power_end is not None else 0.0
            frame.start.sec, frame.start.nanosec = cdr.stamp_of(max(0.0, start))
            frame.end.sec, frame.end.nanosec = cdr.stamp_of(max(0.0, end))
            frame.power = array.array("f", np.ascontiguousarray(out.power, dtype=np.float32).tobytes())
            p["wavelet_frame"].publish(frame)
        if out.flags is not None:
            stability = stability_message(out.flags, self.session.config.rig.damping_ratio)
            stability.header.stamp = now
            p["stability"].publish(stability)
        if out.dominant_frequency is not None and "dominant_frequency" in p:
            p["dominant_frequency"].publish(Float64(data=out.dominant_frequency))
        if out.image is not None and "wavelet_image" in p:
            image = Image()
            image.header.stamp = now
            image.header.frame_id = "wavelet"
            image.height, image.width = out.image.shape[0], out.image.shape[1]
            image.encoding = "rgb8"
            image.step = 3 * out.image.shape[1]
            image.data = out.image.tobytes()
            p["wavelet_image"].publish(image)
        if out.oscillation_growing is not None and "oscillation_growing" in p:
            p["oscillation_growing"].publish(Bool(data=out.oscillation_growing))
        if out.statuses and "/diagnostics" in p:
            diagnostics = DiagnosticArray()
            diagnostics.header.stamp = now
            diagnostics.status = [common.diagnostic_status(s, self) for s in out.statuses]
            p["/diagnostics"].publish(diagnostics)


def prepare() -> None:
    """Before the node is built (nodes/entry.py): the session's warm-up, on the default run.

    It loads numba's CPU target, the default friction law's cached kernels and what the first
    update imports (AnalysisSession.warm_up); the node's own warm-up on its run's configuration
    then finds them loaded (a run of another law loads that law's kernels). Imported here: the
    module stays numba-free.
    """
    from ..app.selection import RunSelection

    common.load_numba_target()
    AnalysisSession.warm_up(RunSelection().resolve())


def main(args: list[str] | None = None) -> int:
    """Console script / ros2 run entry point."""
    return common.spin_node(Analysis, args)


if __name__ == "__main__":
    raise SystemExit(main())
