"""What verifying a bag finds: problems (where and what), per-stream continuity, the verdict.

Filled by the verifier's parts (verify_data, verify_summary, metacheck, continuity) and read by
`lubrig bag check|info`, repair and the report / replay refusal (lubrig_ros.bag.verify).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from .errors import BagError

STRUCTURE, CONTINUITY = "structure", "continuity"
#: A structural problem that means there is no bag at all (missing path, no .mcap): nothing to repair.
NO_BAG = "no bag"


@dataclass(frozen=True)
class Problem:
    """One thing wrong with a bag: where (byte offset, topic) and what."""

    text: str
    offset: int | None = None
    topic: str | None = None
    kind: str = STRUCTURE

    def line(self) -> str:
        """One line: `at byte N (topic T): text`."""
        where = []
        if self.offset is not None:
            where.append(f"at byte {self.offset}")
        if self.topic:
            where.append(f"{'topics' if ', ' in self.topic else 'topic'} {self.topic}")
        return f"{', '.join(where)}: {self.text}" if where else self.text


@dataclass
class StreamReport:
    """Sample continuity of one topic."""

    topic: str
    msgtype: str
    messages: int = 0
    samples: int = 0
    method: str = "unchecked"
    gaps: int = 0
    missing: int = 0
    first_gap_s: float | None = None
    duplicates: int = 0
    first_duplicate_s: float | None = None
    backwards: int = 0
    first_backwards_s: float | None = None
    segments: int = 0
    declared_gaps: int = 0  # RigStateBlock.skipped: the plant fell behind real time
    skipped: int = 0
    first_skip_s: float | None = None

    def format(self) -> str:
        """`gaps 2 (first at 1.234 s), duplicates 0` or why continuity was not checked."""
        if not self.method.startswith("by "):
            return self.method
        text = f"gaps {self.gaps}"
        if self.gaps:
            text += f" ({self.missing} samples missing, first at {self.first_gap_s:.6f} s)"
        text += f", duplicates {self.duplicates}"
        if self.duplicates:
            text += f" (first at {self.first_duplicate_s:.6f} s)"
        if self.backwards:
            text += f", backwards {self.backwards} (first at {self.first_backwards_s:.6f} s)"
        if self.declared_gaps:
            text += (
                f", declared gaps {self.declared_gaps} ({self.skipped} samples skipped by the "
                f"plant behind real time, first at {self.first_skip_s:.6f} s)"
            )
        return text


@dataclass
class Verification:
    """What verify_bag found."""

    bag: Path
    mcap: Path | None = None
    full: bool = True
    problems: list[Problem] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    streams: dict[str, StreamReport] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    types: dict[str, str] = field(default_factory=dict)
    chunks: int = 0
    finalized: bool = False
    start_ns: int = 0  # first and last log time of the data section (0, 0 without messages)
    end_ns: int = 0
    #: metadata.yaml's rosbag2_bagfile_information (None: missing or unreadable)
    metadata: dict[str, object] | None = None

    @property
    def ok(self) -> bool:
        """No problem of any kind."""
        return not self.problems

    @property
    def structural(self) -> list[Problem]:
        """Problems of the file itself (what repair fixes), not of the recorded data."""
        return [p for p in self.problems if p.kind in (STRUCTURE, NO_BAG)]

    @property
    def no_bag(self) -> bool:
        """There is no bag at the path at all (nothing to repair)."""
        return bool(self.problems) and self.problems[0].kind == NO_BAG

    def problem_line(self, command: str | None = None) -> str:
        """The one line naming the first problem: what it is, and repair when it can help."""
        if self.no_bag:
            return self.problems[0].text
        how = f"{command} refuses it: run" if command else "run"
        return f"{self.verdict()}; {how} `lubrig bag repair {self.bag}`{' first' if command else ''}"

    def error(self, command: str | None = None) -> BagError | None:
        """The one-line BagError of a bag with a structural problem (None: none); see problem_line."""
        return BagError(self.problem_line(command)) if self.structural else None

    def add(
        self, text: str, offset: int | None = None, topic: str | None = None, kind: str = STRUCTURE
    ) -> None:
        """Record a problem."""
        self.problems.append(Problem(text, offset, topic, kind))

    def verdict(self) -> str:
        """One line: OK with what was checked, or the first problem and how many there are."""
        if self.ok:
            what = "fully verified" if self.full else "structure verified (quick)"
            total = sum(self.counts.values())
            return f"bag {str(self.bag)!r} OK: {what}, {total} messages, {self.chunks} chunks"
        more = f" (+{len(self.problems) - 1} more)" if len(self.problems) > 1 else ""
        return f"bag {str(self.bag)!r} is damaged: {self.problems[0].line()}{more}"
