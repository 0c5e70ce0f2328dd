"""Per-stream sample accounting: counts, gaps, duplicates and out-of-order samples.

Every sample the plant publishes carries its index in its segment (RigState.sample_index; a block's
first_sample_index + i) and its segment (0 from the plant's start, +1 per reset, the index
restarting at 0). From these alone a consumer knows what it should have: samples 0, 1, 2, ... of
every segment, once each, in order. `StreamAccount` keeps that account for one stream (a topic)
from the messages as they are taken, without ROS:

- ``samples``: distinct samples taken;
- a **gap**: indices never taken (between two taken samples, before the first one of a segment, or
  after the last one when the publisher announced more with `announce`): count and the rig time
  of the first missing sample;
- a **duplicate**: a sample taken a second time;
- **out of order**: a sample that arrives after a later one of its segment (it fills a gap
  late; counted here, and no longer a gap) or of an older segment after a newer one;
- **skipped** (declared, not a problem): indices the publisher says it never published, just
  before a message (RigStateBlock.skipped: a realtime plant that fell behind real time and kept
  it); they are counted apart and listed, and are no gap.

`taken(segment)` is the number of samples of a segment taken in order without gap (0, 1, ... k-1):
what a flow-control participant reports (FlowProgress.samples). `StreamAccount.problems` gives
one line per kind of problem naming the stream and the first occurrence; `summary` a plain
mapping for the run folder's JSON.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from lubrig_ros.core.errors import InputError


@dataclass(frozen=True)
class Gap:
    """Missing samples [first_index, first_index + count) of one segment."""

    segment: int
    first_index: int
    count: int
    #: rig time of the first missing sample, ns: interpolated between the samples around the gap
    #: (or, with no earlier sample in its segment, the next one minus count sample periods; for
    #: an announced tail, the last sample plus one period)
    rig_time_ns: int


@dataclass(frozen=True)
class Event:
    """The first duplicate or out-of-order sample of a stream."""

    segment: int
    index: int
    rig_time_ns: int


@dataclass
class _Segment:
    next_index: int = 0  # one past the highest index taken
    last_time_ns: int | None = None  # rig time of sample next_index - 1
    taken: int = 0
    #: gaps as [start, stop, rig time of start (ns), rig time per sample (ns)], sorted
    missing: list[list[float]] = field(default_factory=list)
    announced: int = 0  # samples the publisher says it published in this segment
    period_ns: float | None = None  # of the blocks (or estimated from consecutive samples)
    declared: list[Gap] = field(default_factory=list)  # skipped by the publisher


def _time_of(span_first: int, stamp_ns: int, period_ns: float | None, index: int) -> int:
    return stamp_ns + round((index - span_first) * (period_ns or 0.0))


@dataclass
class StreamAccount:
    """The account of one stream; feed it with `add` per message in the order taken."""

    name: str
    samples: int = 0
    messages: int = 0
    duplicates: int = 0
    out_of_order: int = 0
    first_duplicate: Event | None = None
    first_out_of_order: Event | None = None
    segments: dict[int, _Segment] = field(default_factory=dict)
    newest_segment: int = -1
    skipped: int = 0

    def add(
        self,
        segment: int,
        first_index: int,
        count: int,
        stamp_ns: int,
        period_ns: float | None = None,
        skipped: int = 0,
    ) -> None:
        """Samples first_index .. first_index + count - 1 of `segment`, the first at rig time stamp_ns.

        period_ns: rig time between the samples of a block (None for one sample per message).
        skipped: the publisher declares indices first_index - skipped .. first_index - 1 skipped.
        ValueError for a negative segment, index or count.
        """
        if segment < 0 or first_index < 0 or count < 0 or skipped < 0:
            raise InputError(
                f"{self.name}: segment {segment}, first index {first_index}, count {count}: "
                "expected integers >= 0"
            )
        self.messages += 1
        if count == 0:
            return
        seg = self.segments.setdefault(segment, _Segment())
        older_segment = segment < self.newest_segment
        self.newest_segment = max(self.newest_segment, segment)
        stop = first_index + count
        late_start = min(stop, seg.next_index)
        # samples below next_index: each either fills a gap (out of order) or is a duplicate
        for index in range(first_index, late_start):
            t = _time_of(first_index, stamp_ns, period_ns, index)
            if self._fill(seg, index):
                seg.taken += 1
                self.samples += 1
                self._late(segment, index, t)
            else:
                self.duplicates += 1
                if self.first_duplicate is None:
                    self.first_duplicate = Event(segment, index, t)
        if stop > seg.next_index:
            start = max(first_index, seg.next_index)
            t_start = _time_of(first_index, stamp_ns, period_ns, start)
            if period_ns:
                seg.period_ns = period_ns
            if start > seg.next_index:  # a jump ahead: the indices in between are missing ...
                declared = max(seg.next_index, first_index - skipped) if start == first_index else start
                if declared > seg.next_index:
                    t_declared = _time_of(first_index, stamp_ns, period_ns, declared)
                    seg.missing.append(self._new_gap(seg, declared, t_declared))
                if start > declared:  # ... unless the publisher says it skipped them
                    t_declared = _time_of(first_index, stamp_ns, period_ns, declared)
                    seg.declared.append(Gap(segment, declared, start - declared, t_declared))
                    self.skipped += start - declared
            elif period_ns is None and seg.last_time_ns is not None:
                seg.period_ns = float(t_start - seg.last_time_ns)  # consecutive samples
            new = stop - start
            seg.taken += new
            self.samples += new
            if older_segment:
                self._late(segment, start, t_start)
            seg.next_index = stop
            seg.last_time_ns = _time_of(first_index, stamp_ns, period_ns, stop - 1)

    @staticmethod
    def _new_gap(seg: _Segment, start: int, t_start: int) -> list[float]:
        """The gap [seg.next_index, start) before a sample at rig time t_start."""
        count = start - seg.next_index
        if seg.last_time_ns is not None:  # linear between the neighbours
            step = (t_start - seg.last_time_ns) / (count + 1)
            return [seg.next_index, start, seg.last_time_ns + step, step]
        step = seg.period_ns or 0.0  # nothing before it in this segment
        return [seg.next_index, start, t_start - count * step, step]

    def announce(self, segment: int, samples: int) -> None:
        """The publisher says it has published `samples` samples of `segment` (e.g. its FlowProgress)."""
        seg = self.segments.setdefault(segment, _Segment())
        seg.announced = max(seg.announced, samples)

    def taken(self, segment: int) -> int:
        """Samples of `segment` taken in order without gap: k when 0 .. k-1 are all taken."""
        seg = self.segments.get(segment)
        if seg is None:
            return 0
        return int(seg.missing[0][0]) if seg.missing else seg.next_index

    def behind(self) -> int:
        """Samples announced (announce) but not taken yet, over all segments."""
        return sum(max(0, s.announced - s.next_index) for s in self.segments.values())

    # ---------------------------------------------------------------------- results
    @property
    def gaps(self) -> list[Gap]:
        """Every gap, by segment and index (an announced tail not taken included)."""
        out = []
        for number in sorted(self.segments):
            seg = self.segments[number]
            ranges = [(int(r[0]), int(r[1]), round(r[2])) for r in seg.missing]
            if seg.announced > seg.next_index:
                t = (seg.last_time_ns or 0) + round(seg.period_ns or 0)
                ranges.append((seg.next_index, seg.announced, t))
            for start, stop, t_ns in ranges:
                out.append(Gap(number, start, stop - start, t_ns))
        return out

    @property
    def declared_gaps(self) -> list[Gap]:
        """The gaps the publisher declared (skipped), by segment and index."""
        return [g for n in sorted(self.segments) for g in self.segments[n].declared]

    @property
    def missing(self) -> int:
        """Samples in gaps."""
        return sum(g.count for g in self.gaps)

    def problems(self) -> list[str]:
        """One line per kind of problem (gaps, duplicates, out of order), naming the first one."""
        lines = []
        gaps = self.gaps
        if gaps:
            g = gaps[0]
            lines.append(
                f"{self.name}: {sum(x.count for x in gaps)} samples missing in {len(gaps)} gap(s); "
                f"first gap: {g.count} samples from index {g.first_index} of segment {g.segment} "
                f"at rig time {g.rig_time_ns / 1e9:.6f} s"
            )
        if self.first_duplicate is not None:
            d = self.first_duplicate
            lines.append(
                f"{self.name}: {self.duplicates} duplicate samples; first: index {d.index} of "
                f"segment {d.segment} at rig time {d.rig_time_ns / 1e9:.6f} s"
            )
        if self.first_out_of_order is not None:
            o = self.first_out_of_order
            lines.append(
                f"{self.name}: {self.out_of_order} samples out of order; first: index {o.index} of "
                f"segment {o.segment} at rig time {o.rig_time_ns / 1e9:.6f} s"
            )
        return lines

    @property
    def complete(self) -> bool:
        """No gap, no duplicate, nothing out of order."""
        return not self.problems()

    def summary(self) -> dict[str, Any]:
        """Plain data for JSON/YAML: counts per segment, gaps, duplicates, out of order."""
        return {
            "messages": self.messages,
            "samples": self.samples,
            "missing": self.missing,
            "duplicates": self.duplicates,
            "out_of_order": self.out_of_order,
            "skipped": self.skipped,
            "declared_gaps": [
                {
                    "segment": g.segment,
                    "first_index": g.first_index,
                    "count": g.count,
                    "rig_time_s": g.rig_time_ns / 1e9,
                }
                for g in self.declared_gaps
            ],
            "segments": {
                str(n): {"samples": s.taken, "last_index": s.next_index - 1, "announced": s.announced}
                for n, s in sorted(self.segments.items())
            },
            "gaps": [
                {
                    "segment": g.segment,
                    "first_index": g.first_index,
                    "count": g.count,
                    "rig_time_s": g.rig_time_ns / 1e9,
                }
                for g in self.gaps
            ],
            "first_duplicate": _event(self.first_duplicate),
            "first_out_of_order": _event(self.first_out_of_order),
            "complete": self.complete,
        }

    # ---------------------------------------------------------------------- internals
    def _fill(self, seg: _Segment, index: int) -> bool:
        for i, (start, stop, t_start, step) in enumerate(seg.missing):
            if start <= index < stop:
                pieces = [
                    [start, index, t_start, step],
                    [index + 1, stop, t_start + (index + 1 - start) * step, step],
                ]
                seg.missing[i : i + 1] = [p for p in pieces if p[1] > p[0]]
                return True
        return False

    def _late(self, segment: int, index: int, t: int) -> None:
        self.out_of_order += 1
        if self.first_out_of_order is None:
            self.first_out_of_order = Event(segment, index, t)


def _event(event: Event | None) -> dict[str, Any] | None:
    if event is None:
        return None
    return {"segment": event.segment, "index": event.index, "rig_time_s": event.rig_time_ns / 1e9}
