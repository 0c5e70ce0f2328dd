"""Rebuild the Trajectory and RunConfig of a run from a bag recorded by the recorder node.

Two layouts are read (docs/recording.md "Bag layouts"):

- current (issue 12): ``<ns>/state_block`` (lubrig_interfaces/RigStateBlock, sim) or
  ``<ns>/state`` (lubrig_interfaces/RigState, realtime and rig-in-the-loop): every sample carries
  x, ẋ, μ, v_band, v_rel with its sample_index and segment, so gaps are found from the bag alone;
- legacy (before issue 12): sensor_msgs/JointState on ``<ns>/state`` plus the Float64 topics
  ``<ns>/friction_coefficient`` and ``<ns>/band_velocity``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..app.accounting import StreamAccount
from ..app.contract import DEFAULT_NAMESPACE, resolve, validate_namespace
from ..bag import BagError, TopicArrays, bag_info, read_arrays
from ..core.params import ParameterError
from ..core.presets import RunConfig, from_mapping
from ..core.trajectory import Trajectory

#: Contract names (relative to the rig namespace, /lubrig by default) of the topics read.
STATE, STATE_BLOCK, FRICTION, BAND = "state", "state_block", "friction_coefficient", "band_velocity"
JOINT_STATE = "sensor_msgs/msg/JointState"
RIG_STATE = "lubrig_interfaces/msg/RigState"
RIG_STATE_BLOCK = "lubrig_interfaces/msg/RigStateBlock"
#: (relative name, type) of the state topics, current layout first.
STATE_TOPICS = ((STATE_BLOCK, RIG_STATE_BLOCK), (STATE, RIG_STATE), (STATE, JOINT_STATE))


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
    """The rig namespace of a bag: that of its state topic(s) with messages.

    State topics: <namespace>/state_block (RigStateBlock), <namespace>/state (RigState, or the
    legacy JointState). A bag without one gives the default /lubrig (the caller then finds no
    states); one with the states of several namespaces (two rigs) is refused, naming them.
    """
    try:
        topics = bag_info(bag).topics
    except BagError as exc:
        raise ReportError(str(exc)) from None
    found: dict[str, list[str]] = {}
    for t in topics:
        for name, msgtype in STATE_TOPICS:
            suffix = "/" + name
            if t.count and t.msgtype == msgtype and t.name.endswith(suffix) and len(t.name) > len(suffix):
                found.setdefault(t.name[: -len(suffix)], []).append(t.name)
    if not found:
        return DEFAULT_NAMESPACE
    if len(found) > 1:
        names = ", ".join(n for ns in sorted(found) for n in found[ns])
        raise ReportError(f"bag {str(bag)!r} holds the states of several rigs ({names}); expected one")
    try:
        return validate_namespace(next(iter(found)))
    except ValueError as exc:
        raise ReportError(f"bag {str(bag)!r}: {exc}") from None


def _state_arrays(bag: str | Path, namespace: str) -> tuple[str, TopicArrays, dict[str, TopicArrays]]:
    """(state topic, its arrays, all arrays read) for the first state topic of STATE_TOPICS found."""
    try:
        names = {name: resolve(namespace, name) for name in (STATE, STATE_BLOCK, FRICTION, BAND)}
    except ValueError as exc:
        raise ReportError(str(exc)) from None
    try:
        arrays = read_arrays(bag, list(names.values()))
    except BagError as exc:
        raise ReportError(str(exc)) from None
    for name, msgtype in STATE_TOPICS:
        topic = names[name]
        if topic in arrays and arrays[topic].msgtype == msgtype and arrays[topic].t.size:
            return topic, arrays[topic], arrays
    return names[STATE], TopicArrays("", np.zeros(0), {}), arrays


def stream_accounts(bag: str | Path, namespace: str | None = None) -> dict[str, StreamAccount]:
    """Sample accounting (app/accounting.py) of the bag's indexed streams, from the bag alone.

    The state stream (state_block or RigState state) in log-time order; legacy bags (no sample
    index) give {}.
    """
    namespace = bag_namespace(bag) if namespace is None else namespace
    topic, state, _arrays = _state_arrays(bag, namespace)
    if state.msgtype not in (RIG_STATE, RIG_STATE_BLOCK):
        return {}
    account = StreamAccount(topic)
    segment = np.asarray(state["segment"], np.int64)
    index = np.asarray(state["sample_index"], np.int64)
    stamp_ns = np.rint(np.asarray(state["stamp"], float) * 1e9).astype(np.int64)
    for seg, k, t in zip(segment.tolist(), index.tolist(), stamp_ns.tolist(), strict=True):
        account.add(seg, k, 1, t)
    return {topic: account}


def recording_summary(bag: str | Path, namespace: str | None = None) -> dict[str, Any]:
    """Per-stream sample accounting of the bag for a report: {topic: StreamAccount.summary()}.

    Empty for a legacy bag (its samples carry no index). "problems" lists one line per gap,
    duplicate or out-of-order kind (StreamAccount.problems).
    """
    accounts = stream_accounts(bag, namespace)
    return {
        "streams": {name: a.summary() for name, a in accounts.items()},
        "problems": [line for a in accounts.values() for line in a.problems()],
    }


def trajectory_from_bag(
    bag: str | Path, namespace: str | None = None, segment: int | None = None
) -> tuple[RunConfig, Trajectory]:
    """(RunConfig, Trajectory) of a recorded sim or realtime run.

    The topics are read under `namespace` (default: taken from the bag, see bag_namespace).

    Current layout: the samples of <ns>/state_block (sim) or <ns>/state (RigState), ordered by
    (segment, sample_index), each sample once; time is the sample's header stamp (rig time),
    x, ẋ, μ, v_band and v_rel are the recorded fields. `segment`: the run segment to read
    (default: the first one in the bag; a plant reset starts a new segment at rig time 0). A gap
    leaves its samples out (recording_summary names it).

    Legacy layout (JointState on <ns>/state): time is the header stamp, x / ẋ its position /
    velocity; μ comes from <ns>/friction_coefficient when it has one message per state (else
    effort / N); the band velocity from <ns>/band_velocity when it is complete (belt_drive
    published samples 1…N, sample 0 is the profile's value at t = 0), else the profile
    evaluated at the state times.

    Stamps within 1e-3 samples of the k / sample_rate grid are put back on it exactly.
    """
    config = config_from_bag(bag)
    if namespace is None:
        namespace = bag_namespace(bag)
    state_topic, state, arrays = _state_arrays(bag, namespace)
    if state.t.size < 2:
        raise ReportError(f"bag {str(bag)!r} has fewer than 2 {state_topic} messages: nothing to report")
    if state.msgtype in (RIG_STATE, RIG_STATE_BLOCK):
        return config, _current_layout(config, state, segment, bag)
    return config, _legacy_layout(config, state, arrays, namespace)


def _on_grid(time: np.ndarray, rate: float) -> np.ndarray:
    index = np.rint(time * rate)
    if np.all(np.abs(time * rate - index) < 1e-3):
        return index / rate  # stamps are ns-rounded k / rate: restore the grid
    return time


def _current_layout(
    config: RunConfig, state: TopicArrays, segment: int | None, bag: str | Path
) -> Trajectory:
    segments = np.asarray(state["segment"], np.int64)
    wanted = int(segments.min()) if segment is None else segment
    chosen = np.flatnonzero(segments == wanted)
    if chosen.size < 2:
        present = sorted(set(segments.tolist()))
        raise ReportError(
            f"bag {str(bag)!r}: segment {wanted} has {chosen.size} samples; segments in the bag: {present}"
        )
    index = np.asarray(state["sample_index"], np.int64)[chosen]
    order = chosen[np.argsort(index, kind="stable")]
    keep = np.concatenate([[True], np.diff(np.asarray(state["sample_index"])[order]) != 0])
    order = order[keep]  # each sample once (a duplicate is the same sample again)
    field = lambda name: np.asarray(state[name], float)[order]  # noqa: E731
    time = _on_grid(field("stamp"), config.sample_rate)
    return Trajectory(time, field("displacement"), field("velocity"), field("friction_coefficient"),
                      field("band_velocity"), field("relative_velocity"))


def _legacy_layout(config: RunConfig, state: TopicArrays, arrays: dict[str, TopicArrays],
                   namespace: str) -> Trajectory:
    friction_topic, band_topic = resolve(namespace, FRICTION), resolve(namespace, BAND)
    order = np.argsort(state["stamp"], kind="stable")
    time = np.asarray(state["stamp"], float)[order]
    x = np.asarray(state["position"], float)[order]
    v = np.asarray(state["velocity"], float)[order]
    n = time.size
    time = _on_grid(time, config.sample_rate)
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
    return Trajectory(time, x, v, mu, band, rel)
