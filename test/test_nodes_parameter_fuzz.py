"""Parameter fuzz: random values and types for every parameter of every node, sim and realtime.

belt_drive, plant and analysis run a rig; every parameter each node lists gets values of every
kind (NaN, ±inf, huge, tiny at the double-precision floor, negative, zero, wrong types, arrays),
then the plant is reset so that the accepted rig parameters apply. Asserted: no node dies or stops
answering, a non-finite number is never accepted, every accepted value is inside the parameter's
documented physical range (app/interface/node_parameters.py, from core/schema.py), every refusal carries a
reason that names the parameter, the run configuration the plant publishes after the reset is a
valid one (nothing outside a range was fabricated into it), and nothing any node publishes holds a
non-finite number.
"""

from __future__ import annotations

import math
import random
from typing import Any

import pytest
import yaml
from rcl_interfaces.srv import ListParameters
from std_srvs.srv import Trigger

from lubrig_ros.app.interface import contract
from lubrig_ros.core.presets import from_mapping
from lubrig_ros.nodes.interfaces import message_class, qos_profile

NS = contract.DEFAULT_NAMESPACE
NODES = ("plant", "belt_drive", "analysis")
VALUES: tuple[Any, ...] = (
    math.nan,
    math.inf,
    -math.inf,
    -1.0,
    0.0,
    1e308,
    -1e308,
    5e-324,
    -5e-324,
    1e-7,
    1000.0,
    2**62,
    -1,
    0,
    1,
    "",
    "garbage",
    True,
    False,
    [1.0, 2.0],
    ["x"],
)
PER_PARAMETER = 6


def _non_finite(value: Any, path: str = "") -> list[str]:
    """Paths of the non-finite floats inside a message."""
    if isinstance(value, float):
        return [] if math.isfinite(value) else [path]
    if hasattr(value, "get_fields_and_field_types"):
        out: list[str] = []
        for field in value.get_fields_and_field_types():
            out += _non_finite(getattr(value, field), f"{path}.{field}")
        return out
    if isinstance(value, (list, tuple)) or hasattr(value, "tolist"):
        items = value.tolist() if hasattr(value, "tolist") else value
        return [f"{path}[{i}]" for i, v in enumerate(items) if isinstance(v, float) and not math.isfinite(v)]
    return []


def _spec(node: str, name: str) -> contract.NodeParameter | None:
    if name.startswith("profile."):
        return contract.profile_parameter(name.removeprefix("profile."))
    try:
        return contract.parameter(node, name)
    except KeyError:
        return None  # rclpy's own (use_sim_time, start_type_description_service)


@pytest.mark.parametrize("mode", ["sim", "realtime"])
def test_no_value_of_any_type_kills_a_node_or_is_published_non_finite(procs, probe, mode):
    bad: list[str] = []
    configs: list[str] = []

    def check(topic: str):
        return lambda msg: bad.extend(f"{topic}{p}" for p in _non_finite(msg))

    for spec in contract.documented_topics(NS).values():
        probe.node.create_subscription(
            message_class(spec.msgtype), spec.name, check(spec.name), qos_profile(spec.qos)
        )
    run_config = contract.topic("run_config").resolved(NS)
    probe.node.create_subscription(
        message_class(run_config.msgtype),
        run_config.name,
        lambda m: configs.append(m.data),
        qos_profile(run_config.qos),
    )
    extra = {"max_lag": 10.0} if mode == "realtime" else {}
    procs.node("plant", case=1, duration=60.0, mode=mode, **extra)
    procs.node("belt_drive", case=1, duration=60.0, mode=mode)
    procs.node("analysis", case=1)
    rng = random.Random(20261201 + (mode == "realtime"))
    tried = refused = 0
    outside: list[str] = []
    for node in NODES:
        names = probe.call(
            ListParameters, f"{NS}/{node}/list_parameters", ListParameters.Request(), 120
        ).result.names
        assert len(names) >= 5, (node, names)
        for name in names:
            spec = _spec(node, name)
            for value in rng.sample(VALUES, PER_PARAMETER):
                result = probe.set_parameter(f"lubrig/{node}", name, value)
                tried += 1
                if isinstance(value, float) and not math.isfinite(value):
                    assert not result.successful, (node, name, value)
                if result.successful and spec is not None and spec.type in ("double", "integer"):
                    try:
                        spec.check(value)
                    except ValueError as exc:
                        outside.append(f"{node} {name}={value!r} accepted: {exc}")
                if not result.successful:
                    refused += 1
                    assert result.reason, (node, name, value)
                    # rclpy's own refusals (type, read-only) may not name it; ours must
                    assert (
                        name in result.reason
                        or "read-only" in result.reason.lower()
                        or ("type" in result.reason.lower())
                    ), (node, name, value, result.reason)
        assert procs[node].running(), procs.logs()
    assert not outside, outside[:20]
    assert tried > 100 and refused > tried // 2, (tried, refused)
    before = len(configs)
    reply = probe.call(Trigger, f"{NS}/plant/reset", Trigger.Request(), 60)
    assert reply.message, reply  # applied, or refused with a reason
    if reply.success:
        assert probe.wait_for(lambda: len(configs) > before, 30), procs.log("plant")
    for text in configs:  # every published configuration is one the ranges accept
        from_mapping(yaml.safe_load(text))
    for node in NODES:  # still answering after the fuzz and the reset
        probe.call(ListParameters, f"{NS}/{node}/list_parameters", ListParameters.Request(), 60)
        assert procs[node].running(), procs.logs()
    assert not bad, bad[:20]
    codes = procs.stop_all()
    assert all(code == 0 for code in codes.values()), (codes, procs.logs())
