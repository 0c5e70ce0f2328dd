"""An opened bag read message by message, in file order, without holding it in memory.

:func:`open_bag` runs the cheap part of `lubrig bag check` (record frames, chunk headers, summary,
footer, metadata.yaml: no chunk is decompressed) and gives an :class:`OpenedBag`: its topics,
types, counts, log-time span and run configuration. :meth:`OpenedBag.messages` then walks the
data section once (lubrig_ros.bag.mcapscan: every chunk's CRC checked as it is reached) and
yields each message as it comes, so a one-hour recording costs one chunk of memory, not the run.
A damaged chunk is a BagError when the walk ends (what was yielded before stays valid; the
callers write their output under a temporary name and drop it then).

Order: the file's, which is the order the recorder wrote (per stream, the order the samples
arrived: sample order for the plant's streams; `lubrig bag check` names any sample out of order).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from lubrig_ros.bag.errors import BagError
from lubrig_ros.bag.layout import RUN_CONFIG_KEY
from lubrig_ros.bag.reader import Stream, messages_in_file_order
from lubrig_ros.bag.verify import verify_bag


@dataclass
class OpenedBag:
    """A bag whose structure verified: what it holds, and its messages on demand."""

    path: Path  # as given (directory or .mcap file)
    mcap: Path
    types: dict[str, str]  # topic -> message type, every channel of the file
    counts: dict[str, int]  # topic -> messages (the file's index)
    start_ns: int  # first log time
    end_ns: int  # last log time
    custom_data: dict[str, str] = field(default_factory=dict)

    @property
    def run_config(self) -> str | None:
        """The run configuration YAML stored with the bag, if any."""
        return self.custom_data.get(RUN_CONFIG_KEY)

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[tuple[Stream, int, bytes]]:
        """(stream, log_time_ns, cdr_bytes) of every message of `topics` (None: all), in file order.

        BagError when a chunk does not verify or a message is on an undefined channel.
        """
        return messages_in_file_order(self.path, topics, mcap=self.mcap)


def open_bag(bag: str | Path) -> OpenedBag:
    """Open a bag after the cheap structural check; BagError (one line) if it is missing or damaged."""
    v = verify_bag(bag, full=False, continuity=False)
    problem = v.error()
    if problem is not None:
        raise problem
    assert v.mcap is not None
    start, end = _log_time_span(v.mcap)
    custom = (v.metadata or {}).get("custom_data") or {}
    return OpenedBag(
        Path(bag),
        v.mcap,
        dict(v.types),
        dict(v.counts),
        start,
        end,
        {str(k): str(x) for k, x in dict(custom).items()},  # type: ignore[call-overload]
    )


def _log_time_span(mcap: Path) -> tuple[int, int]:
    """(first, last) log time of a verified file, from its summary's statistics (the `mcap` reader)."""
    from mcap.reader import make_reader

    try:
        with open(mcap, "rb") as f:
            summary = make_reader(f).get_summary()
    except Exception as exc:  # the summary verified; a reader failing on it is named, not raised
        raise BagError(f"cannot read the summary of {str(mcap)!r}: {exc}") from None
    stats = summary.statistics if summary is not None else None
    if stats is None or not stats.message_count:
        return 0, 0
    return int(stats.message_start_time), int(stats.message_end_time)
