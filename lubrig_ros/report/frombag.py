"""Rebuild the Trajectory and RunConfig of a run from a bag recorded by the recorder node.

Two layouts are read (docs/recording.md "Bag layouts"):

- current: ``<ns>/state_block`` (lubrig_interfaces/RigStateBlock, sim) or
  ``<ns>/state`` (lubrig_interfaces/RigState, realtime and rig-in-the-loop): every sample carries
  x, ẋ, μ, v_band, v_rel with its sample_index and segment, so gaps are found from the bag alone;
- legacy (the per-sample layout of earlier versions): sensor_msgs/JointState on ``<ns>/state``
  plus the Float64 topics ``<ns>/friction_coefficient`` and ``<ns>/band_velocity``.

Time is rig time: a sim plant stamps its samples with rig time on its clock, as on /clock (0 at
the start; a reset starts a new segment, sample_index from 0, but the clock goes on, so a later
segment's times start where the one before ended, as the recorder's log times and gap times do);
a realtime plant with the wall clock (its due times, about 1.8e9 s), whose rig time is due time −
segment start = sample_index · sample_period, 0 at each segment's start (`rig_times`).

`read_run` reads a bag once (a lubrig_ros.bag.Bag: one walk of the file for its integrity check
and the messages, one decoding pass) and gives everything the report needs: configuration,
trajectory, the sample accounting and, for a realtime recording, its timing (app/recording/lateness.py);
`trajectory_from_bag` and `recording_summary` are its parts. `open_bag` opens a bag with the
topics the report reads, so a caller can refuse a damaged bag and report on it from one read.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from lubrig_ros.core.errors import LubrigError

from ..app.interface.contract import DEFAULT_NAMESPACE, resolve, validate_namespace
from ..app.recording.accounting import StreamAccount
from ..app.recording.lateness import RigTiming, rig_timing
from ..bag import Bag, BagError, BagSummary, TopicArrays
from ..core.params import ParameterError
from ..core.presets import RunConfig, from_mapping
from ..core.trajectory import Trajectory

#: Contract names (relative to the rig namespace, /lubrig by default) of the topics read.
STATE, STATE_BLOCK, FRICTION, BAND = "state", "state_block", "friction_coefficient", "band_velocity"
#: The diagnostics topic (absolute): the plant's timing status may state its max_lag.
DIAGNOSTICS = "/diagnostics"
#: Key of the plant's timing status (`<ns>/plant: timing`) that states its max_lag, s.
MAX_LAG_KEY = "lag_bound_s"
JOINT_STATE = "sensor_msgs/msg/JointState"
RIG_STATE = "lubrig_interfaces/msg/RigState"
RIG_STATE_BLOCK = "lubrig_interfaces/msg/RigStateBlock"
#: (relative name, type) of the state topics, current layout first.
STATE_TOPICS = ((STATE_BLOCK, RIG_STATE_BLOCK), (STATE, RIG_STATE), (STATE, JOINT_STATE))


class ReportError(LubrigError, ValueError):
    """The bag cannot be turned into a report; the message is one user-facing line."""


def _reads(topic: str) -> bool:
    """A topic the report reads, under any namespace (the namespace is known once the bag is read)."""
    return topic == DIAGNOSTICS or topic.rsplit("/", 1)[-1] in (STATE, STATE_BLOCK, FRICTION, BAND)


def open_bag(bag: str | Path | Bag) -> Bag:
    """The bag read once with the topics the report reads (a Bag is returned as it is)."""
    return bag if isinstance(bag, Bag) else Bag(bag, keep=_reads)


def _info(bag: Bag) -> BagSummary:
    """The bag's summary after its full integrity check; ReportError naming the problem."""
    try:
        return bag.summary()
    except BagError as exc:
        raise ReportError(str(exc)) from None


def _config(bag: str | Path, info: BagSummary) -> RunConfig:
    text = info.run_config
    if not text:
        raise ReportError(f"bag {str(bag)!r} holds no run configuration (recorded without --config?)")
    try:
        return from_mapping(yaml.safe_load(text))
    except (yaml.YAMLError, ParameterError, TypeError, KeyError) as exc:
        raise ReportError(f"bag {str(bag)!r}: stored run configuration is invalid ({exc})") from None


def _namespace(bag: str | Path, info: BagSummary) -> str:
    """The rig namespace of a bag: that of its state topic(s) with messages.

    State topics: <namespace>/state_block (RigStateBlock), <namespace>/state (RigState, or the
    legacy JointState). A bag without one gives the default /lubrig (the caller then finds no
    states); one with the states of several namespaces (two rigs) is refused, naming them.
    """
    found: dict[str, list[str]] = {}
    for t in info.topics:
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


def _state_arrays(bag: Bag, namespace: str) -> tuple[str, TopicArrays, dict[str, TopicArrays]]:
    """(state topic, its arrays, all arrays read) for the first state topic of STATE_TOPICS found.

    One decoding pass over the bag: the state topics, the legacy layout's Float64 topics and
    the diagnostics (for the plant's stated max_lag).
    """
    try:
        names = {name: resolve(namespace, name) for name in (STATE, STATE_BLOCK, FRICTION, BAND)}
    except ValueError as exc:
        raise ReportError(str(exc)) from None
    try:
        arrays = bag.arrays([*names.values(), DIAGNOSTICS])
    except BagError as exc:
        raise ReportError(str(exc)) from None
    for name, msgtype in STATE_TOPICS:
        topic = names[name]
        if topic in arrays and arrays[topic].msgtype == msgtype and arrays[topic].t.size:
            return topic, arrays[topic], arrays
    for name in (STATE_BLOCK, STATE):  # a state stream the report cannot read is never passed over
        held = arrays.get(names[name])
        if held is not None and held.t.size:
            readable = ", ".join(f"{n} {t}" for n, t in STATE_TOPICS)
            raise ReportError(
                f"bag {str(bag.path)!r}: {names[name]} holds {held.t.size} {held.msgtype} messages, "
                f"a type the report cannot read as rig states (readable: {readable})"
            )
    return names[STATE], TopicArrays("", np.zeros(0), {}), arrays


def stream_accounts(bag: str | Path | Bag, namespace: str | None = None) -> dict[str, StreamAccount]:
    """Sample accounting (app/recording/accounting.py) of the bag's indexed streams, from the bag alone.

    The state stream (state_block or RigState state) in log-time order; legacy bags (no sample
    index) give {}.
    """
    bag = open_bag(bag)
    info = _info(bag)
    namespace = _namespace(bag.path, info) if namespace is None else namespace
    try:
        rate: float | None = _config(bag.path, info).sample_rate
    except ReportError:  # no usable configuration: rig_times takes the period from the stamps
        rate = None
    topic, state, _arrays = _state_arrays(bag, namespace)
    return _accounts(topic, state, rate)


def _accounts(topic: str, state: TopicArrays, rate: float | None) -> dict[str, StreamAccount]:
    """The account of a state stream; {} for legacy.

    A gap's time is rig time (rig_times); samples a block declares skipped (RigStateBlock.skipped)
    are the account's declared gaps, not gaps, as in the recorder's own accounting.
    """
    if state.msgtype not in (RIG_STATE, RIG_STATE_BLOCK):
        return {}
    account = StreamAccount(topic)
    segment = np.asarray(state["segment"], np.int64)
    index = np.asarray(state["sample_index"], np.int64)
    time_ns = np.rint(rig_times(state, rate) * 1e9).astype(np.int64)
    skipped = np.asarray(state["skipped"], np.int64) if "skipped" in state.fields else np.zeros_like(index)
    period_ns = 1e9 / rate if rate else None  # places a declared gap's first skipped sample
    rows = zip(segment.tolist(), index.tolist(), time_ns.tolist(), skipped.tolist(), strict=True)
    for seg, k, t, skip in rows:
        account.add(seg, k, 1, t, period_ns, skipped=skip)
    return {topic: account}


def _recording(accounts: dict[str, StreamAccount]) -> dict[str, Any]:
    return {
        "streams": {name: a.summary() for name, a in accounts.items()},
        "problems": [line for a in accounts.values() for line in a.problems()],
    }


def recording_summary(bag: str | Path | Bag, namespace: str | None = None) -> dict[str, Any]:
    """Per-stream sample accounting of the bag for a report: {topic: StreamAccount.summary()}.

    Empty for a legacy bag (its samples carry no index). "problems" lists one line per gap,
    duplicate or out-of-order kind (StreamAccount.problems).
    """
    return _recording(stream_accounts(bag, namespace))


def trajectory_from_bag(
    bag: str | Path | Bag, namespace: str | None = None, segment: int | None = None
) -> tuple[RunConfig, Trajectory]:
    """(RunConfig, Trajectory) of a recorded sim or realtime run.

    The topics are read under `namespace` (default: taken from the bag, see bag_namespace).

    Current layout: the samples of <ns>/state_block or <ns>/state (RigState), ordered by
    (segment, sample_index), each sample once; time is rig time (rig_times: the header stamp
    in sim, due time − segment start in realtime), x, ẋ, μ, v_band and v_rel are the recorded
    fields. `segment`: the run segment to read
    (default: the first one in the bag; a plant reset starts a new segment, sample_index from 0,
    its sim stamps going on from the old segment's end). A gap
    leaves its samples out (recording_summary names it).

    Legacy layout (JointState on <ns>/state): time is the header stamp, x / ẋ its position /
    velocity; μ comes from <ns>/friction_coefficient when it has one message per state (else
    effort / N); the band velocity from <ns>/band_velocity when it is complete (belt_drive
    published samples 1…N, sample 0 is the profile's value at t = 0), else the profile
    evaluated at the state times.

    Stamps within 1e-3 samples of the k / sample_rate grid are put back on it exactly.
    """
    run = _read(bag, namespace)
    return run.config, _trajectory(run, segment)[0]


@dataclass(frozen=True)
class RecordedRun:
    """What the report takes from a bag (read_run)."""

    config: RunConfig
    trajectory: Trajectory
    #: {"streams": {topic: StreamAccount.summary()}, "problems": [...]} ({} streams: legacy bag)
    recording: dict[str, Any]
    #: the realtime timing of the trajectory's segment; None without recorded lateness (sim,
    #: per-sample RigState, bags recorded before RigStateBlock carried it)
    timing: RigTiming | None


@dataclass(frozen=True)
class _Bag:
    bag: str | Path
    config: RunConfig
    namespace: str
    state_topic: str
    state: TopicArrays
    arrays: dict[str, TopicArrays]


def _read(source: str | Path | Bag, namespace: str | None) -> _Bag:
    """One read of the bag (open_bag), one decoding pass: configuration, namespace, state arrays."""
    bag = open_bag(source)
    info = _info(bag)
    config = _config(bag.path, info)
    namespace = _namespace(bag.path, info) if namespace is None else namespace
    state_topic, state, arrays = _state_arrays(bag, namespace)
    if state.t.size < 2:
        raise ReportError(f"bag {str(bag.path)!r} has fewer than 2 {state_topic} messages: nothing to report")
    return _Bag(bag.path, config, namespace, state_topic, state, arrays)


def read_run(bag: str | Path | Bag, namespace: str | None = None, segment: int | None = None) -> RecordedRun:
    """Everything the report takes from a bag, from one read of it (one check, one pass).

    The trajectory as trajectory_from_bag gives it, the recording as recording_summary does, and
    the timing of the trajectory's segment when its samples carry a realtime lateness (the
    plant's max_lag from its timing status in the bag, else app.recording.lateness.DEFAULT_MAX_LAG).
    """
    run = _read(bag, namespace)
    trajectory, order = _trajectory(run, segment)
    accounts = _accounts(run.state_topic, run.state, run.config.sample_rate)
    timing = None
    if order is not None and "lateness" in run.state.fields:
        state = run.state
        timing = rig_timing(
            int(np.asarray(state["segment"])[order[0]]),
            1.0 / run.config.sample_rate,
            np.asarray(state["sample_index"])[order],
            np.asarray(state["lateness"])[order],
            np.asarray(state["skipped"])[order],
            stated_max_lag(run.arrays, run.namespace),
        )
    return RecordedRun(run.config, trajectory, _recording(accounts), timing)


def _trajectory(run: _Bag, segment: int | None) -> tuple[Trajectory, np.ndarray | None]:
    """The trajectory and, in the current layout, the state samples it holds (indices, in order)."""
    if run.state.msgtype in (RIG_STATE, RIG_STATE_BLOCK):
        return _current_layout(run.config, run.state, segment, run.bag)
    return _legacy_layout(run.config, run.state, run.arrays, run.namespace), None


#: s: a segment whose first sample is stamped beyond this (1973) carries wall-clock (ROS) time.
WALL_CLOCK_S = 1e8


def rig_times(state: TopicArrays, rate: float | None) -> np.ndarray:
    """Rig time (s) of every sample of a current-layout state stream, 0 at each segment's start.

    A segment whose stamps are rig time (sim: the plant's own clock, sample k at k / rate; any
    stream stamped from its own time origin) keeps them, so gap times agree with the recorder's
    accounting. A segment stamped with the wall clock (realtime: sample k at its due time, the
    segment's start + k · sample_period, about 1.8e9 s, beyond WALL_CLOCK_S; per-sample RigState
    at its publication) gets due time − segment start, i.e. sample_index / rate: the rig time the
    plant integrated the sample at, whatever its lateness. rate None (a bag without a usable
    configuration): the segment's median stamp step per index step.
    """
    stamp = np.asarray(state["stamp"], float)
    index = np.asarray(state["sample_index"], np.int64)
    segments = np.asarray(state["segment"], np.int64)
    time = stamp.copy()
    for seg in np.unique(segments).tolist():
        rows = np.flatnonzero(segments == seg)
        rows = rows[np.argsort(index[rows], kind="stable")]
        period = 1.0 / rate if rate else _median_period(stamp[rows], index[rows])
        if period is None:
            continue
        if stamp[rows[0]] - index[rows[0]] * period > WALL_CLOCK_S:  # ROS time, not rig time
            time[rows] = index[rows] * period
    return time


def _median_period(stamp: np.ndarray, index: np.ndarray) -> float | None:
    step = np.diff(index)
    ok = step > 0
    if not ok.any():
        return None
    period = float(np.median(np.diff(stamp)[ok] / step[ok]))
    return period if period > 0 else None


def stated_max_lag(arrays: dict[str, TopicArrays], namespace: str) -> float | None:
    """The max_lag (s) the plant's last timing status in the bag states (MAX_LAG_KEY), if any."""
    diag = arrays.get(DIAGNOSTICS)
    if diag is None or "message" not in diag.fields:
        return None
    name = f"{namespace.rstrip('/')}/plant: timing"
    stated = None
    for msg in diag["message"]:
        for status in getattr(msg, "status", ()):
            if status.name != name:
                continue
            for pair in status.values:
                if pair.key == MAX_LAG_KEY:
                    try:
                        value = float(pair.value)
                    except ValueError:
                        continue
                    if np.isfinite(value) and value > 0:
                        stated = value
    return stated


def _on_grid(time: np.ndarray, rate: float) -> np.ndarray:
    index = np.rint(time * rate)
    if np.all(np.abs(time * rate - index) < 1e-3):
        return index / rate  # stamps are ns-rounded k / rate: restore the grid
    return time


def _current_layout(
    config: RunConfig, state: TopicArrays, segment: int | None, bag: str | Path
) -> tuple[Trajectory, np.ndarray]:
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
    time = _on_grid(rig_times(state, config.sample_rate)[order], config.sample_rate)
    trajectory = Trajectory(
        time,
        field("displacement"),
        field("velocity"),
        field("friction_coefficient"),
        field("band_velocity"),
        field("relative_velocity"),
    )
    return trajectory, order


def _legacy_layout(
    config: RunConfig, state: TopicArrays, arrays: dict[str, TopicArrays], namespace: str
) -> Trajectory:
    friction_topic, band_topic = resolve(namespace, FRICTION), resolve(namespace, BAND)
    order = np.argsort(state["stamp"], kind="stable")
    time = np.asarray(state["stamp"], float)[order]
    x = np.asarray(state["position"], float)[order]
    v = np.asarray(state["velocity"], float)[order]
    n = time.size
    time = _on_grid(time, config.sample_rate)
    friction = _legacy_scalar(arrays, friction_topic, (n,), n)
    if friction is not None:
        mu = friction[order]
    else:
        mu = np.asarray(state["effort"], float)[order] / config.rig.friction.normal_force
    band_recorded = _legacy_scalar(arrays, band_topic, (n - 1, n), n)
    if band_recorded is None:
        band = np.asarray(config.band(time), float)
    elif band_recorded.size == n - 1:
        band = np.concatenate([[float(config.band(0.0))], band_recorded])
    else:
        band = band_recorded
    rel = config.rig.relative_velocity(band, v)
    return Trajectory(time, x, v, mu, band, rel)


def _legacy_scalar(
    arrays: dict[str, TopicArrays], topic: str, sizes: tuple[int, ...], states: int
) -> np.ndarray | None:
    """The Float64 values of a legacy topic, None if the bag holds none (the fallback is then used).

    A topic that holds messages but cannot be paired with the states (another count, no `data`)
    is a ReportError naming it: a recorded stream is never replaced silently.
    """
    held = arrays.get(topic)
    if held is None or not held.t.size:
        return None
    if "data" not in held.fields or held.t.size not in sizes:
        expected = " or ".join(str(k) for k in sizes)
        raise ReportError(
            f"{topic} holds {held.t.size} {held.msgtype} messages for {states} states (expected {expected} "
            "Float64 values): it cannot be paired with the states"
        )
    return np.asarray(held["data"], float)
