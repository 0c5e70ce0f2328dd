"""Rebuild the Trajectory and RunConfig of a run from a bag recorded by the recorder node."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from ..bag import BagError, bag_info, read_arrays
from ..core.integrator import Trajectory
from ..core.params import ParameterError
from ..core.presets import RunConfig, from_mapping

STATE = "/lubrig/state"
FRICTION = "/lubrig/friction_coefficient"
BAND = "/lubrig/band_velocity"


class ReportError(ValueError):
    """The bag cannot be turned into a report; the message is one user-facing line."""


def config_from_bag(bag: str | Path) -> RunConfig:
    """The RunConfig stored with the bag (full integrity check first)."""
    try:
        info = bag_info(bag)
    except BagError as exc:
        raise ReportError(str(exc)) from None
    text = info.run_config
    if not text:
        raise ReportError(f"bag {str(bag)!r} holds no run configuration (recorded without --config?)")
    try:
        return from_mapping(yaml.safe_load(text))
    except (yaml.YAMLError, ParameterError, TypeError, KeyError) as exc:
        raise ReportError(f"bag {str(bag)!r}: stored run configuration is invalid ({exc})") from None


def trajectory_from_bag(bag: str | Path) -> tuple[RunConfig, Trajectory]:
    """(RunConfig, Trajectory) of a recorded sim or realtime run.

    Time is the JointState header stamp (rig time), x / ẋ its position / velocity; μ comes from
    /lubrig/friction_coefficient when it has one message per state (else effort / N); the band
    velocity from /lubrig/band_velocity when it is complete (belt_drive publishes samples 1…N,
    sample 0 is the profile's value at t = 0), else the profile evaluated at the state times.
    Stamps within 1e-3 samples of the k / sample_rate grid are put back on it exactly.
    """
    config = config_from_bag(bag)
    try:
        arrays = read_arrays(bag, [STATE, FRICTION, BAND])
    except BagError as exc:
        raise ReportError(str(exc)) from None
    if STATE not in arrays or arrays[STATE].t.size < 2:
        raise ReportError(f"bag {str(bag)!r} has fewer than 2 {STATE} messages: nothing to report")
    state = arrays[STATE]
    order = np.argsort(state["stamp"], kind="stable")
    time = np.asarray(state["stamp"], float)[order]
    x = np.asarray(state["position"], float)[order]
    v = np.asarray(state["velocity"], float)[order]
    n = time.size
    index = np.rint(time * config.sample_rate)
    if np.all(np.abs(time * config.sample_rate - index) < 1e-3):
        time = index / config.sample_rate  # stamps are ns-rounded k / rate: restore the grid
    if FRICTION in arrays and arrays[FRICTION].t.size == n:
        mu = np.asarray(arrays[FRICTION]["data"], float)[order]
    else:
        mu = np.asarray(state["effort"], float)[order] / config.rig.friction.normal_force
    band_recorded = np.asarray(arrays[BAND]["data"], float) if BAND in arrays else np.zeros(0)
    if band_recorded.size == n - 1:
        band = np.concatenate([[float(config.band(0.0))], band_recorded])
    elif band_recorded.size == n:
        band = band_recorded
    else:
        band = np.asarray(config.band(time), float)
    rel = band - config.rig.velocity_factor * v
    return config, Trajectory(time, x, v, mu, band, rel)
