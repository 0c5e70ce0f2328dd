"""μ between output samples (core/dense.py) against a brute-force re-integration at 1 MHz.

Case 8 at s = 0.08 sticks briefly once per 10 Hz cycle: sampled at 1 kHz its μ stays near 0.02,
while at every stick entry v_rel passes the friction peak (μ = 0.161) within a microsecond. The
zoomed re-integration must find at least every extreme a 1 MHz record of the same stretch shows,
and the peak itself; on a sliding run (paper case 1) nothing is re-integrated and the 1 MHz record
stays within the sampled range up to the curvature of one sample interval.
"""

from __future__ import annotations

import numpy as np
import pytest

from lubrig_ros.core.dense import mu_extremes
from lubrig_ros.core.friction import friction_peak
from lubrig_ros.core.integrator import RigIntegrator
from lubrig_ros.core.run import simulate
from lubrig_ros.core.trajectory import Trajectory
from lubrig_ros.study.runs import study_configs


def _brute(trajectory: Trajectory, config, first: int, last: int, factor: int) -> np.ndarray:  # type: ignore[no-untyped-def]
    """μ over samples first … last re-integrated at factor × the sample rate (band linear between samples)."""
    integrator = RigIntegrator(
        config.rig,
        float(trajectory.band_velocity[first]),
        sample_rate=config.sample_rate * factor,
        rtol=config.rtol,
        initial_displacement=float(trajectory.displacement[first]),
        initial_velocity=float(trajectory.velocity[first]),
    )
    fine_t = np.arange(1, (last - first) * factor + 1) / factor
    band = np.interp(fine_t, np.arange(last - first + 1), trajectory.band_velocity[first : last + 1])
    return integrator.advance(band).friction_coefficient


def _window(s: float | str, seconds: float) -> tuple[Trajectory, object, int, int]:
    config = study_configs(s, 12.0)[8 if s != "paper" else 1]
    trajectory = simulate(config)
    first = int(np.searchsorted(trajectory.time, 10.0))
    last = first + round(seconds * config.sample_rate)
    cut = Trajectory(**{name: getattr(trajectory, name)[: last + 1] for name, _ in Trajectory.COLUMNS})
    return cut, config, first, last


@pytest.mark.slow
def test_stick_entries_reach_the_friction_peak_between_samples() -> None:
    trajectory, config, first, last = _window(0.08, 0.5)
    rig = config.rig  # type: ignore[attr-defined]
    found = mu_extremes(trajectory, rig, config.rtol, first)  # type: ignore[attr-defined]
    peak = friction_peak(rig.friction).mu
    fine = _brute(trajectory, config, first, last, 1000)
    assert found.sampled_max < 0.05 < 0.1 < fine.max()  # 1 kHz misses what 1 MHz catches in part
    assert found.candidates >= 5
    assert found.mu_max >= fine.max() - 1e-9 and found.mu_min <= fine.min() + 1e-9
    assert abs(found.mu_max - peak) < 1e-6 * peak
    assert 0.0 < found.resolution <= 1e-9
    assert found.sampled_min >= found.mu_min and found.sampled_max <= found.mu_max


def test_sliding_run_needs_no_refinement() -> None:
    trajectory, config, first, last = _window("paper", 0.2)
    found = mu_extremes(trajectory, config.rig, config.rtol, first)  # type: ignore[attr-defined]
    assert found.candidates == 0 and found.resolution == 0.0
    fine = _brute(trajectory, config, first, last, 100)
    span = found.sampled_max - found.sampled_min
    assert fine.max() <= found.mu_max + 1e-6 * span
    assert fine.min() >= found.mu_min - 1e-6 * span
