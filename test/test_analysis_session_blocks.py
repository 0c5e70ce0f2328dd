"""The analysis session on the block path (samples_input) and its typed outputs, without DDS."""

from __future__ import annotations

import math

import numpy as np

from lubrig_ros.app.analysis.session import AnalysisSession, AnalysisSettings
from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import simulate
from lubrig_ros.core.stability import linear_stability

SETTINGS = AnalysisSettings(window=256, n_scales=16, image_width=64, max_columns=8)


def test_blocks_are_taken_with_their_own_band_and_relative_velocity():
    session = AnalysisSession(load_case(1), SETTINGS)
    assert session.samples_input([1e-9, 2e-9], [0.0, 1e-9], [1e-7, 2e-7], [1e-7, 3e-7], 0.5) == 2
    assert session.x == [1e-9, 2e-9] and session.vrel == [1e-7, 3e-7]
    assert session.band == 2e-7 and session.newest_time == 0.5


def test_malformed_blocks_and_bad_samples_are_counted():
    session = AnalysisSession(load_case(1), SETTINGS)
    assert session.samples_input([1.0, 2.0], [0.0], [1e-7], [1e-7]) == 0  # unequal lengths
    assert session.samples_input([], [], [], []) == 0
    assert session.samples_input("x", [0.0], [1e-7], [1e-7]) == 0
    assert session.bad_messages == 3
    taken = session.samples_input([math.nan, 1e-9, 2e-9], [0.0, math.inf, 0.0], [1e-7] * 3, [1e-7] * 3)
    assert taken == 1 and session.x == [2e-9] and session.bad_messages == 5


def test_a_run_in_blocks_gives_the_frame_axes_and_every_flag():
    config = load_case(1).with_overrides(duration=1.0)
    ref = simulate(config)
    session = AnalysisSession(config, SETTINGS)
    outs = []
    for start in range(0, len(ref), 100):
        end = min(start + 100, len(ref))
        session.samples_input(
            ref.displacement[start:end],
            ref.velocity[start:end],
            ref.band_velocity[start:end],
            ref.relative_velocity[start:end],
            float(ref.time[end - 1]),
        )
        outs.append(session.tick())
    framed = [o for o in outs if o.power is not None]
    assert framed, "no wavelet output"
    last = framed[-1]
    rows, cols = last.power.shape
    assert last.frequencies.shape == (rows,) and np.all(np.diff(last.frequencies) < 0)  # row 0 highest
    assert last.power_end == ref.time[-1]
    assert math.isclose(last.power_start, ref.time[-1] - (cols - 1) * 1e-3, abs_tol=1e-12)
    flags = outs[-1].flags
    assert flags is not None and flags.band_velocity_m_s == ref.band_velocity[-1]
    verdict = linear_stability(abs(ref.band_velocity[-1]), config.rig)
    assert flags.zone == verdict.zone and flags.critical_damping_ratio == verdict.critical_damping_ratio
    assert flags.oscillation in ("growing", "decaying", "steady")  # from the window analysis
    assert flags.stick_share is not None
