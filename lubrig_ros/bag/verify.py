"""Verify a bag as an independent reader would: structure, CRCs, index, summary, metadata, continuity.

``verify_bag(bag, full=True)`` checks, in file order, and lists every problem with its byte
offset and topic (the first one is what the CLI names):

- the directory (metadata.yaml present and readable, one .mcap file) and the MCAP magic;
- the header (op 0x01, profile ros2);
- every record frame of the data section; every chunk's decompression, size and CRC-32 (a CRC
  of 0 — bags of the earlier rosbags-based writer — is a note, not a problem: such a chunk cannot be
  checked), its inner records and the log-time range it declares; every message index against
  the chunk before it; the DataEnd record's data-section CRC (verify_data);
- the footer and the summary: its CRC, its records, schemas and channels against the data
  section, statistics, the chunk indexes against the chunks, the metadata index (verify_summary);
- metadata.yaml against the file, every field it holds: file names and sizes, start, duration,
  counts, and per topic type, serialization format, QoS, type hash and count; custom_data,
  ros_distro and version against the file's rosbag2 record (metacheck);
- (full only) per-stream sample continuity (continuity): for RigState (sample_index, segment)
  and RigStateBlock / BandVelocityBlock (first_sample_index + n, segment) gaps, duplicates and
  stamps going back; for Float64 / JointState streams of one message per sample log-time steps
  against the sample period when the log times are on that grid (rig time); receive-time log
  times are noted as unchecked.

``continuity=False`` is the part ``lubrig report`` and ``lubrig replay`` run first (no message is
decoded); ``full=False`` is cheaper still: record frames, chunk headers, footer, summary and
metadata.yaml, without decompressing any chunk.
Nothing here raises for a damaged file: every failure is a :class:`Problem`.
"""

from __future__ import annotations

import mmap
from collections.abc import Callable
from pathlib import Path

from lubrig_ros.bag.continuity import INDEXED_TYPES, SPACED_TYPES, check_continuity
from lubrig_ros.bag.errors import BagError
from lubrig_ros.bag.findings import CONTINUITY, NO_BAG, STRUCTURE, Problem, StreamReport, Verification
from lubrig_ros.bag.layout import MetadataUnreadableError, bag_information, find_mcap
from lubrig_ros.bag.metacheck import check_metadata, file_facts
from lubrig_ros.bag.verify_data import ScanState, walk
from lubrig_ros.bag.verify_summary import check_summary

__all__ = [
    "CONTINUITY",
    "INDEXED_TYPES",
    "SPACED_TYPES",
    "STRUCTURE",
    "Problem",
    "StreamReport",
    "Verification",
    "inspect_bag",
    "refuse_damaged",
    "verify_bag",
]


def refuse_damaged(bag: str | Path, command: str) -> None:
    """The cheap part `lubrig report` / `lubrig replay` run first: BagError (one line) if damaged.

    Everything of the file (CRCs, index, summary, footer, metadata.yaml), not the continuity of
    the samples (a bag with gaps is reported on; `lubrig bag info` shows them).
    """
    problem = verify_bag(bag, full=True, continuity=False).error(command)
    if problem is not None:
        raise problem


def _directory(v: Verification) -> bool:
    """Check the bag directory and read metadata.yaml; False if there is nothing to verify."""
    bag = v.bag
    if not bag.exists():
        v.add(f"bag {str(bag)!r} does not exist: give a bag directory or an .mcap file", kind=NO_BAG)
        return False
    if not bag.is_dir():
        return True
    n_mcap = len(list(bag.glob("*.mcap")))
    meta_path = bag / "metadata.yaml"
    if not meta_path.exists() and n_mcap != 1:
        v.add(
            f"bag {str(bag)!r}: expected one .mcap file in the bag directory, found {n_mcap} "
            "(and no metadata.yaml): not a bag",
            kind=NO_BAG,
        )
        return False
    if not meta_path.is_file():
        v.add("metadata.yaml is missing (recording not finalized, or deleted)")
        return True
    try:
        v.metadata = bag_information(bag)
    except MetadataUnreadableError as exc:
        v.add(exc.what)
    return True


def verify_bag(bag: str | Path, full: bool = True, continuity: bool = True) -> Verification:
    """Check bag (a directory or an .mcap file); see the module docstring. Never raises BagError.

    full=False: no chunk is decompressed (frames, chunk headers, summary, footer, metadata.yaml);
    continuity=False: everything of the file, not the samples' continuity.
    """
    return inspect_bag(bag, full, continuity)[0]


def inspect_bag(
    bag: str | Path, full: bool = True, continuity: bool = True, keep: Callable[[str], bool] | None = None
) -> tuple[Verification, ScanState]:
    """verify_bag, and what its one walk of the file collected (ScanState).

    With `keep` (full only) the walk keeps the payload of every message on a topic keep(topic)
    accepts (ScanState.messages), so a reader needs no second pass (lubrig_ros.bag.reader.Bag).
    """
    v = Verification(Path(bag), full=full)
    st = ScanState(keep_samples=full and continuity, keep=keep if full else None)
    if not _directory(v):
        return v, st
    try:
        v.mcap = find_mcap(v.bag)
    except BagError as exc:
        v.add(str(exc))
        return v, st
    try:
        with open(v.mcap, "rb") as f:
            size = f.seek(0, 2)
            if size == 0:
                v.add("the .mcap file is empty", 0)
                return v, st
            with mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
                data_end = walk(v, buf, size, st, full)
                if data_end is not None:
                    check_summary(v, buf, size, data_end, st)
        _conclude(v, st, full, continuity)
    except OSError as exc:
        v.add(f"cannot read {str(v.mcap)!r}: {exc.strerror or exc}")
    return v, st


def _conclude(v: Verification, st: ScanState, full: bool, continuity: bool) -> None:
    """Counts, types and times of the walk; metadata.yaml against them; continuity."""
    assert v.mcap is not None
    counts = st.counts if full else st.index_counts
    v.counts = {ch.topic: counts.get(cid, 0) for cid, ch in sorted(st.channels.items())}
    v.types = {ch.topic: st.msgtype(cid) for cid, ch in sorted(st.channels.items())}
    if sum(v.counts.values()) and st.end >= st.start:
        v.start_ns, v.end_ns = st.start, st.end
    if v.metadata is not None:
        comparable = full or v.finalized or not v.structural  # counts of a broken file are not
        check_metadata(v, v.metadata, file_facts(st, v.mcap, v.counts, full), comparable)
    if full and continuity:
        check_continuity(v, st.channels, st.schemas, st.samples, st.skipped, v.metadata)
