"""What a Foxglove client may do through `view --allow-*`: names and checks (app/view/access.py)."""

from __future__ import annotations

import json
import math
import struct

import pytest

from lubrig_ros.app.interface.contract import SERVICES
from lubrig_ros.app.interface.node_parameters import NODE_PARAMETERS
from lubrig_ros.app.view import access as view_access
from lubrig_ros.core.errors import InputError


def _float64_cdr(value: float) -> bytes:
    return b"\x00\x01\x00\x00" + struct.pack("<d", value)


def test_read_only_unless_opened():
    assert view_access.Access().opened() == []
    assert view_access.Access(services=True, publish=True).opened() == ["services", "publish"]


def test_services_and_nodes_come_from_the_contract():
    assert [s.name for s in view_access.rig_services("/rig2")] == [f"/rig2/{s.name}" for s in SERVICES]
    assert view_access.rig_nodes("/rig2") == {f"/rig2/{n}": n for n in NODE_PARAMETERS}
    assert view_access.resolve_node("/", "plant") == "/plant"
    assert view_access.resolve_node("/lubrig", "plant") == "/lubrig/plant"


def test_parameter_names_round_trip_and_foreign_names_are_refused():
    nodes = view_access.rig_nodes("/lubrig")
    full = view_access.parameter_name("/lubrig/plant", "friction.peak_coefficient")
    assert full == "/lubrig/plant.friction.peak_coefficient"
    assert view_access.split_parameter_name(full, nodes) == ("/lubrig/plant", "friction.peak_coefficient")
    for bad in ("/lubrig/plant", "/lubrig/plant.", "/other/plant.rtol", "rtol", "/lubrig/view.x"):
        with pytest.raises(InputError, match="is not a rig node's") as exc:
            view_access.split_parameter_name(bad, nodes)
        assert repr(bad) in str(exc.value) and "/lubrig/plant" in str(exc.value)


@pytest.mark.parametrize(
    ("topic", "encoding", "schema", "problem"),
    [
        ("/lubrig/band_velocity", "cdr", "std_msgs/msg/Float64", None),
        ("/lubrig/band_velocity", "json", "std_msgs/Float64", None),
        ("/lubrig/state", "cdr", "std_msgs/msg/Float64", "only /lubrig/band_velocity"),
        ("/rig2/band_velocity", "cdr", "std_msgs/msg/Float64", "only /lubrig/band_velocity"),
        ("/lubrig/band_velocity", "cdr", "std_msgs/msg/Float32", "takes std_msgs/msg/Float64"),
        ("/lubrig/band_velocity", "protobuf", "std_msgs/msg/Float64", "not one of ['cdr', 'json']"),
    ],
)
def test_only_band_velocity_float64_may_be_published(topic, encoding, schema, problem):
    found = view_access.band_channel_problem("/lubrig", topic, encoding, schema)
    assert found is None if problem is None else problem in found


def test_band_values_finite_or_refused():
    assert view_access.band_value("cdr", _float64_cdr(2.5e-7)) == 2.5e-7
    assert view_access.band_value("json", json.dumps({"data": 3}).encode()) == 3.0
    refused = [
        ("cdr", _float64_cdr(math.nan)),
        ("cdr", _float64_cdr(-math.inf)),
        ("cdr", b"\x00\x01"),  # too short
        ("json", b'{"data": true}'),
        ("json", b'{"data": "1e-7"}'),
        ("json", b'{"value": 1e-7}'),
        ("json", b"not json"),
        ("json", b'{"data": 1e999}'),  # inf
    ]
    for encoding, data in refused:
        with pytest.raises(InputError, match="band input"):
            view_access.band_value(encoding, data)


def test_band_input_only_to_a_rig_in_the_loop_plant():
    assert view_access.band_mode_problem("/lubrig", "rig_in_loop") is None
    for mode in ("sim", "lockstep", "realtime"):
        problem = view_access.band_mode_problem("/lubrig", mode)
        assert problem is not None and repr(mode) in problem and "rig_in_loop" in problem
    assert "no plant /rig2/plant answered" in str(view_access.band_mode_problem("/rig2", None))
