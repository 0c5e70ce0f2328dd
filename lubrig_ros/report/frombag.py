"""Rebuild the Trajectory and RunConfig of a run from a bag recorded by the recorder node."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from ..app.contract import DEFAULT_NAMESPACE, resolve, validate_namespace
from ..bag import BagError, bag_info, read_arrays
from ..core.integrator import Trajectory
from ..core.params import ParameterError
from ..core.presets import RunConfig, from_mapping

#: Contract names (relative to the rig namespace, /lubrig by default) of the topics read.
STATE, FRICTION, BAND = "state", "friction_coefficient", "band_velocity"
JOINT_STATE = "sensor_msgs/msg/JointState"


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


def bag_namespace(bag: str | Path) -> str:
    """The rig namespace of a bag: that of its one JointState topic named <namespace>/state.

    A bag without such a topic gives the default /lubrig (the caller then finds no states); one
    with several (two rigs) is refused, naming them.
    """
    try:
        topics = bag_info(bag).topics
    except BagError as exc:
        raise ReportError(str(exc)) from None
    found = sorted(
        t.name[: -len("/state")]
        for t in topics
        if t.msgtype == JOINT_STATE and t.name.endswith("/state") and len(t.name) > len("/state")
    )
    if not found:
        return DEFAULT_NAMESPACE
    if len(found) > 1:
        raise ReportError(
            f"bag {str(bag)!r} holds the states of several rigs ({', '.join(n + '/state' for n in found)}); "
            "expected one"
        )
    try:
        return validate_namespace(found[0])
    except ValueError as exc:
        raise ReportError(f"bag {str(bag)!r}: {exc}") from None


def trajectory_from_bag(bag: str | Path, namespace: str | None = None) -> tuple[RunConfig, Trajectory]:
    """(RunConfig, Trajectory) of a recorded sim or realtime run.

    The topics are read under `namespace` (default: taken from the bag, see bag_namespace).

    Time is the JointState header stamp (rig time), x / ẋ its position / velocity; μ comes from
    <ns>/friction_coefficient when it has one message per state (else effort / N); the band
    velocity from <ns>/band_velocity when it is complete (belt_drive publishes samples 1…N,
    sample 0 is the profile's value at t = 0), else the profile evaluated at the state times.
    Stamps within 1e-3 samples of the k / sample_rate grid are put back on it exactly.
    """
    config = config_from_bag(bag)
    if namespace is None:
        namespace = bag_namespace(bag)
    try:
        state_topic, friction_topic, band_topic = (resolve(namespace, n) for n in (STATE, FRICTION, BAND))
    except ValueError as exc:
        raise ReportError(str(exc)) from None
    try:
        arrays = read_arrays(bag, [state_topic, friction_topic, band_topic])
    except BagError as exc:
        raise ReportError(str(exc)) from None
    if state_topic not in arrays or arrays[state_topic].t.size < 2:
        raise ReportError(f"bag {str(bag)!r} has fewer than 2 {state_topic} messages: nothing to report")
    state = arrays[state_topic]
    order = np.argsort(state["stamp"], kind="stable")
    time = np.asarray(state["stamp"], float)[order]
    x = np.asarray(state["position"], float)[order]
    v = np.asarray(state["velocity"], float)[order]
    n = time.size
    index = np.rint(time * config.sample_rate)
    if np.all(np.abs(time * config.sample_rate - index) < 1e-3):
        time = index / config.sample_rate  # stamps are ns-rounded k / rate: restore the grid
    if friction_topic in arrays and arrays[friction_topic].t.size == n:
        mu = np.asarray(arrays[friction_topic]["data"], float)[order]
    else:
        mu = np.asarray(state["effort"], float)[order] / config.rig.friction.normal_force
    recorded = arrays.get(band_topic)
    band_recorded = np.asarray(recorded["data"], float) if recorded is not None else np.zeros(0)
    if band_recorded.size == n - 1:
        band = np.concatenate([[float(config.band(0.0))], band_recorded])
    elif band_recorded.size == n:
        band = band_recorded
    else:
        band = np.asarray(config.band(time), float)
    rel = config.rig.relative_velocity(band, v)
    return config, Trajectory(time, x, v, mu, band, rel)
