"""Lossless replay without ROS: the sim flow control (app/flow.py) with the replay as its source.

A lossless replay publishes the bag's state blocks (RigStateBlock, the topic the sim flow control
counts) no faster than the named subscribers take them: each reports on <ns>/flow_progress, as
every required consumer of a sim run does (the recorder, a test probe), the samples of a
segment it has taken. The replay takes the plant's place in a `FlowGate`: it "reports" what it
has sent itself, and a block whose last sample lies beyond the slowest subscriber's covered
samples + ``window`` waits. At most ``window`` samples (plus one block) are in flight towards the
slowest subscriber, so none is lost to a full history (BLOCK_QOS), however slow it is and
whatever the replay's rate.

A replay need not play a segment from its first sample (--start, a seek, a loop): every block
that does not continue what was sent (another segment, or another first sample index) starts a
new *stretch*. The replay first waits until every subscriber has taken the whole previous
stretch, then opens a new gate in which every subscriber counts as having taken the samples
before the stretch's first one. Within a stretch a report counts only if it lies inside it
(above its first sample, at most what was sent), and a repeat of a subscriber's last count of
the previous stretch (a heartbeat) only once it has reported another value in this one: older
reports still in flight say nothing about it.

A subscriber must report its reach (segment, the end of the last block it took), as
`FlowProgress` documents for the samples taken in order. The recorder counts samples taken in
order without a gap from the segment's first sample, so a stretch that starts inside a segment
(or plays a segment a second time) never moves its count: as a lossless subscriber it follows
only a replay that plays each segment from its start, once.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from lubrig_ros.app.flow import FlowGate, flow_window_problem
from lubrig_ros.app.interface.cdr import SampleSpan
from lubrig_ros.core.errors import InputError


@dataclass
class LosslessFlow:
    """Which state blocks may be sent now (see the module docstring).

    `me`: the replay's own name (its place in the gate); `subscribers`: fully qualified node names
    whose flow_progress paces the replay; `window`: samples beyond the slowest one's.
    """

    me: str
    subscribers: tuple[str, ...]
    window: int
    heard: set[str] = field(default_factory=set)
    gate: FlowGate | None = None
    segment: int = 0
    base: int = 0  # first sample index of the stretch
    reach: int = 0  # one past the last sample sent in the stretch
    #: per subscriber, the previous stretch's last count (same segment): a repeat of it (a
    #: heartbeat) says nothing about this stretch until the subscriber has reported another value
    stale: dict[str, int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.subscribers:
            raise InputError("lossless replay needs at least one subscriber node name")
        FlowGate(self.window, self.me, self.subscribers)  # checks the window

    def check_blocks(self, block_length: int) -> None:
        """InputError if blocks of this many samples could overflow the QoS history."""
        problem = flow_window_problem(self.window, max(1, block_length))
        if problem:
            raise InputError(f"--flow-window: {problem}")

    def report(self, participant: str, segment: int, samples: int) -> bool:
        """One flow_progress message; True when it may let a held block go."""
        if participant not in self.subscribers:
            return False
        new = participant not in self.heard
        self.heard.add(participant)
        if self.gate is None or segment != self.segment or not self.base < samples <= self.reach:
            return new
        if self.stale.get(participant) == samples:
            return new
        self.stale.pop(participant, None)
        return self.gate.report(participant, segment, samples) or new

    def unheard(self) -> str | None:
        """Why nothing may be sent yet: a subscriber has not reported once (None: all have).

        Its first report says that its readers have matched (the recorder's does: its readers of
        every stream with a publisher on the graph); a message of any topic sent before it could
        arrive at a reader not yet matched, which drops it.
        """
        missing = [name for name in self.subscribers if name not in self.heard]
        return f"waiting for the first flow_progress of {', '.join(missing)}" if missing else None

    def hold(self, span: SampleSpan) -> str | None:
        """Why the block of `span` may not be sent yet, or None (it may)."""
        unheard = self.unheard()
        if unheard:
            return unheard
        if self.gate is None or span.segment != self.segment or span.first_index != self.reach:
            behind = self._behind(self.reach)
            if behind:
                return behind
            self._stretch(span)
        assert self.gate is not None
        last = span.first_index + span.count - 1
        if last > self.gate.limit():
            return self._behind(last - self.window + 1) or "waiting for flow_progress"
        return None

    def sent(self, span: SampleSpan) -> None:
        """The block of `span` was published."""
        self.reach = span.first_index + span.count
        if self.gate is not None:
            self.gate.report(self.me, self.segment, self.reach)

    def pending(self) -> str | None:
        """Who has not yet taken everything sent (the replay's end waits for them), or None."""
        return self._behind(self.reach)

    def _stretch(self, span: SampleSpan) -> None:
        same = self.gate is not None and span.segment == self.segment
        self.stale = dict.fromkeys(self.subscribers, self.reach) if same else {}
        self.segment, self.base, self.reach = span.segment, span.first_index, span.first_index
        self.gate = FlowGate(self.window, self.me, self.subscribers)
        self.gate.report(self.me, self.segment, self.base)
        for name in self.subscribers:
            self.gate.report(name, self.segment, self.base)

    def _behind(self, samples: int) -> str | None:
        """Who has not yet taken `samples` samples of the stretch's segment (None: all have)."""
        if self.gate is None:
            return None
        slowest = self.gate.slowest()
        if slowest is None or slowest[1] >= samples - 1:
            return None
        name, covered = slowest
        return (
            f"waiting for {name} (flow_progress): it has taken segment {self.segment} up to sample "
            f"{covered}, {samples - 1 - covered} short of sample {samples - 1}"
        )
