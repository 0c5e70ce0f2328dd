"""Stability flags: linear verdict, envelope growth rate, stick detection, resonance."""

import json
import math

import numpy as np
import pytest

from lubrig_ros.core.flags import (
    StabilityFlags,
    detect_stick,
    evaluate_flags,
    resonance_check,
    signal_growth_rate,
)
from lubrig_ros.core.params import RigParameters
from lubrig_ros.core.stability import linear_stability

DT = 1e-3


def damped(rate, f=10.0, n=6000):
    t = np.arange(n) * DT
    return np.exp(rate * t) * np.sin(2 * np.pi * f * t)


@pytest.mark.parametrize("rate", [-0.8, 0.0, 0.5])
def test_growth_rate_recovered(rate):
    est, r2 = signal_growth_rate(damped(rate), DT, 10.0)
    assert abs(est - rate) < 0.03
    if rate != 0.0:
        assert r2 > 0.99


def test_oscillation_classification():
    rig = RigParameters(natural_frequency=10.0)
    assert evaluate_flags(rig, displacement=damped(0.5), dt=DT).oscillation == "growing"
    assert evaluate_flags(rig, displacement=damped(-0.5), dt=DT).oscillation == "decaying"
    assert evaluate_flags(rig, displacement=damped(0.0), dt=DT).oscillation == "steady"
    assert evaluate_flags(rig).oscillation == "unknown"


def test_stick_episodes_and_share():
    v = np.ones(1000)
    v[100:150] = 0.0
    v[400:500] = 1e-4
    v[990:] = 0.0
    s = detect_stick(v, DT, threshold_m_s=1e-3)
    assert s.episodes == 3
    assert math.isclose(s.share, 160 / 1000)
    assert math.isclose(s.longest_s, 100 * DT)
    assert detect_stick(np.ones(10), DT, 0.5).episodes == 0
    with pytest.raises(ValueError, match="threshold_m_s"):
        detect_stick(v, DT, 0.0)
    with pytest.raises(ValueError, match="non-finite"):
        detect_stick([1.0, np.nan], DT, 1.0)


def test_resonance_check():
    warn, k, text = resonance_check(3.4, 10.0)
    assert warn and k == 3 and "harmonic 3" in text
    warn, k, _ = resonance_check(4.4, 10.0)
    assert not warn and k is None
    with pytest.raises(ValueError, match="fundamental_hz"):
        resonance_check(0.0, 10.0)


def test_linear_verdict_matches_core_and_dict_is_json():
    rig = RigParameters()
    for v in (1e-12, 1e-8, 1e-4):
        flags = evaluate_flags(rig, band_velocity=v)
        ref = linear_stability(v, rig)
        assert flags.zone == ref.zone and flags.linear_stable == ref.stable
        assert flags.critical_damping_ratio == ref.critical_damping_ratio
    vrel = np.where(np.arange(2000) % 200 < 50, 0.0, 1e-6)
    flags = evaluate_flags(
        rig,
        band_velocity=1e-6,
        relative_velocity=vrel,
        dt=DT,
        fundamental_hz=5.0,
        displacement=damped(0.0),
    )
    d = flags.to_dict()
    assert set(d) == set(StabilityFlags.__dataclass_fields__)
    assert d["stick_episodes"] == 10 and abs(d["stick_share"] - 0.25) < 1e-12
    assert d["resonance"] is True and d["resonance_harmonic"] == 2
    json.dumps(d)


def test_missing_dt_is_an_error():
    with pytest.raises(ValueError, match="dt"):
        evaluate_flags(RigParameters(), displacement=damped(0.0))


def test_band_at_rest_has_no_linear_verdict_but_other_flags_work():
    from lubrig_ros.core.flags import evaluate_flags
    from lubrig_ros.core.params import RigParameters

    t = np.arange(2000) * 1e-3
    flags = evaluate_flags(
        RigParameters(),
        band_velocity=0.0,
        displacement=1e-9 * np.sin(2 * np.pi * 10 * t),
        dt=1e-3,
        relative_velocity=np.zeros(2000),
        fundamental_hz=4.76,
    )
    assert flags.band_velocity_m_s == 0.0
    assert flags.zone is None and flags.linear_stable is None and flags.critical_damping_ratio is None
    assert flags.stick_share == 1.0  # v_rel = 0 throughout: stuck (threshold: friction peak velocity)
    assert flags.oscillation == "steady" and flags.resonance is not None
