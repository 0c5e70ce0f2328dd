"""Parameter fuzz (issue 11): random values and types for every parameter of every node.

belt_drive, plant and analysis run a sim rig; every parameter each node lists gets values of
every kind (NaN, ±inf, huge, tiny, negative, zero, wrong types, arrays). Asserted: no node dies or
stops answering, a non-finite number is never accepted, every refusal carries a reason that names
the parameter, and nothing any node publishes holds a non-finite number.
"""

from __future__ import annotations

import math
import random
from typing import Any

from rcl_interfaces.srv import ListParameters

from lubrig_ros.app import contract
from lubrig_ros.nodes.interfaces import message_class, qos_profile

NS = contract.DEFAULT_NAMESPACE
NODES = ("plant", "belt_drive", "analysis")
VALUES: tuple[Any, ...] = (
    math.nan, math.inf, -math.inf, -1.0, 0.0, 1e308, -1e308, 5e-324, 1e-7, 1000.0, 2**62, -1, 0,
    "", "garbage", True, False, [1.0, 2.0], ["x"],
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


def test_no_value_of_any_type_kills_a_node_or_is_published_non_finite(procs, probe):
    bad: list[str] = []

    def check(topic: str):
        return lambda msg: bad.extend(f"{topic}{p}" for p in _non_finite(msg))

    for spec in contract.documented_topics(NS).values():
        probe.node.create_subscription(
            message_class(spec.msgtype), spec.name, check(spec.name), qos_profile(spec.qos)
        )
    for node in NODES:
        procs.node(node, case=1, duration=60.0)
    rng = random.Random(20261201)
    tried = refused = 0
    for node in NODES:
        names = probe.call(
            ListParameters, f"{NS}/{node}/list_parameters", ListParameters.Request(), 120
        ).result.names
        assert len(names) >= 5, (node, names)
        for name in names:
            for value in rng.sample(VALUES, PER_PARAMETER):
                result = probe.set_parameter(f"lubrig/{node}", name, value)
                tried += 1
                if isinstance(value, float) and not math.isfinite(value):
                    assert not result.successful, (node, name, value)
                if not result.successful:
                    refused += 1
                    assert result.reason, (node, name, value)
                    # rclpy's own refusals (type, read-only) may not name it; ours must
                    assert name in result.reason or "read-only" in result.reason.lower() or (
                        "type" in result.reason.lower()
                    ), (node, name, value, result.reason)
        assert procs[node].running(), procs.logs()
    assert tried > 100 and refused > tried // 2, (tried, refused)
    for node in NODES:  # still answering after the fuzz
        probe.call(ListParameters, f"{NS}/{node}/list_parameters", ListParameters.Request(), 60)
        assert procs[node].running(), procs.logs()
    assert not bad, bad[:20]
    codes = procs.stop_all()
    assert all(code == 0 for code in codes.values()), (codes, procs.logs())
