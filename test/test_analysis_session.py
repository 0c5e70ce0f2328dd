"""The analysis node's rules (app/analysis/session.py) without DDS: pairing, odd input, outputs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lubrig_ros.app.analysis.session import AnalysisSession, AnalysisSettings, render_power
from lubrig_ros.core.presets import default_config, load_case
from lubrig_ros.core.run import simulate
from lubrig_ros.core.stability import linear_stability

SETTINGS = AnalysisSettings(window=256, n_scales=16, image_width=64, max_columns=8)


def test_samples_are_taken_with_the_band_velocity_they_were_integrated_with():
    session = AnalysisSession(load_case(1), SETTINGS)
    taken = session.samples_input([1e-9, 2e-9], [2e-8, 3e-8], [1e-7, 2e-7], [9e-8, 1.7e-7], 0.002)
    assert taken == 2
    assert session.x == [1e-9, 2e-9] and session.vrel == [9e-8, 1.7e-7]
    assert session.band == 2e-7 and session.newest_time == 0.002  # the last sample's band and time


@pytest.mark.parametrize(
    "arrays, taken, bad",
    [
        (([], [], [], []), 0, 1),  # an empty block
        (([1.0], [1.0, 2.0], [0.0], [0.0]), 0, 1),  # arrays of unequal length
        (([math.nan], [0.0], [0.0], [0.0]), 0, 1),
        (([0.0], [math.inf], [0.0], [0.0]), 0, 1),
        (([0.0, 1.0], [0.0, 0.0], [0.0, 0.0], [-math.inf, 0.0]), 1, 1),  # the finite sample is kept
        ((["a"], [0.0], [0.0], [0.0]), 0, 1),  # not numbers
    ],
)
def test_malformed_samples_are_counted_and_skipped(arrays, taken, bad):
    session = AnalysisSession(default_config(), SETTINGS)
    assert session.samples_input(*arrays) == taken
    assert session.bad_messages == bad and len(session.x) == taken


def test_a_non_finite_band_velocity_keeps_the_last_good_one():
    session = AnalysisSession(default_config(), SETTINGS)
    session.samples_input([0.0], [0.0], [1e-7], [1e-7])
    assert session.samples_input([0.0], [0.0], [math.nan], [1e-7]) == 1  # x, ẋ, v_rel are finite
    assert session.band == 1e-7


def test_zone_and_critical_damping_at_the_current_band():
    config = load_case(1)
    session = AnalysisSession(config, SETTINGS)
    out = session.tick()
    assert out.linear_zone is None and out.critical_damping_ratio is None  # no band yet
    session.samples_input([0.0], [0.0], [0.0], [0.0])
    assert session.tick().linear_zone is None  # a band at rest has no sliding equilibrium
    session.samples_input([0.0], [0.0], [-1e-7], [-1e-7])
    out = session.tick()
    verdict = linear_stability(1e-7, config.rig)
    assert out.linear_zone == int(verdict.zone) == 2
    assert out.critical_damping_ratio == pytest.approx(verdict.critical_damping_ratio)
    assert out.power is None and out.statuses == [] and out.skipped is None


def test_a_full_window_gives_every_output():
    config = load_case(1).with_overrides(duration=1.0)
    ref = simulate(config)
    session = AnalysisSession(config, SETTINGS)
    outputs = []
    for start in range(0, len(ref), 100):  # ten updates' worth of blocks
        block = slice(start, start + 100)
        session.samples_input(
            ref.displacement[block],
            ref.velocity[block],
            ref.band_velocity[block],
            ref.relative_velocity[block],
        )
        outputs.append(session.tick())
    assert outputs[0].power is None  # the window (256 samples) is not full yet
    ready = [o for o in outputs if o.power is not None]
    assert ready, "no update after the window filled"
    for out in ready:
        assert out.power.shape[0] == SETTINGS.n_scales
        assert 1 <= out.power.shape[1] <= SETTINGS.max_columns
        assert np.isfinite(out.power).all()
    images = [o.image for o in ready if o.image is not None]
    assert images and all(i.dtype == np.uint8 for i in images)
    assert all(i.shape == (SETTINGS.n_scales, SETTINGS.image_width, 3) for i in images)
    freqs = [o.dominant_frequency for o in ready if o.dominant_frequency is not None]
    assert freqs and all(math.isfinite(f) and f > 0 for f in freqs)
    flagged = [o for o in ready if o.statuses]
    assert flagged and all(isinstance(o.oscillation_growing, bool) for o in flagged)
    names = [s.name for s in flagged[-1].statuses]
    assert names == [g for g in ("linear", "oscillation", "stick", "resonance")]
    assert flagged[-1].statuses[0].as_dict()["zone"] in ("2", "3")  # the cycle runs V1 (2) to V2 (3)
    assert all(o.skipped is None for o in outputs)


def test_run_config_replaces_the_rig_and_drops_buffered_samples():
    session = AnalysisSession(default_config(), SETTINGS)
    session.samples_input([1.0], [0.0], [0.0], [0.0])
    case = load_case(4)
    assert session.run_config_input(case.to_yaml()) is None
    assert session.config == case and session.x == [] and session.gamma == case.rig.velocity_factor
    for bad in ("{not: [yaml", "rig: {mass: -1}", "- a list", "unknown_section: 1"):
        reason = session.run_config_input(bad)
        assert reason, bad
        assert session.config == case  # kept


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_an_update_on_input_it_cannot_analyse_is_skipped_not_fatal():
    session = AnalysisSession(load_case(1), SETTINGS)
    k = np.arange(300)  # finite but absurd samples: the wavelet statistics overflow
    session.samples_input(1e300 * (k % 2), np.full(300, 1e300), np.full(300, 1e-7), np.full(300, -1e300))
    out = session.tick()
    assert out.skipped and "lag1" in out.skipped and session.bad_updates == 1
    assert out.linear_zone == 2  # what could be computed is still published
    assert out.power is None and out.dominant_frequency is None and out.image is None
    session.samples_input([0.0], [0.0], [1e-7], [1e-7])
    assert session.tick().linear_zone == 2  # and the session goes on


def test_render_power_orientation_and_range():
    power = np.outer(np.arange(1, 5), np.ones(10)).astype(float)  # the last row strongest
    rgb = render_power(power, width=5)
    assert rgb.shape == (4, 5, 3) and rgb.dtype == np.uint8
    assert tuple(rgb[0, 0]) == (253, 231, 37)  # rows are flipped: the last row is on top
    assert tuple(render_power(np.zeros((3, 4)), 4)[0, 0]) == (68, 1, 84)
