"""Verify a bag as an independent reader would: structure, CRCs, index, summary, counts, continuity.

``verify_bag(bag, full=True)`` checks, in file order, and lists every problem with its byte
offset and topic (the first one is what the CLI names):

- the directory (metadata.yaml present and readable, one .mcap file) and the MCAP magic;
- the header (op 0x01, profile ros2);
- every record frame of the data section; every chunk's decompression, size and CRC-32 (a CRC
  of 0 — bags written before issue 15 — is a note, not a problem: such a chunk cannot be
  checked), its inner records and the log-time range it declares; every message index against
  the chunk before it; the DataEnd record's data-section CRC;
- the footer and the summary: its CRC, its records, schemas and channels against the data
  section, statistics, the chunk indexes against the chunks, the metadata index;
- metadata.yaml: the file name and the message counts per topic against the data section;
- (full only) per-stream sample continuity: for RigState (sample_index, segment) and
  RigStateBlock / BandVelocityBlock (first_sample_index + n, segment) gaps, duplicates and
  stamps going back; for Float64 / JointState streams of one message per sample (contract
  rate: output rate) log-time steps against the sample period (the run configuration's
  sample_rate, else the median step) when the log times are on that grid (rig time);
  receive-time log times are noted as unchecked.

``continuity=False`` is the part ``lubrig report`` and ``lubrig replay`` run first (no message is
decoded); ``full=False`` is cheaper still: record frames, chunk headers, footer, summary and
metadata.yaml, without decompressing any chunk.
Nothing here raises for a damaged file: every failure is a :class:`Problem`.
"""

from __future__ import annotations

import itertools
import mmap
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import yaml
from backports import zstd

from lubrig_ros.app import contract
from lubrig_ros.app.cdr import block_skipped
from lubrig_ros.bag.errors import BagError
from lubrig_ros.bag.layout import RUN_CONFIG_KEY, bag_information, find_mcap

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
OP_MESSAGE_INDEX, OP_CHUNK_INDEX, OP_ATTACHMENT, OP_ATTACHMENT_INDEX = 0x07, 0x08, 0x09, 0x0A
OP_STATISTICS, OP_METADATA, OP_METADATA_INDEX, OP_SUMMARY_OFFSET, OP_DATA_END = 0x0B, 0x0C, 0x0D, 0x0E, 0x0F
FOOTER_BYTES = 1 + 8 + 8 + 8 + 4  # footer record; the file ends with it and the magic
STRUCTURE, CONTINUITY = "structure", "continuity"
Buffer = bytes | memoryview | mmap.mmap
INDEXED_TYPES = {
    "lubrig_interfaces/msg/RigState": "sample",
    "lubrig_interfaces/msg/RigStateBlock": "block",
    "lubrig_interfaces/msg/BandVelocityBlock": "block",
}
SPACED_TYPES = {"std_msgs/msg/Float64", "sensor_msgs/msg/JointState", "rosgraph_msgs/msg/Clock"}


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
            text += (f", declared gaps {self.declared_gaps} ({self.skipped} samples skipped by the "
                     f"plant behind real time, first at {self.first_skip_s:.6f} s)")
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

    @property
    def ok(self) -> bool:
        """No problem of any kind."""
        return not self.problems

    @property
    def structural(self) -> list[Problem]:
        """Problems of the file itself (what repair fixes), not of the recorded data."""
        return [p for p in self.problems if p.kind == STRUCTURE]

    def add(self, text: str, offset: int | None = None, topic: str | None = None,
            kind: str = STRUCTURE) -> None:
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


def refuse_damaged(bag: str | Path, command: str) -> None:
    """The cheap part `lubrig report` / `lubrig replay` run first: BagError (one line) if damaged.

    Everything of the file (CRCs, index, summary, footer, metadata.yaml), not the continuity of
    the samples (a bag with gaps is reported on; `lubrig bag info` shows them).
    """
    v = verify_bag(bag, full=True, continuity=False)
    if v.structural:
        first = v.structural[0]
        if "does not exist" in first.text or "not a bag" in first.text:
            raise BagError(first.text)  # the command's own error line names the command
        raise BagError(f"{v.verdict()}; {command} refuses it: run `lubrig bag repair {bag}` first")


# ----------------------------------------------------------------------------- record parsing


class _BadError(Exception):
    """A record body does not parse."""


class _Body:
    """Little-endian reader over one record body."""

    def __init__(self, buf: Buffer, start: int = 0, end: int | None = None) -> None:
        self.buf, self.pos = buf, start
        self.end = len(buf) if end is None else end

    def take(self, n: int) -> bytes:
        if n < 0 or self.pos + n > self.end:
            raise _BadError(f"field of {n} bytes runs past the record end")
        out = bytes(self.buf[self.pos : self.pos + n])
        self.pos += n
        return out

    def u(self, fmt: str) -> int:
        size = struct.calcsize(fmt)
        (value,) = struct.unpack("<" + fmt, self.take(size))
        return int(value)

    def string(self) -> str:
        n = self.u("I")
        try:
            return self.take(n).decode()
        except UnicodeDecodeError as exc:
            raise _BadError(f"string is not UTF-8 ({exc.reason})") from None

    def data(self, width: str = "I") -> bytes:
        return self.take(self.u(width))

    def string_map(self) -> dict[str, str]:
        n = self.u("I")
        end = self.pos + n
        if end > self.end:
            raise _BadError("map runs past the record end")
        out: dict[str, str] = {}
        while self.pos < end:
            key = self.string()
            out[key] = self.string()
        if self.pos != end:
            raise _BadError("map length disagrees with its entries")
        return out


def _frames(buf: Buffer, start: int, end: int) -> Iterator[tuple[int, int, int, int]]:
    """(offset, opcode, body start, body end) of the records in buf[start:end]; _BadError on a bad frame."""
    pos = start
    while pos < end:
        if pos + 9 > end:
            raise _BadError(f"record header truncated at byte {pos}")
        op = buf[pos]
        (n,) = struct.unpack_from("<Q", buf, pos + 1)
        if not 0x01 <= op <= 0x0F:
            raise _BadError(f"invalid record opcode 0x{op:02x} at byte {pos}")
        if pos + 9 + n > end:
            raise _BadError(f"record (opcode 0x{op:02x}) at byte {pos} runs past the end ({n} bytes)")
        yield pos, op, pos + 9, pos + 9 + n
        pos += 9 + n


@dataclass
class _Chunk:
    offset: int
    length: int
    start: int
    end: int
    compression: str
    compressed_size: int
    uncompressed_size: int
    messages: dict[int, set[tuple[int, int]]] = field(default_factory=dict)
    index_offsets: dict[int, int] = field(default_factory=dict)
    index_end: int = 0
    decoded: bool = False


@dataclass
class _State:
    schemas: dict[int, tuple[str, str, bytes]] = field(default_factory=dict)
    channels: dict[int, tuple[int, str, str, dict[str, str]]] = field(default_factory=dict)
    counts: dict[int, int] = field(default_factory=dict)
    index_counts: dict[int, int] = field(default_factory=dict)
    chunks: list[_Chunk] = field(default_factory=list)
    metadata: dict[int, str] = field(default_factory=dict)
    samples: dict[int, list[tuple[int, int, bytes]]] = field(default_factory=dict)  # cid -> (off, t, data)
    start: int = 2**63 - 1
    end: int = 0
    zero_crc: int = 0
    keep_samples: bool = True  # payloads kept for the continuity check
    #: channel id -> its schema has RigStateBlock.skipped (read at scan time: it follows the arrays)
    declares: dict[int, bool] = field(default_factory=dict)
    #: (channel id, position in samples[cid]) -> RigStateBlock.skipped when not 0
    skipped: dict[tuple[int, int], int] = field(default_factory=dict)


def _schema(b: _Body) -> tuple[int, tuple[str, str, bytes]]:
    sid = b.u("H")
    name = b.string()
    encoding = b.string()
    return sid, (name, encoding, b.data())


def _channel(b: _Body) -> tuple[int, tuple[int, str, str, dict[str, str]]]:
    cid, sid = b.u("H"), b.u("H")
    topic = b.string()
    encoding = b.string()
    return cid, (sid, topic, encoding, b.string_map())


# ----------------------------------------------------------------------------- the walk


def verify_bag(bag: str | Path, full: bool = True, continuity: bool = True) -> Verification:
    """Check bag (a directory or an .mcap file); see the module docstring. Never raises BagError.

    full=False: no chunk is decompressed (frames, chunk headers, summary, footer, metadata.yaml);
    continuity=False: everything of the file, not the samples' continuity.
    """
    bag = Path(bag)
    v = Verification(bag, full=full)
    meta: dict[str, object] | None = None
    if not bag.exists():
        v.add(f"bag {str(bag)!r} does not exist: give a bag directory or an .mcap file")
        return v
    if bag.is_dir() and not (bag / "metadata.yaml").exists() and len(list(bag.glob("*.mcap"))) != 1:
        n_mcap = len(list(bag.glob("*.mcap")))
        v.add(f"expected one .mcap file in the bag directory, found {n_mcap} (and no metadata.yaml): "
              "not a bag")
        return v
    if bag.is_dir():
        meta_path = bag / "metadata.yaml"
        if not meta_path.is_file():
            v.add("metadata.yaml is missing (recording not finalized, or deleted)", topic=None)
        else:
            try:
                meta = bag_information(bag)
            except BagError as exc:
                v.add(str(exc))
    try:
        v.mcap = find_mcap(bag)
    except BagError as exc:
        if meta is not None or not bag.is_dir():
            v.add(str(exc))
        else:
            v.add(f"expected one .mcap file in the bag directory, found {len(list(bag.glob('*.mcap')))}")
        return v
    try:
        with open(v.mcap, "rb") as f:
            size = f.seek(0, 2)
            if size == 0:
                v.add("the .mcap file is empty", 0)
                return v
            with mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
                st = _State(keep_samples=full and continuity)
                _walk(v, buf, size, st, full)
                names = {cid: ch[1] for cid, ch in st.channels.items()}
                counts = st.counts if full else st.index_counts
                v.counts = {names[c]: counts.get(c, 0) for c in sorted(names)}
                v.types = {
                    ch[1]: st.schemas.get(ch[0], ("?", "", b""))[0] for _c, ch in sorted(st.channels.items())
                }
                if meta is not None:
                    _check_metadata(v, meta)
                if full and continuity:
                    _continuity(v, st, meta)
    except OSError as exc:
        v.add(f"cannot read {str(v.mcap)!r}: {exc.strerror or exc}")
    return v


def _walk(v: Verification, buf: mmap.mmap, size: int, st: _State, full: bool) -> None:
    if size < 8 or buf[:8] != MAGIC:
        v.add("file does not start with the MCAP magic", 0)
        return
    pos = 8
    if size < 17 or buf[8] != OP_HEADER:
        v.add("no header record after the magic", 8)
        return
    try:
        (n,) = struct.unpack_from("<Q", buf, 9)
        b = _Body(buf, 17, min(17 + n, size))
        profile, _library = b.string(), b.string()
    except (_BadError, struct.error) as exc:
        v.add(f"header record is unreadable: {exc}", 8)
        return
    if profile != "ros2":
        v.add(f"header profile is {profile!r}, expected 'ros2'", 8)
    pos = 17 + n
    data_end = _walk_data(v, buf, size, pos, st, full)
    v.chunks = len(st.chunks)
    topics = {c.offset: _topics_of(st, c.index_offsets) for c in st.chunks}
    v.problems = [  # a damaged chunk is named by the topics its message index lists
        Problem(p.text, p.offset, topics[p.offset], p.kind) if p.topic is None and p.offset in topics else p
        for p in v.problems
    ]
    if st.zero_crc:
        v.notes.append(
            f"{st.zero_crc} chunk(s) carry no CRC (written before issue 15): damage inside them "
            "cannot be detected"
        )
    if data_end is not None:
        _check_summary(v, buf, size, data_end, st)


def _walk_data(v: Verification, buf: mmap.mmap, size: int, pos: int, st: _State, full: bool) -> int | None:
    """Walk the data section from pos; the offset after DataEnd, or None if it was not reached."""
    last_chunk: _Chunk | None = None
    try:
        for off, op, b0, b1 in _frames(buf, pos, size):
            if op == OP_FOOTER:
                v.add("footer reached without a DataEnd record", off)
                return None
            try:
                if op == OP_DATA_END:
                    (crc,) = struct.unpack_from("<I", buf, b0)
                    if full and crc and zlib.crc32(buf[:off]) != crc:
                        v.add("data section CRC mismatch (DataEnd record)", off)
                    return b1
                if op == OP_SCHEMA:
                    sid, schema = _schema(_Body(buf, b0, b1))
                    st.schemas.setdefault(sid, schema)
                elif op == OP_CHANNEL:
                    cid, ch = _channel(_Body(buf, b0, b1))
                    st.channels.setdefault(cid, ch)
                elif op == OP_CHUNK:
                    if last_chunk is not None:
                        last_chunk.messages = {}  # compared with its message index already
                    last_chunk = _chunk(v, buf, off, b0, b1, st, full)
                elif op == OP_MESSAGE_INDEX:
                    _message_index(v, buf, off, b0, b1, st, last_chunk, full)
                elif op == OP_MESSAGE:
                    b = _Body(buf, b0, b1)
                    cid = b.u("H")
                    b.u("I")
                    t = b.u("Q")
                    if cid not in st.channels:
                        v.add(f"message on undefined channel {cid}", off)
                    st.counts[cid] = st.counts.get(cid, 0) + 1
                    st.index_counts[cid] = st.index_counts.get(cid, 0) + 1
                    st.start, st.end = min(st.start, t), max(st.end, t)
                elif op == OP_METADATA:
                    st.metadata[off] = _Body(buf, b0, b1).string()
                elif op in (OP_CHUNK_INDEX, OP_STATISTICS, OP_SUMMARY_OFFSET, OP_ATTACHMENT_INDEX,
                            OP_METADATA_INDEX):
                    v.add(f"summary record (opcode 0x{op:02x}) inside the data section", off)
            except (_BadError, struct.error) as exc:
                v.add(f"record (opcode 0x{op:02x}) is unreadable: {exc}", off)
    except _BadError as exc:
        offset = _offset_of(str(exc))
        v.add(f"data section broken: {exc} (truncated or overwritten?)", offset)
        return None
    v.add(f"file ends at byte {size} without DataEnd, summary and footer (not finalized or truncated)", size)
    return None


def _offset_of(text: str) -> int | None:
    words = text.replace(")", " ").split()
    for i, w in enumerate(words[:-1]):
        if w == "byte" and words[i + 1].isdigit():
            return int(words[i + 1])
    return None


def _topics_of(st: _State, cids: object) -> str | None:
    names = sorted({st.channels[c][1] for c in cids if c in st.channels})  # type: ignore[attr-defined]
    return ", ".join(names) if names else None


def _chunk(v: Verification, buf: mmap.mmap, off: int, b0: int, b1: int, st: _State, full: bool) -> _Chunk:
    b = _Body(buf, b0, b1)
    start, end, usize, crc = b.u("Q"), b.u("Q"), b.u("Q"), b.u("I")
    comp = b.string()
    csize = b.u("Q")
    chunk = _Chunk(off, b1 - off, start, end, comp, csize, usize)
    st.chunks.append(chunk)
    if b.pos + csize != b1:
        v.add(f"chunk's compressed size {csize} disagrees with its record length", off)
        return chunk
    if not full:
        return chunk
    try:
        if comp == "zstd":
            raw = zstd.decompress(bytes(buf[b.pos : b1]))
        elif comp == "":
            raw = bytes(buf[b.pos : b1])
        else:
            v.add(f"chunk compression {comp!r} is not supported", off)
            return chunk
    except zstd.ZstdError as exc:
        v.add(f"chunk does not decompress ({exc})", off)
        return chunk
    if len(raw) != usize:
        v.add(f"chunk decompresses to {len(raw)} bytes, its header says {usize}", off)
        return chunk
    if crc == 0:
        st.zero_crc += 1
    elif zlib.crc32(raw) != crc:
        v.add(f"chunk CRC mismatch (stored 0x{crc:08x}, computed 0x{zlib.crc32(raw):08x})", off)
        return chunk
    times: list[int] = []
    try:
        for roff, op, r0, r1 in _frames(raw, 0, len(raw)):
            rb = _Body(raw, r0, r1)
            if op == OP_SCHEMA:
                sid, schema = _schema(rb)
                st.schemas.setdefault(sid, schema)
            elif op == OP_CHANNEL:
                cid, ch = _channel(rb)
                if ch[0] not in st.schemas and ch[0] != 0:
                    v.add(f"channel {cid} ({ch[1]}) refers to undefined schema {ch[0]}", off, ch[1])
                st.channels.setdefault(cid, ch)
            elif op == OP_MESSAGE:
                cid, _seq, t, _pub = rb.u("H"), rb.u("I"), rb.u("Q"), rb.u("Q")
                if cid not in st.channels:
                    v.add(f"message on undefined channel {cid} inside the chunk", off)
                chunk.messages.setdefault(cid, set()).add((t, roff))
                st.counts[cid] = st.counts.get(cid, 0) + 1
                if st.keep_samples:
                    # the leading fields are enough (header, indices, the first array's length);
                    # a block's declared skip comes after its arrays: read now
                    kept = st.samples.setdefault(cid, [])
                    kept.append((off, t, raw[r0 + 22 : min(r1, r0 + 22 + 512)]))
                    if _declares(st, cid):
                        skipped = _skipped_of(raw[r0 + 22 : r1])
                        if skipped:
                            st.skipped[(cid, len(kept) - 1)] = skipped
                times.append(t)
            else:
                v.add(f"record opcode 0x{op:02x} is not allowed inside a chunk", off)
    except (_BadError, struct.error) as exc:
        v.add(f"chunk records are unreadable: {exc}", off)
        return chunk
    chunk.decoded = True
    if times:
        st.start, st.end = min(st.start, min(times)), max(st.end, max(times))
        if min(times) != start or max(times) != end:
            topic = _topics_of(st, chunk.messages)
            v.add(f"chunk declares log times {start}..{end} ns, holds {min(times)}..{max(times)}", off, topic)
    return chunk


def _message_index(v: Verification, buf: mmap.mmap, off: int, b0: int, b1: int, st: _State,
                   chunk: _Chunk | None, full: bool) -> None:
    b = _Body(buf, b0, b1)
    cid = b.u("H")
    n = b.u("I")
    if n % 16 or b.pos + n != b1:
        raise _BadError("message index length is not a multiple of 16 or disagrees with the record")
    entries = {struct.unpack_from("<QQ", buf, b.pos + 16 * k) for k in range(n // 16)}
    st.index_counts[cid] = st.index_counts.get(cid, 0) + len(entries)
    topic = st.channels.get(cid, (0, None))[1]
    if chunk is None:
        v.add("message index without a chunk before it", off, topic)
        return
    chunk.index_offsets[cid] = off
    chunk.index_end = b1
    if full and chunk.decoded and entries != chunk.messages.get(cid, set()):
        v.add(f"message index disagrees with the chunk at byte {chunk.offset}", off, topic)


def _check_summary(v: Verification, buf: mmap.mmap, size: int, data_end: int, st: _State) -> None:
    footer = size - len(MAGIC) - FOOTER_BYTES
    if footer < data_end:
        v.add("file ends after the data section without a footer (truncated?)", data_end)
        return
    if buf[size - 8 : size] != MAGIC:
        v.add("file does not end with the MCAP magic (truncated or damaged footer)", size - 8)
        return
    if buf[footer] != OP_FOOTER or struct.unpack_from("<Q", buf, footer + 1)[0] != 20:
        v.add("footer record is damaged", footer)
        return
    summary_start, offset_start, crc = struct.unpack_from("<QQI", buf, footer + 9)
    if summary_start == 0:
        v.add("the footer points to no summary (no index: readers must scan the file)", footer)
        return
    if summary_start != data_end:
        v.add(f"footer's summary start {summary_start} is not the end of the data section {data_end}", footer)
        return
    if crc == 0:
        v.notes.append("the summary carries no CRC (written before issue 15)")
    elif zlib.crc32(buf[summary_start : footer + 25]) != crc:
        v.add("summary CRC mismatch (summary or footer damaged)", summary_start)
    if offset_start and not summary_start <= offset_start <= footer:
        v.add(f"footer's summary offset start {offset_start} lies outside the summary", footer)
    chunk_at = {c.offset: c for c in st.chunks}
    seen_index: set[int] = set()
    stats_seen = False
    try:
        for off, op, b0, b1 in _frames(buf, summary_start, footer):
            b = _Body(buf, b0, b1)
            try:
                if op == OP_SCHEMA:
                    sid, schema = _schema(b)
                    if not v.full or sid not in st.schemas:
                        # not scanned (the definitions are inside the chunks), or defined in the
                        # summary only: the writer puts a definition into the data section with
                        # its first message, so a topic without messages (an empty bag) has none
                        st.schemas.setdefault(sid, schema)
                    elif st.schemas[sid] != schema:
                        v.add(f"summary schema {sid} ({schema[0]}) differs from the data section", off)
                elif op == OP_CHANNEL:
                    cid, ch = _channel(b)
                    if not v.full or cid not in st.channels:  # as for schemas
                        st.channels.setdefault(cid, ch)
                    elif st.channels[cid] != ch:
                        v.add(f"summary channel {cid} differs from the data section", off, ch[1])
                elif op == OP_STATISTICS:
                    stats_seen = True
                    _statistics(v, b, off, st)
                elif op == OP_CHUNK_INDEX:
                    _chunk_index(v, b, off, chunk_at, seen_index, st)
                elif op == OP_METADATA_INDEX:
                    moff, _mlen = b.u("Q"), b.u("Q")
                    name = b.string()
                    if st.metadata.get(moff) != name:
                        v.add(f"metadata index points to byte {moff}, no metadata record {name!r} there", off)
                elif op == OP_SUMMARY_OFFSET:
                    gop, gstart, glen = b.u("B"), b.u("Q"), b.u("Q")
                    inside = summary_start <= gstart and gstart + glen <= footer
                    if glen and not (inside and buf[gstart] == gop):
                        v.add(f"summary offset for opcode 0x{gop:02x} points to byte {gstart}, "
                              "no such group", off)
                elif op in (OP_MESSAGE, OP_CHUNK, OP_MESSAGE_INDEX, OP_DATA_END, OP_HEADER):
                    v.add(f"record opcode 0x{op:02x} is not allowed in the summary", off)
            except (_BadError, struct.error) as exc:
                v.add(f"summary record (opcode 0x{op:02x}) is unreadable: {exc}", off)
    except _BadError as exc:
        v.add(f"summary section broken: {exc}", _offset_of(str(exc)))
        return
    missing = [c.offset for c in st.chunks if c.offset not in seen_index]
    if missing:
        v.add(f"{len(missing)} chunk(s) have no chunk index in the summary", missing[0],
              _topics_of(st, next(c for c in st.chunks if c.offset == missing[0]).index_offsets))
    if not stats_seen:
        v.add("the summary has no statistics record", summary_start)
    if not v.structural:
        v.finalized = True


def _statistics(v: Verification, b: _Body, off: int, st: _State) -> None:
    total = b.u("Q")
    n_schema, n_channel = b.u("H"), b.u("I")
    _attach, _meta, n_chunk = b.u("I"), b.u("I"), b.u("I")
    t0, t1 = b.u("Q"), b.u("Q")
    n = b.u("I")
    per: dict[int, int] = {}
    end = b.pos + n
    while b.pos < end:
        cid = b.u("H")
        per[cid] = b.u("Q")
    counts = st.counts if v.full else st.index_counts
    if total != sum(counts.values()):
        v.add(f"summary statistics count {total} messages, the data section holds "
              f"{sum(counts.values())}", off)
    for cid, count in sorted(per.items()):
        if counts.get(cid, 0) != count:
            topic = st.channels.get(cid, (0, None))[1]
            v.add(f"summary statistics count {count} messages, the data section holds {counts.get(cid, 0)}",
                  off, topic)
    if n_chunk != len(st.chunks) or (v.full and (n_schema, n_channel) != (len(st.schemas), len(st.channels))):
        v.add(f"summary statistics list {n_chunk} chunks / {n_schema} schemas / {n_channel} channels, the "
              f"data section has {len(st.chunks)} / {len(st.schemas)} / {len(st.channels)}", off)
    if total and v.full and (t0, t1) != (st.start, st.end):
        v.add(f"summary statistics log times {t0}..{t1} ns differ from the data {st.start}..{st.end}", off)


def _chunk_index(v: Verification, b: _Body, off: int, chunk_at: dict[int, _Chunk], seen: set[int],
                 st: _State) -> None:
    t0, t1, coff, clen = b.u("Q"), b.u("Q"), b.u("Q"), b.u("Q")
    n = b.u("I")
    offsets: dict[int, int] = {}
    end = b.pos + n
    while b.pos < end:
        cid = b.u("H")
        offsets[cid] = b.u("Q")
    ilen = b.u("Q")
    comp = b.string()
    csize, usize = b.u("Q"), b.u("Q")
    chunk = chunk_at.get(coff)
    if chunk is None:
        v.add(f"chunk index points to byte {coff}, where no chunk starts", off)
        return
    seen.add(coff)
    topic = _topics_of(st, offsets)
    actual = (chunk.length, chunk.start, chunk.end, chunk.compression, chunk.compressed_size,
              chunk.uncompressed_size)
    if (clen, t0, t1, comp, csize, usize) != actual:
        v.add(f"chunk index disagrees with the chunk at byte {coff}", off, topic)
    if offsets != chunk.index_offsets:
        v.add(f"chunk index's message index offsets disagree with the file (chunk at byte {coff})",
              off, topic)
    elif offsets and ilen != chunk.index_end - (coff + clen):
        v.add(f"chunk index's message index length disagrees with the file (chunk at byte {coff})",
              off, topic)


def _check_metadata(v: Verification, meta: dict[str, object]) -> None:
    assert v.mcap is not None
    try:
        files = list(meta.get("relative_file_paths") or [])  # type: ignore[call-overload]
        listed = {
            str(t["topic_metadata"]["name"]): int(t["message_count"])
            for t in meta.get("topics_with_message_count") or []  # type: ignore[attr-defined]
        }
        total = int(meta.get("message_count", -1))  # type: ignore[call-overload]
    except (KeyError, TypeError, ValueError) as exc:
        v.add(f"metadata.yaml is malformed ({exc})")
        return
    if files != [v.mcap.name]:
        v.add(f"metadata.yaml lists files {files}, the bag has {v.mcap.name!r}")
    if not v.full and not v.finalized and v.structural:
        return  # counts of a broken file are not comparable
    for topic in sorted(set(listed) | set(v.counts)):
        if listed.get(topic, 0) != v.counts.get(topic, 0):
            v.add(f"metadata.yaml counts {listed.get(topic, 0)} messages, the file holds "
                  f"{v.counts.get(topic, 0)}", topic=topic)
    if total != sum(listed.values()):
        v.add(f"metadata.yaml message_count {total} is not the sum of its topics ({sum(listed.values())})")


# ----------------------------------------------------------------------------- continuity


def _sample_period_s(meta: dict[str, object] | None) -> float | None:
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
        raise _BadError("payload too short or unknown CDR encapsulation")
    e = "<" if data[1] == 1 else ">"
    sec, nsec, n = struct.unpack_from(e + "iII", data, 4)
    return e, sec * 1_000_000_000 + nsec, 16 + n


def _align(pos: int, a: int) -> int:
    return 4 + -(-(pos - 4) // a) * a


def _declares(st: _State, cid: int) -> bool:
    """The channel's schema is a RigStateBlock with the `skipped` field (cached per channel)."""
    if cid not in st.declares:
        ch = st.channels.get(cid)
        schema = st.schemas.get(ch[0], ("?", "", b"")) if ch is not None else ("?", "", b"")
        st.declares[cid] = schema[0] == "lubrig_interfaces/msg/RigStateBlock" and b"skipped" in schema[2]
    return st.declares[cid]


def _skipped_of(data: bytes) -> int:
    """RigStateBlock.skipped of a whole payload (0 when unreadable)."""
    try:
        _e, _stamp, pos = _cdr_header(data)
    except (_BadError, struct.error):
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


def _continuity(v: Verification, st: _State, meta: dict[str, object] | None) -> None:
    period = _sample_period_s(meta)
    for cid, (sid, topic, _enc, _m) in sorted(st.channels.items()):
        msgtype = st.schemas.get(sid, ("?", "", b""))[0]
        items = st.samples.get(cid, [])
        rep = StreamReport(topic, msgtype, len(items))
        v.streams[topic] = rep
        if msgtype in INDEXED_TYPES:
            skips = {i: n for (c, i), n in st.skipped.items() if c == cid}
            _by_index(v, rep, INDEXED_TYPES[msgtype], items, skips)
        elif msgtype in SPACED_TYPES and _per_sample(topic):
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


def _by_index(v: Verification, rep: StreamReport, kind: str, items: list[tuple[int, int, bytes]],
              skips: dict[int, int] | None = None) -> None:
    """Continuity from the indices; `skips`: position in items -> samples the plant declared skipped."""
    rep.method = "by " + ("sample_index" if kind == "sample" else "first_sample_index")
    segment: int | None = None
    expected, last_stamp = 0, -1
    skips = skips or {}
    for position, (off, _t, data) in enumerate(items):
        skipped = skips.get(position, 0)
        try:
            seg, first, n, stamp, _period = _indexed(kind, data)
        except (_BadError, struct.error):
            v.add("message does not decode (sample index unreadable)", off, rep.topic, CONTINUITY)
            continue
        rep.samples += n
        t_s = stamp / 1e9
        if segment is None or seg != segment:
            if segment is not None and seg < segment:
                _note(v, rep, "backwards", off, t_s,
                      f"segment goes back from {segment} to {seg} at {t_s:.6f} s")
            elif segment is not None and first != 0:
                rep.missing += first
                _note(v, rep, "gap", off, t_s, f"segment {seg} starts at sample {first}: {first} samples "
                      f"missing before rig time {t_s:.6f} s")
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
            _note(v, rep, "gap", off, t_s, f"gap: {missing} samples missing before rig time "
                  f"{t_s:.6f} s (sample {first}, expected {expected})")
        elif first < expected:
            last = min(expected, first + n) - 1
            _note(v, rep, "duplicate", off, t_s,
                  f"duplicate: samples {first}..{last} recorded twice (rig time {t_s:.6f} s)")
        if stamp < last_stamp:
            _note(v, rep, "backwards", off, t_s, f"stamp goes back to {t_s:.6f} s")
        expected, last_stamp = max(expected, first + n), max(last_stamp, stamp)


def _by_spacing(v: Verification, rep: StreamReport, items: list[tuple[int, int, bytes]],
                period: float | None) -> None:
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
            _note(v, rep, "gap", off, t / 1e9,
                  f"gap: {step - 1} samples missing before log time {t / 1e9:.6f} s")
        elif step == 0:
            _note(v, rep, "duplicate", off, t / 1e9, f"duplicate log time {t / 1e9:.6f} s")
        elif step < 0:
            _note(v, rep, "backwards", off, t / 1e9, f"log time goes back to {t / 1e9:.6f} s")
        prev = max(prev, k)
