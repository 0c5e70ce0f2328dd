"""Physical ranges have one home (core/schema.py): the YAML comments, the node parameters, the
run configuration and the profile kinds all apply or state the same ranges."""

from __future__ import annotations

import math
import re
from dataclasses import fields
from pathlib import Path

import pytest

from lubrig_ros.app.interface import contract
from lubrig_ros.app.plant.config import config_from
from lubrig_ros.core import schema
from lubrig_ros.core.friction_laws import law_names, law_parameters
from lubrig_ros.core.params import ParameterError
from lubrig_ros.core.presets import SIMULATION_KEYS, config_dir, default_config, from_mapping
from lubrig_ros.core.profiles import ConstantBand, ProfileParameters, profile_class

CONFIG = config_dir()
KEY_LINE = re.compile(r"^( *)([A-Za-z_]+):(.*)$")


def _spec(path: list[str]) -> schema.FieldSpec | None:
    if len(path) == 2 and path[0] == "rig":
        return schema.RIG_FIELDS.get(path[1])
    if len(path) == 3 and path[:2] == ["rig", "friction"]:
        return schema.friction_field("junction_kinetics", path[2])
    if len(path) == 2 and path[0] == "simulation":
        return schema.SIMULATION_FIELDS.get(path[1])
    if len(path) == 2 and path[0] == "band":
        return schema.band_field(path[1])
    return None


def _field_lines(path: Path) -> list[tuple[list[str], str]]:
    """(key path, line) of every mapping key of a YAML file (indentation 2)."""
    out, stack = [], []
    for line in path.read_text().splitlines():
        m = KEY_LINE.match(line)
        if m:
            stack = [*stack[: len(m.group(1)) // 2], m.group(2)]
            out.append((list(stack), line))
    return out


@pytest.mark.parametrize("name", ["rig.yaml", "stickslip.yaml"])
def test_yaml_comments_state_the_schema_range_of_every_field(name):
    checked = 0
    for path, line in _field_lines(CONFIG / name):
        spec = _spec(path)
        if spec is None:
            continue
        comment = line.partition("#")[2]
        assert spec.range_text().removeprefix("[").removeprefix("(") in comment, (path, line)
        checked += 1
    assert checked >= (20 if name == "rig.yaml" else 2)


def test_nodes_yaml_comments_state_the_contract_range():
    node = None
    checked = 0
    for line in (CONFIG / "nodes.yaml").read_text().splitlines():
        if m := re.match(r"^/\*\*/(\w+):", line):
            node = m.group(1)
        elif (m := re.match(r"^    (\w+): ", line)) and node:
            assert f"valid {contract.parameter(node, m.group(1)).expected()}" in line, line
            checked += 1
    assert checked >= 10


def test_the_schema_covers_every_field_of_the_laws_kinds_and_simulation():
    for law in law_names():
        table = schema.friction_fields(law)
        assert set(table) == {f.name for f in fields(law_parameters(law))}, law
    numeric = {"constant": {"velocity"}, "table": {"velocities"}}
    for kind, table in schema.BAND_FIELDS.items():
        expected = numeric.get(kind) or {f.name for f in fields(profile_class(kind))}
        assert set(table) == expected, kind
    assert tuple(schema.SIMULATION_FIELDS) == SIMULATION_KEYS


def _outside(spec: schema.FieldSpec) -> list[float]:
    below = spec.low if spec.low_open else math.nextafter(spec.low, -math.inf)
    return [below, math.nextafter(spec.high, math.inf), spec.high * 10 + 1, -1e308, 1e308, 5e-324]


def _schema_parameters(node: str):
    for p in contract.NODE_PARAMETERS[node]:
        if p.type != "double" or not p.from_config:
            continue
        *section, name = p.from_config.split(".")
        spec = _spec([*section, name])
        yield p, spec


def test_node_parameters_carry_the_schema_range():
    seen = 0
    for node in ("plant", "belt_drive"):
        for p, spec in _schema_parameters(node):
            assert spec is not None, p.name
            assert p.unit == spec.unit and p.high == spec.high, p.name
            if p.zero_means:
                assert p.low == 0.0 and p.nonzero_low == spec.low, p.name
            else:
                assert (p.low, p.low_open) == (spec.low, spec.low_open), p.name
            seen += 1
    assert seen >= 30


def test_the_nodes_and_a_run_configuration_refuse_the_same_values():
    """What the plant's parameter check refuses, the run configuration (CLI, YAML) refuses too."""
    base = default_config()
    for p, spec in _schema_parameters("plant"):
        for value in _outside(spec):
            if (p.zero_means and value == 0.0) or spec.contains(value):
                continue
            with pytest.raises(ParameterError, match=re.escape(p.name)):
                p.check(value)
            with pytest.raises(ParameterError):
                config_from(base, {p.name: value})
        for value in (spec.low if not spec.low_open else None, spec.high):
            if value is None or (p.name == "duration" and value < 1e-3):
                continue
            p.check(value)
            values = {p.name: value}
            if p.name == "rig.natural_frequency":
                values["sample_rate"] = schema.SIMULATION_FIELDS["sample_rate"].high
            if p.name == "sample_rate":
                values["rig.natural_frequency"] = schema.RIG_FIELDS["natural_frequency"].low
            if p.name == "friction.interpenetration_thickness" and value > 1e-8:
                values["friction.interface_thickness"] = value
            config_from(base, values)


@pytest.mark.parametrize(
    ("band", "match"),
    [
        (
            {"kind": "constant", "velocity": 1e308},
            r"velocity=1e\+308 is outside the physical range \[-0.01, 0.01\] m/s",
        ),
        ({"kind": "cycle", "ramp_time": 0.0}, r"ramp_time=0.0 is outside the physical range \(0, "),
        ({"kind": "cycle", "plateau_time": 5e-324, "ramp_time": 1e308}, r"ramp_time=1e\+308"),
        ({"kind": "sine", "mean_velocity": 0.008, "amplitude": 0.005}, r"\|mean_velocity\| \+ amplitude"),
        ({"kind": "sine", "frequency": 600.0}, "above half the sample rate"),
        ({"kind": "sine", "phase": 1e308}, r"phase=1e\+308"),
        ({"kind": "table", "times": [0, 1], "velocities": [0, 1.0]}, "row 2 has velocity=1.0"),
    ],
)
def test_band_fields_and_their_cross_checks(band, match):
    with pytest.raises(ParameterError, match=match):
        from_mapping({"band": band})


@pytest.mark.parametrize(
    ("data", "match"),
    [
        ({"rig": {"friction": {"yield_distance": 1e308}}}, r"yield_distance=1e\+308 is outside"),
        ({"rig": {"friction": {"contact_area": 1e308}}}, r"contact_area=1e\+308"),
        ({"rig": {"friction": {"interpenetration_thickness": 1e-8}}}, r"\(d <= D\)"),
        ({"rig": {"velocity_coupling": 1e308}}, r"velocity_coupling=1e\+308"),
        ({"rig": {"friction": {"law": "stribeck", "stribeck_velocity": 5e-324}}}, "stribeck_velocity"),
        ({"simulation": {"initial_perturbation": -1e308}}, r"initial_perturbation=-1e\+308"),
        ({"simulation": {"duration": 1e-4}}, "holds no sample"),
        ({"simulation": {"duration": 1e6, "sample_rate": 1e5}}, "samples; at most"),
    ],
)
def test_absurd_values_and_cross_checks_are_refused(data, match):
    with pytest.raises(ParameterError, match=match):
        from_mapping(data)


def test_a_field_of_an_inactive_profile_kind_is_checked_too():
    params = ProfileParameters(ConstantBand(1e-7))
    with pytest.raises(ParameterError, match=r"profile.frequency=1e\+308 is outside the physical range"):
        params.apply({"frequency": 1e308})
    assert params.values("sine")["frequency"] == 1.0  # nothing changed
    params.apply({"frequency": 2.0})
    assert params.values("sine")["frequency"] == 2.0 and params.kind == "constant"


def test_every_rig_parameter_has_one_schema_entry():
    """A RigParameters field (but the named convention and the friction law) is a RIG_FIELDS entry."""
    from lubrig_ros.core.params import RigParameters

    on_rig = {f.name for f in fields(RigParameters)} - {"convention", "friction"}
    assert set(schema.rig_fields(on_rig=True)) == on_rig
    assert set(schema.rig_fields(held="friction")) == {"normal_force"}
    assert schema.RIG_OVERRIDES[0] == "convention"


def test_where_a_rig_parameter_may_be_set_derives_from_its_schema_entry():
    import argparse

    from lubrig_ros.app.selection import RunSelection
    from lubrig_ros.cli.common import add_run_selection
    from lubrig_ros.fit.parameters import fittable_names

    parser = argparse.ArgumentParser()
    add_run_selection(parser)
    options = {o: a.help or "" for a in parser._actions for o in a.option_strings}
    plant = {p.name for p in contract.PLANT_PARAMETERS}
    base = default_config()
    fittable = fittable_names(base)
    for name, spec in schema.RIG_FIELDS.items():
        if spec.cli_option is not None:
            assert spec.range_text() in options[spec.cli_option], name
        if spec.node:
            assert f"rig.{name}" in plant and name in contract.RIG_FIELDS, name
        if spec.on_rig:  # normal_force is fittable as the friction law's field
            assert (name in fittable) == spec.fit, name
        assert (name in schema.RIG_OVERRIDES) == spec.override, name
        if spec.override and spec.on_rig and spec.unset == "":
            value = spec.high if name != "natural_frequency" else spec.low
            assert getattr(RunSelection(**{name: value}).resolve().rig, name) == value, name


@pytest.mark.parametrize(
    ("name", "value", "message"),
    [
        ("mass", 0.0, "mass=0.0 must be > 0"),
        ("natural_frequency", -1.0, "natural_frequency=-1.0 must be > 0"),
        ("damping_ratio", -0.1, "damping_ratio=-0.1 must be >= 0"),
        ("damping_ratio", math.nan, "damping_ratio=nan is not finite"),
        ("mass", "x", "mass='x' is not a number"),
    ],
)
def test_rig_parameters_check_the_models_own_bound_from_the_schema(name, value, message):
    from lubrig_ros.core.params import RigParameters

    with pytest.raises(ParameterError, match=re.escape(message)):
        RigParameters(**{name: value})
    assert RigParameters(damping_ratio=0.0).damping_ratio == 0.0


def test_the_default_rig_states_every_rig_parameter():
    """config/rig.yaml, the built-in defaults, has a line for every RIG_FIELDS entry (its range: above)."""
    paths = {tuple(path) for path, _ in _field_lines(CONFIG / "rig.yaml")}
    for name, spec in schema.RIG_FIELDS.items():
        assert (("rig", name) if spec.on_rig else ("rig", spec.held, name)) in paths, name
