"""belt_drive's profile.* parameters on a real rclpy node (in this process, its own ROS domain).

Parameters are set through the node's own parameter API (the path `ros2 param set` ends in), so
the pre-set completion of a kind switch and the validation run as in a launched node.
"""

from __future__ import annotations

import os
import random
from collections.abc import Iterator

import pytest
from rclpy.parameter import Parameter
from test_profile_registry import SquareBand

from lubrig_ros.core.profiles import RegularCycle, SinusoidalBand, register_profile, unregister_profile

pytestmark = pytest.mark.ros


@pytest.fixture
def node(monkeypatch: pytest.MonkeyPatch) -> Iterator[object]:
    import rclpy

    from lubrig_ros.nodes.belt_drive import BeltDrive

    monkeypatch.setenv("ROS_DOMAIN_ID", str(random.Random(os.getpid()).randint(100, 200)))
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    register_profile(SquareBand)
    rclpy.init(args=["--ros-args", "-p", "mode:=realtime", "-p", "profile.kind:=sine"])
    drive = None
    try:
        drive = BeltDrive()
        yield drive
    finally:
        if drive is not None:
            drive.destroy_node()
        rclpy.shutdown()
        unregister_profile("square")


def _set(node: object, **values: object) -> object:
    return node.set_parameters_atomically(  # type: ignore[attr-defined]
        [Parameter(f"profile.{k}", value=v) for k, v in values.items()]
    )


def test_kind_switch_uses_the_new_kinds_own_values(node: object) -> None:
    get = node.get_parameter  # type: ignore[attr-defined]
    assert node.profile == SinusoidalBand()  # type: ignore[attr-defined]
    assert "square" in node.describe_parameter("profile.kind").description  # type: ignore[attr-defined]
    assert _set(node, frequency=2.0).successful
    assert node.profile == SinusoidalBand(frequency=2.0)  # type: ignore[attr-defined]
    result = _set(node, kind="cycle", low_velocity=5e-8)
    assert result.successful, result.reason
    assert node.profile == RegularCycle(low_velocity=5e-8)  # type: ignore[attr-defined]
    # one parameter profile.frequency, but square gets its own value, and the parameter says so
    assert _set(node, kind="square").successful
    assert node.profile == SquareBand()  # type: ignore[attr-defined]
    assert get("profile.frequency").value == 5.0 and get("profile.low_velocity").value == 1e-7
    assert _set(node, kind="sine").successful
    assert node.profile == SinusoidalBand(frequency=2.0)  # type: ignore[attr-defined]
    assert get("profile.frequency").value == 2.0


def test_invalid_profile_updates_are_rejected_and_change_nothing(node: object) -> None:
    result = _set(node, kind="sawtooth")
    assert not result.successful and "sawtooth" in result.reason and "constant" in result.reason
    result = _set(node, frequency=-1.0)
    # refused by the descriptor's physical range (rclpy's wording names parameter, value and range)
    assert not result.successful and "profile.frequency" in result.reason and "-1.0" in result.reason
    result = _set(node, path=3.0)
    assert not result.successful  # a number for the string parameter: rclpy refuses the type
    assert node.profile == SinusoidalBand()  # type: ignore[attr-defined]
    assert node.get_parameter("profile.kind").value == "sine"  # type: ignore[attr-defined]
