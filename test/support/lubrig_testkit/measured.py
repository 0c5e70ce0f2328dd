"""Synthetic 'measured' records for fit tests and benchmarks, from the independent reference rig.

The record is what a real rig would give: the reference rig (reference_rig.py: the model
document's equations integrated by scipy's LSODA, nothing of lubrig_ros's integrator) with chosen
true parameters, driven by a configuration's band over its duration at 1 kHz, plus Gaussian noise
of `noise` (default 1 %) of each stream's range.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .reference_rig import ReferenceRig, reference_state


def noisy_record(
    config: Any, truth: dict[str, float], seed: int = 1, noise: float = 0.01
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(time s, band m/s, displacement m, μ) of the reference rig with `truth`, noise added.

    `config` (a lubrig_ros RunConfig) gives only the band, the duration, the convention (γ = 1
    physical, 1/ω0 of the true f0 otherwise) and the initial perturbation x(0) = (1 + p) x0.
    """
    rig = ReferenceRig(**truth)
    time = np.arange(round(config.duration * 1000) + 1) / 1000.0
    band = np.asarray(config.band(time), float)
    gamma = 1.0 if config.rig.convention == "physical" else 1.0 / rig.omega0
    x0 = (1.0 + config.initial_perturbation) * rig.mu(band[0]) * rig.normal_force / rig.stiffness
    x, v = reference_state(time, band, x0, gamma, rig)
    mu = np.array([rig.mu(b - gamma * w) for b, w in zip(band, v, strict=True)])
    rng = np.random.default_rng(seed)
    noisy_x = x + rng.normal(0.0, noise * np.ptp(x), x.size)
    noisy_mu = mu + rng.normal(0.0, noise * np.ptp(mu), mu.size)
    return time, band, noisy_x, noisy_mu
