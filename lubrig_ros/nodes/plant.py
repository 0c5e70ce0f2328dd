"""plant node: the rig (app.plant_session.PlantSession) on ROS topics, driven by <ns>/band_velocity.

Modes sim | realtime | rig_in_loop; their rules live in app/plant_session.py (unit-tested without
DDS): sim integrates one sample per band message, in order, equal to core.run.simulate, and
publishes /clock; realtime modes tick from a deadline loop with the latest good band value.
Services <ns>/plant/reset and <ns>/plant/pause. Topics, QoS, parameters: app/contract.py.
"""

from __future__ import annotations

import sys
import threading

from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64, String
from std_srvs.srv import SetBool, Trigger

from ..app import cdr, contract
from ..app.plant_session import (
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
from . import common
from .interfaces import create_publisher, create_service, create_subscription


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
        self.wait_for_subscriber = values["wait_for_subscriber"]
        settings = PlantSettings(values["mode"], values["band_velocity_limit"], values["stale_timeout"])
        outputs = ("displacement", "velocity", "friction_coefficient", "state")
        self.pub_x, self.pub_v, self.pub_mu, self.pub_state = (create_publisher(self, n) for n in outputs)
        self.pub_clock = create_publisher(self, "/clock") if self.mode == "sim" else None
        self.pub_diag = create_publisher(self, "/diagnostics")
        self.pub_config = create_publisher(self, "run_config")
        self.pub_complete = create_publisher(self, "run_complete")
        self._msgs = (Float64(), Float64(), Float64(), JointState(), Clock())
        self._msgs[3].name = ["mass", "band"]
        self.session = PlantSession(
            base,
            settings,
            config=config_from(base, self._config_values()),
            on_sample=self._publish,
            on_complete=lambda done: self.pub_complete.publish(Bool(data=done)),
            log=self._log,
        )
        self.add_on_set_parameters_callback(self._on_set_parameters)
        common.check_updates(self, contract.plant_parameters(law))
        self.pub_config.publish(String(data=self.session.config.to_yaml()))
        self.pub_complete.publish(Bool(data=False))
        # raw (serialized CDR) subscription: about 2x cheaper per message than a Float64 object
        create_subscription(self, "band_velocity", self._on_band_raw, raw=True)
        create_service(self, "plant/reset", self._on_reset)
        create_service(self, "plant/pause", self._on_pause)
        self.create_timer(values["diagnostics_period"], self._publish_diagnostics)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        if self.mode == "sim":
            self.create_timer(0.2, self._heartbeat)
        else:
            sys.setswitchinterval(2e-4)  # let the loop thread take the GIL promptly
            common.enter_realtime(values["realtime_priority"], self)
            self._thread = threading.Thread(target=self._realtime_loop, daemon=True)
            self._thread.start()
        config = self.session.config
        self.get_logger().info(
            f"plant: mode={self.mode}, {config.sample_rate:g} Hz, {config.rig.coupling_label}, "
            f"friction law {law}, {config.samples} samples per run (sim)"
        )

    def _on_band_raw(self, data: bytes) -> None:
        self.session.band_input(cdr.float64_value(data))  # malformed payload: NaN, rejected

    def _log(self, level: str, text: str) -> None:
        getattr(self.get_logger(), level)(text)

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
        self.session.reset(config)
        self.get_logger().info("reset: rig time back to 0")
        response.success, response.message = True, "rig reset to t = 0 and the initial state"
        return response

    def _on_pause(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        response.success, response.message = True, self.session.set_paused(bool(request.data))
        self.get_logger().info(f"pause: {response.message}")
        return response

    def _heartbeat(self) -> None:
        """Sim: republish /clock so that a late belt_drive sees where the plant is.

        Until the awaited subscriber (the recorder) has subscribed to every output, the plant stays
        silent, so belt_drive does not start and no sample is published before it is recorded.
        """
        outputs = (self.pub_x, self.pub_v, self.pub_mu, self.pub_state, self.pub_clock)
        if not common.subscribed_by(self, [p.topic_name for p in outputs], self.wait_for_subscriber):
            return
        self.wait_for_subscriber = ""  # seen once: no need to ask the graph again
        clock = Clock()
        clock.clock.sec, clock.clock.nanosec = cdr.stamp_of(self.session.time)
        self.pub_clock.publish(clock)

    def _publish(self, s: PlantSample) -> None:
        mx, mv, mmu, state, clock = self._msgs
        sec, nsec = cdr.stamp_of(s.time)
        mx.data, mv.data, mmu.data = s.displacement, s.velocity, s.friction_coefficient
        state.header.stamp.sec, state.header.stamp.nanosec = sec, nsec
        # joint "mass": x, ẋ, friction force; joint "band": belt travel, the band velocity this
        # sample was integrated with (so subscribers pair each state with its own v_band), 0
        state.position = [s.displacement, s.belt_travel]
        state.velocity = [s.velocity, s.band_velocity]
        state.effort = [s.friction_force, 0.0]
        self.pub_x.publish(mx)
        self.pub_v.publish(mv)
        self.pub_mu.publish(mmu)
        self.pub_state.publish(state)
        if self.pub_clock is not None:
            clock.clock.sec, clock.clock.nanosec = sec, nsec
            self.pub_clock.publish(clock)

    def _realtime_loop(self) -> None:
        try:
            self.session.run_realtime(self._stop.is_set)
        except Exception as exc:
            if not self._stop.is_set() and self.context.ok():
                self.get_logger().fatal(f"real-time loop stopped: {exc!r}")

    def _publish_diagnostics(self) -> None:
        array = DiagnosticArray()
        array.header.stamp = self.get_clock().now().to_msg()
        array.status = [common.diagnostic_status(s) for s in self.session.diagnostics()]
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
