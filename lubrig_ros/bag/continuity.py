"""Per-stream sample continuity of a bag, from the payloads the verifier kept (no full decoding).

RigState (sample_index, segment) and RigStateBlock / BandVelocityBlock (first_sample_index + n,
segment): gaps, duplicates, stamps or segments going back, the plant's declared skips
(RigStateBlock.skipped). Float64 / JointState / Clock streams of one message per sample (the
contract's output rate): log-time steps against the sample period (the run configuration's
sample_rate, else the median step) when the log times are on that grid (rig time).
"""

from __future__ import annotations

import itertools
import struct

import yaml

from lubrig_ros.app.interface import contract
from lubrig_ros.app.interface.cdr import block_skipped
from lubrig_ros.bag.findings import CONTINUITY, StreamReport, Verification
from lubrig_ros.bag.frames import Channel, RecordError, Schema
from lubrig_ros.bag.layout import RUN_CONFIG_KEY

INDEXED_TYPES = {
    "lubrig_interfaces/msg/RigState": "sample",
    "lubrig_interfaces/msg/RigStateBlock": "block",
    "lubrig_interfaces/msg/BandVelocityBlock": "block",
}
SPACED_TYPES = {"std_msgs/msg/Float64", "sensor_msgs/msg/JointState", "rosgraph_msgs/msg/Clock"}
Items = list[tuple[int, int, bytes]]  # (byte offset, log time ns, payload prefix) per message


def sample_period_s(meta: dict[str, object] | None) -> float | None:
    """1 / simulation.sample_rate of the run configuration in metadata.yaml's custom_data, if any."""
    if not meta:
        return None
    try:
        text = dict(meta.get("custom_data") or {}).get(RUN_CONFIG_KEY)  # type: ignore[call-overload]
        rate = float(yaml.safe_load(text)["simulation"]["sample_rate"]) if text else 0.0
    except (yaml.YAMLError, KeyError, TypeError, ValueError):
        return None
    return 1.0 / rate if rate > 0 else None


def _cdr_header(data: bytes) -> tuple[str, int, int]:
    """(endianness, stamp ns, offset after the Header) of a payload starting with a std_msgs/Header."""
    if len(data) < 16 or data[1] not in (0, 1):
        raise RecordError("payload too short or unknown CDR encapsulation")
    e = "<" if data[1] == 1 else ">"
    sec, nsec, n = struct.unpack_from(e + "iII", data, 4)
    return e, sec * 1_000_000_000 + nsec, 16 + n


def _align(pos: int, a: int) -> int:
    return 4 + -(-(pos - 4) // a) * a


def declares_skip(schema: Schema | None) -> bool:
    """The schema is a RigStateBlock with the `skipped` field."""
    return (
        schema is not None
        and schema.name == "lubrig_interfaces/msg/RigStateBlock"
        and b"skipped" in schema.data
    )


def skipped_of(data: bytes) -> int:
    """RigStateBlock.skipped of a whole payload (0 when unreadable)."""
    try:
        _e, _stamp, pos = _cdr_header(data)
    except (RecordError, struct.error):
        return 0
    return block_skipped(data, _align(pos, 8) + 20)


def _indexed(kind: str, data: bytes) -> tuple[int, int, int, int, float]:
    """(segment, first index, n, stamp ns, period s) of a RigState or block payload."""
    e, stamp, pos = _cdr_header(data)
    pos = _align(pos, 8)
    if kind == "sample":
        index, segment = struct.unpack_from(e + "QI", data, pos)
        return segment, index, 1, stamp, 0.0
    period, first, segment = struct.unpack_from(e + "dQI", data, pos)
    (n,) = struct.unpack_from(e + "I", data, _align(pos + 20, 4))
    return segment, first, n, stamp, period


def _per_sample(topic: str) -> bool:
    """A contract topic with one message per sample (band, scalar outputs, a legacy state).

    /clock (one per block plus a heartbeat), the analysis outputs and diagnostics are not sample
    streams: their log-time spacing says nothing about loss.
    """
    try:
        spec = contract.topic(topic.rsplit("/", 1)[-1])
    except KeyError:
        return False
    return spec.rate == contract.OUTPUT_RATE


def check_continuity(
    v: Verification,
    channels: dict[int, Channel],
    schemas: dict[int, Schema],
    samples: dict[int, Items],
    skipped: dict[tuple[int, int], int],
    meta: dict[str, object] | None,
) -> None:
    """A StreamReport per channel in v.streams; the first gap, duplicate or step back of each listed."""
    period = sample_period_s(meta)
    for cid, ch in sorted(channels.items()):
        schema = schemas.get(ch.schema_id)
        msgtype = schema.name if schema is not None else "?"
        items = samples.get(cid, [])
        rep = StreamReport(ch.topic, msgtype, len(items))
        v.streams[ch.topic] = rep
        if msgtype in INDEXED_TYPES:
            skips = {i: n for (c, i), n in skipped.items() if c == cid}
            _by_index(v, rep, INDEXED_TYPES[msgtype], items, skips)
        elif msgtype in SPACED_TYPES and _per_sample(ch.topic):
            _by_spacing(v, rep, items, period)
        else:
            rep.method = "not a sample stream"
            rep.samples = len(items)


def _note(v: Verification, rep: StreamReport, what: str, off: int, t_s: float, text: str) -> None:
    if what == "gap":
        rep.gaps += 1
        if rep.first_gap_s is None:
            rep.first_gap_s = t_s
    elif what == "duplicate":
        rep.duplicates += 1
        if rep.first_duplicate_s is None:
            rep.first_duplicate_s = t_s
    else:
        rep.backwards += 1
        if rep.first_backwards_s is None:
            rep.first_backwards_s = t_s
    if (rep.gaps + rep.duplicates + rep.backwards) == 1:  # the first problem of each stream is listed
        v.add(text, off, rep.topic, CONTINUITY)


def _by_index(
    v: Verification, rep: StreamReport, kind: str, items: Items, skips: dict[int, int] | None = None
) -> None:
    """Continuity from the indices; `skips`: position in items -> samples the plant declared skipped."""
    rep.method = "by " + ("sample_index" if kind == "sample" else "first_sample_index")
    segment: int | None = None
    expected, last_stamp = 0, -1
    skips = skips or {}
    for position, (off, _t, data) in enumerate(items):
        skipped = skips.get(position, 0)
        try:
            seg, first, n, stamp, _period = _indexed(kind, data)
        except (RecordError, struct.error):
            v.add("message does not decode (sample index unreadable)", off, rep.topic, CONTINUITY)
            continue
        rep.samples += n
        t_s = stamp / 1e9
        if segment is None or seg != segment:
            if segment is not None and seg < segment:
                _note(
                    v, rep, "backwards", off, t_s, f"segment goes back from {segment} to {seg} at {t_s:.6f} s"
                )
            elif segment is not None and first != 0:
                rep.missing += first
                _note(
                    v,
                    rep,
                    "gap",
                    off,
                    t_s,
                    f"segment {seg} starts at sample {first}: {first} samples "
                    f"missing before rig time {t_s:.6f} s",
                )
            segment, expected, last_stamp = seg, first, -1
            rep.segments += 1
        declared = min(skipped, max(0, first - expected))
        if declared:  # skipped by the plant (it fell behind real time): shown, not a problem
            rep.skipped += declared
            rep.declared_gaps += 1
            if rep.first_skip_s is None:
                rep.first_skip_s = t_s
        if first - declared > expected:
            missing = first - declared - expected
            rep.missing += missing
            _note(
                v,
                rep,
                "gap",
                off,
                t_s,
                f"gap: {missing} samples missing before rig time "
                f"{t_s:.6f} s (sample {first}, expected {expected})",
            )
        elif first < expected:
            last = min(expected, first + n) - 1
            _note(
                v,
                rep,
                "duplicate",
                off,
                t_s,
                f"duplicate: samples {first}..{last} recorded twice (rig time {t_s:.6f} s)",
            )
        if stamp < last_stamp:
            _note(v, rep, "backwards", off, t_s, f"stamp goes back to {t_s:.6f} s")
        expected, last_stamp = max(expected, first + n), max(last_stamp, stamp)


def _by_spacing(v: Verification, rep: StreamReport, items: Items, period: float | None) -> None:
    rep.samples = len(items)
    if len(items) < 3:
        rep.method = "too few messages to check"
        return
    times = [t for _o, t, _d in items]
    if period is None:
        steps = sorted(b - a for a, b in itertools.pairwise(times) if b > a)
        if not steps:
            rep.method = "unchecked: log times do not advance"
            return
        period_ns = float(steps[len(steps) // 2])
    else:
        period_ns = period * 1e9
    phase = times[0] % period_ns
    on_grid = sum(1 for t in times if abs((t - phase) / period_ns - round((t - phase) / period_ns)) < 1e-3)
    if on_grid < 0.99 * len(times):
        rep.method = "unchecked: log times are receive times, not on the sample grid"
        return
    rep.method = "by log-time steps"
    prev = round((times[0] - phase) / period_ns)
    for off, t, _d in items[1:]:
        k = round((t - phase) / period_ns)
        step = k - prev
        if step > 1:
            rep.missing += step - 1
            _note(
                v,
                rep,
                "gap",
                off,
                t / 1e9,
                f"gap: {step - 1} samples missing before log time {t / 1e9:.6f} s",
            )
        elif step == 0:
            _note(v, rep, "duplicate", off, t / 1e9, f"duplicate log time {t / 1e9:.6f} s")
        elif step < 0:
            _note(v, rep, "backwards", off, t / 1e9, f"log time goes back to {t / 1e9:.6f} s")
        prev = max(prev, k)
