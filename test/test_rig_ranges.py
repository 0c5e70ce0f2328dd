"""A run's rig stays in its physical ranges, and its sample rate resolves the natural frequency."""

from __future__ import annotations

import re
from dataclasses import replace

import pytest

from lubrig_ros.core.params import ParameterError, RigParameters
from lubrig_ros.core.presets import load_case
from lubrig_ros.core.schema import MIN_SAMPLES_PER_PERIOD, RIG_FIELDS


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("mass", 5e3),
        ("mass", 1e-6),
        ("natural_frequency", 1000.0),
        ("damping_ratio", 2.5),
        ("normal_force", 50.0),
    ],
)
def test_a_run_outside_a_physical_range_is_refused_naming_value_and_range(name, value):
    spec = RIG_FIELDS[name]
    base = load_case(1)
    if name == "normal_force":
        rig = replace(base.rig, friction=replace(base.rig.friction, normal_force=value))
        change = {"rig": rig}
    else:
        change = {"rig": replace(base.rig, **{name: value})}
    expected = f"{name}={value!r} is outside the physical range {spec.range_text()}"
    assert spec.unit in expected or spec.unit == "1"
    with pytest.raises(ParameterError, match=re.escape(expected)):
        replace(base, **change)


def test_the_linear_analysis_may_still_use_any_damping():
    assert RigParameters(damping_ratio=1e5).damping_ratio == 1e5  # ζ_crit reaches 1e5 with γ = 1


def test_sample_rate_must_resolve_the_natural_frequency():
    base = load_case(1)
    f0 = base.rig.natural_frequency
    ok = base.with_overrides(sample_rate=MIN_SAMPLES_PER_PERIOD * f0)
    assert ok.sample_rate == MIN_SAMPLES_PER_PERIOD * f0
    with pytest.raises(ParameterError, match=r"sample_rate=100 Hz is too low for natural_frequency=10 Hz"):
        base.with_overrides(sample_rate=100.0)
    with pytest.raises(ParameterError, match=r"natural_frequency <= 50 Hz"):
        base.with_overrides(natural_frequency=60.0)
