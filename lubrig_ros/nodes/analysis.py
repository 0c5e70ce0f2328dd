"""analysis node: online wavelet analysis of the plant's displacement and stability flags.

Subscribes to <ns>/state (x, ẋ) and <ns>/band_velocity; every `publish_period` s (wall) the
samples received since the last update go into app.analysis_session.AnalysisSession, and the node
publishes what it returns: the dominant frequency, the newest wavelet power columns
(Float64MultiArray, dims ["frequency", "time"]), an rgb8 image of the window's power, the linear
zone and ζ_crit at the current band velocity, the stability flags on /diagnostics (one status per
flag group) and <ns>/oscillation_growing. The rig comes from case/config_file and is replaced by
the plant's latched <ns>/run_config when it arrives. Topics, QoS, parameters: app/contract.py.
"""

from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from sensor_msgs.msg import Image, JointState
from std_msgs.msg import Bool, Float64, Float64MultiArray, MultiArrayDimension, String, UInt8

from ..app.analysis_session import AnalysisOutput, AnalysisSession, AnalysisSettings
from ..app.contract import ANALYSIS_PARAMETERS
from . import common
from .interfaces import create_publisher, create_subscription

OUTPUTS = (
    "dominant_frequency", "wavelet_power", "wavelet_image", "linear_zone", "critical_damping_ratio",
    "oscillation_growing", "/diagnostics",
)


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
        self.session = AnalysisSession(config, settings)
        self.pubs = {name: create_publisher(self, name) for name in OUTPUTS}
        create_subscription(self, "state", self._on_state)
        create_subscription(self, "band_velocity", lambda m: self.session.band_input(m.data))
        create_subscription(self, "run_config", self._on_run_config)
        self.create_timer(values["publish_period"], self._tick)
        self.get_logger().info(f"analysis: window {settings.window} samples, {settings.n_scales} scales")

    def _on_run_config(self, msg: String) -> None:
        problem = self.session.run_config_input(msg.data)
        if problem is not None:
            self.get_logger().warning(f"ignoring an invalid run_config message: {problem}")
            return
        self.get_logger().info(f"analysis: run configuration {self.session.config.name!r} from the plant")

    def _on_state(self, msg: JointState) -> None:
        self.session.state_input(msg.position, msg.velocity)

    def _tick(self) -> None:
        out = self.session.tick()
        self._publish(out)
        if out.skipped is not None:
            self.get_logger().warning(f"analysis update skipped: {out.skipped}", throttle_duration_sec=5.0)

    def _publish(self, out: AnalysisOutput) -> None:
        p = self.pubs
        if out.linear_zone is not None:
            p["linear_zone"].publish(UInt8(data=out.linear_zone))
        if out.critical_damping_ratio is not None:
            p["critical_damping_ratio"].publish(Float64(data=out.critical_damping_ratio))
        if out.power is not None:
            msg = Float64MultiArray()
            rows, cols = out.power.shape
            msg.layout.dim = [
                MultiArrayDimension(label="frequency", size=rows, stride=rows * cols),
                MultiArrayDimension(label="time", size=cols, stride=cols),
            ]
            msg.data = out.power.ravel().tolist()
            p["wavelet_power"].publish(msg)
        if out.dominant_frequency is not None:
            p["dominant_frequency"].publish(Float64(data=out.dominant_frequency))
        if out.image is not None:
            image = Image()
            image.header.stamp = self.get_clock().now().to_msg()
            image.header.frame_id = "wavelet"
            image.height, image.width = out.image.shape[0], out.image.shape[1]
            image.encoding = "rgb8"
            image.step = 3 * out.image.shape[1]
            image.data = out.image.tobytes()
            p["wavelet_image"].publish(image)
        if out.oscillation_growing is not None:
            p["oscillation_growing"].publish(Bool(data=out.oscillation_growing))
        if out.statuses:
            array = DiagnosticArray()
            array.header.stamp = self.get_clock().now().to_msg()
            array.status = [common.diagnostic_status(s) for s in out.statuses]
            p["/diagnostics"].publish(array)


def main(args: list[str] | None = None) -> int:
    """Console script / ros2 run entry point."""
    return common.spin_node(Analysis, args)


if __name__ == "__main__":
    raise SystemExit(main())
