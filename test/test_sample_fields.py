"""The plant's per-sample output comes from one table (core.schema.SAMPLE_FIELDS) and its formulas."""

from __future__ import annotations

import numpy as np
import pytest

from lubrig_ros.app.plant import output as plant_output
from lubrig_ros.app.plant.output import BLOCK_FIELDS, QUANTITIES, PlantSample, derive, derive_columns
from lubrig_ros.core.schema import SAMPLE_FIELDS, SAMPLE_UNITS, SampleField


def test_one_sample_and_a_block_get_the_same_values_from_the_formulas():
    rng = np.random.default_rng(7)
    arrays = [rng.normal(size=5) for _ in QUANTITIES[:-1]]
    normal_force = 1e-3
    columns = derive_columns((5,), *arrays, normal_force)
    assert list(columns) == list(BLOCK_FIELDS) == [f.name for f in SAMPLE_FIELDS]
    for i in range(5):
        one = derive(*(float(a[i]) for a in arrays), normal_force)
        assert one == tuple(float(columns[name][i]) for name in BLOCK_FIELDS)
    by_name = dict(zip(QUANTITIES, arrays, strict=False))
    assert np.array_equal(columns["friction_force"], by_name["friction_coefficient"] * normal_force)
    assert np.array_equal(columns["belt_travel"], by_name["belt_travel"])


def test_a_constant_field_is_broadcast_over_a_block(monkeypatch):
    fields = (*SAMPLE_FIELDS, SampleField("normal_load", "N", "N", "test field", "normal_force"))
    monkeypatch.setattr(plant_output, "SAMPLE_FIELDS", fields)
    monkeypatch.setattr(plant_output, "BLOCK_FIELDS", tuple(f.name for f in fields))
    monkeypatch.setattr(plant_output, "derive", plant_output._compile_formulas())
    columns = plant_output.derive_columns((3,), *(np.arange(3.0) for _ in QUANTITIES[:-1]), 2e-3)
    assert np.array_equal(columns["normal_load"], np.full(3, 2e-3))


def test_a_formula_over_an_unknown_name_is_refused_naming_it(monkeypatch):
    bad = SampleField("power", "W", "P", "test field", "friction_force * speed")
    monkeypatch.setattr(plant_output, "SAMPLE_FIELDS", (*SAMPLE_FIELDS, bad))
    with pytest.raises(ImportError, match=r"'power'.*\['friction_force', 'speed'\].*valid names"):
        plant_output._compile_formulas()


def test_a_formula_cannot_reach_builtins(monkeypatch):
    sneaky = SampleField("n", "1", "", "test field", "len(displacement)")
    monkeypatch.setattr(plant_output, "SAMPLE_FIELDS", (sneaky,))
    with pytest.raises(ImportError, match="'len'"):
        plant_output._compile_formulas()


def test_a_sample_names_its_fields():
    values = tuple(float(i) for i in range(len(BLOCK_FIELDS)))
    s = PlantSample(0.25, values, 3, 1)
    assert [getattr(s, name) for name in BLOCK_FIELDS] == list(values)
    assert (s.time, s.sample_index, s.segment) == (0.25, 3, 1)
    with pytest.raises(AttributeError, match="no field 'speed'"):
        _ = s.speed


def test_every_sample_field_has_a_unit_column():
    assert all(SAMPLE_UNITS[f.name] == f.unit for f in SAMPLE_FIELDS)
