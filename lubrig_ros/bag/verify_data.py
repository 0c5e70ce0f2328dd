"""The verifier's walk of an MCAP file's header and data section (records, chunks, message indexes).

Fills a :class:`ScanState` (schemas, channels, counts, chunks, the payloads the continuity check
needs) and adds every problem to the Verification; the summary section is verify_summary's.
"""

from __future__ import annotations

import mmap
import struct
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field

from lubrig_ros.bag.continuity import declares_skip, skipped_of
from lubrig_ros.bag.findings import Problem, Verification
from lubrig_ros.bag.frames import (
    FRAME_BYTES,
    MAGIC,
    MESSAGE_HEADER_BYTES,
    OP_ATTACHMENT_INDEX,
    OP_CHANNEL,
    OP_CHUNK,
    OP_CHUNK_INDEX,
    OP_DATA_END,
    OP_FOOTER,
    OP_HEADER,
    OP_MESSAGE,
    OP_MESSAGE_INDEX,
    OP_METADATA,
    OP_METADATA_INDEX,
    OP_SCHEMA,
    OP_STATISTICS,
    OP_SUMMARY_OFFSET,
    Body,
    Channel,
    RecordError,
    Schema,
    chunk_header,
    chunk_records,
    frames,
    message_header,
    parse_channel,
    parse_metadata,
    parse_schema,
)

#: Bytes of a payload kept for the continuity check: the header, indices, the first array's length.
SAMPLE_PREFIX = 512


@dataclass
class Chunk:
    """A chunk record of the data section as the walk found it."""

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
class ScanState:
    """What the walk of one file collected."""

    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    counts: dict[int, int] = field(default_factory=dict)
    index_counts: dict[int, int] = field(default_factory=dict)
    chunks: list[Chunk] = field(default_factory=list)
    metadata: dict[int, str] = field(default_factory=dict)  # offset -> metadata record name
    #: the "rosbag2" metadata record (serialized_metadata and the rest), if the data section has one
    rosbag2_record: dict[str, str] | None = None
    samples: dict[int, list[tuple[int, int, bytes]]] = field(default_factory=dict)  # cid -> (off, t, data)
    start: int = 2**63 - 1
    end: int = 0
    zero_crc: int = 0
    keep_samples: bool = True  # payloads kept for the continuity check
    #: channel id -> its schema has RigStateBlock.skipped (read at scan time: it follows the arrays)
    declares: dict[int, bool] = field(default_factory=dict)
    #: (channel id, position in samples[cid]) -> RigStateBlock.skipped when not 0
    skipped: dict[tuple[int, int], int] = field(default_factory=dict)
    #: the topics whose messages the walk keeps whole (None: none), for a reader that reads the
    #: file once (lubrig_ros.bag.reader.Bag)
    keep: Callable[[str], bool] | None = None
    #: channel id -> keep(its topic), decided at its first message
    keeps: dict[int, bool] = field(default_factory=dict)
    #: (log time, channel id, payload) of every kept message, in file order
    messages: list[tuple[int, int, bytes]] = field(default_factory=list)

    def keep_message(self, cid: int, t: int, payload: bytes | memoryview) -> None:
        """Keep a message's payload if its topic is one the caller reads (keep, not None)."""
        assert self.keep is not None
        if cid not in self.keeps:
            topic = self.topic(cid)
            self.keeps[cid] = topic is not None and self.keep(topic)
        if self.keeps[cid]:
            self.messages.append((t, cid, bytes(payload)))

    def topics_of(self, cids: object) -> str | None:
        """The topics of channel ids cids, comma-separated (None if none is known)."""
        names = sorted({self.channels[c].topic for c in cids if c in self.channels})  # type: ignore[attr-defined]
        return ", ".join(names) if names else None

    def topic(self, cid: int) -> str | None:
        """The topic of channel cid, None if it is not defined."""
        ch = self.channels.get(cid)
        return ch.topic if ch is not None else None

    def msgtype(self, cid: int) -> str:
        """The schema name of channel cid ("?" if unknown)."""
        ch = self.channels.get(cid)
        schema = self.schemas.get(ch.schema_id) if ch is not None else None
        return schema.name if schema is not None else "?"


def walk(v: Verification, buf: mmap.mmap, size: int, st: ScanState, full: bool) -> int | None:
    """Check the magic, the header and the data section; the offset after DataEnd (None: not reached)."""
    if size < len(MAGIC) or buf[: len(MAGIC)] != MAGIC:
        v.add("file does not start with the MCAP magic", 0)
        return None
    head = len(MAGIC)
    if size < head + FRAME_BYTES or buf[head] != OP_HEADER:
        v.add("no header record after the magic", head)
        return None
    try:
        (n,) = struct.unpack_from("<Q", buf, head + 1)
        b = Body(buf, head + FRAME_BYTES, min(head + FRAME_BYTES + n, size))
        profile, _library = b.string(), b.string()
    except (RecordError, struct.error) as exc:
        v.add(f"header record is unreadable: {exc}", head)
        return None
    if profile != "ros2":
        v.add(f"header profile is {profile!r}, expected 'ros2'", head)
    data_end = _walk_data(v, buf, size, head + FRAME_BYTES + n, st, full)
    v.chunks = len(st.chunks)
    topics = {c.offset: st.topics_of(c.index_offsets) for c in st.chunks}
    v.problems = [  # a damaged chunk is named by the topics its message index lists
        Problem(p.text, p.offset, topics[p.offset], p.kind) if p.topic is None and p.offset in topics else p
        for p in v.problems
    ]
    if st.zero_crc:
        v.notes.append(
            f"{st.zero_crc} chunk(s) carry no CRC (an earlier writer's bag): damage inside them "
            "cannot be detected"
        )
    return data_end


def _walk_data(v: Verification, buf: mmap.mmap, size: int, pos: int, st: ScanState, full: bool) -> int | None:
    """Walk the data section from pos; the offset after DataEnd, or None if it was not reached."""
    last_chunk: Chunk | None = None
    try:
        for off, op, b0, b1 in frames(buf, pos, size):
            if op == OP_FOOTER:
                v.add("footer reached without a DataEnd record", off)
                return None
            try:
                if op == OP_DATA_END:
                    (crc,) = struct.unpack_from("<I", buf, b0)
                    if full and crc and zlib.crc32(buf[:off]) != crc:
                        v.add("data section CRC mismatch (DataEnd record)", off)
                    return b1
                if op == OP_CHUNK:
                    if last_chunk is not None:
                        last_chunk.messages = {}  # compared with its message index already
                    last_chunk = _chunk(v, buf, off, b0, b1, st, full)
                elif op == OP_MESSAGE_INDEX:
                    _message_index(v, buf, off, b0, b1, st, last_chunk, full)
                else:
                    _outer_record(v, Body(buf, b0, b1), op, off, st)
            except (RecordError, struct.error) as exc:
                v.add(f"record (opcode 0x{op:02x}) is unreadable: {exc}", off)
    except RecordError as exc:
        v.add(f"data section broken: {exc} (truncated or overwritten?)", offset_of(str(exc)))
        return None
    v.add(f"file ends at byte {size} without DataEnd, summary and footer (not finalized or truncated)", size)
    return None


def _outer_record(v: Verification, b: Body, op: int, off: int, st: ScanState) -> None:
    """A record of the data section outside any chunk."""
    if op == OP_SCHEMA:
        schema = parse_schema(b)
        st.schemas.setdefault(schema.id, schema)
    elif op == OP_CHANNEL:
        ch = parse_channel(b)
        st.channels.setdefault(ch.id, ch)
    elif op == OP_MESSAGE:
        cid, _seq, t, _pub = message_header(b)
        if cid not in st.channels:
            v.add(f"message on undefined channel {cid}", off)
        if st.keep is not None:
            st.keep_message(cid, t, b.buf[b.pos : b.end])
        st.counts[cid] = st.counts.get(cid, 0) + 1
        st.index_counts[cid] = st.index_counts.get(cid, 0) + 1
        st.start, st.end = min(st.start, t), max(st.end, t)
    elif op == OP_METADATA:
        record = parse_metadata(b)
        st.metadata[off] = record.name
        if record.name == "rosbag2":
            st.rosbag2_record = record.metadata
    elif op in (OP_CHUNK_INDEX, OP_STATISTICS, OP_SUMMARY_OFFSET, OP_ATTACHMENT_INDEX, OP_METADATA_INDEX):
        v.add(f"summary record (opcode 0x{op:02x}) inside the data section", off)


def offset_of(text: str) -> int | None:
    """The N of the first `byte N` in text."""
    words = text.replace(")", " ").replace(",", " ").split()
    for i, w in enumerate(words[:-1]):
        if w == "byte" and words[i + 1].isdigit():
            return int(words[i + 1])
    return None


def _chunk(v: Verification, buf: mmap.mmap, off: int, b0: int, b1: int, st: ScanState, full: bool) -> Chunk:
    b = Body(buf, b0, b1)
    start, end, usize, crc = b.u("Q"), b.u("Q"), b.u("Q"), b.u("I")
    comp = b.string()
    csize = b.u("Q")
    chunk = Chunk(off, b1 - off, start, end, comp, csize, usize)
    st.chunks.append(chunk)
    try:
        header = chunk_header(buf, b0, b1)
        if not full:
            return chunk
        raw = chunk_records(buf, header)
    except RecordError as exc:
        v.add(str(exc), off)
        return chunk
    if crc == 0:
        st.zero_crc += 1
    times: list[int] = []
    try:
        for roff, op, r0, r1 in frames(raw, 0, len(raw)):
            _inner_record(v, raw, roff, op, r0, r1, off, st, chunk, times)
    except (RecordError, struct.error) as exc:
        v.add(f"chunk records are unreadable: {exc}", off)
        return chunk
    chunk.decoded = True
    if times:
        st.start, st.end = min(st.start, min(times)), max(st.end, max(times))
        if min(times) != start or max(times) != end:
            topic = st.topics_of(chunk.messages)
            v.add(f"chunk declares log times {start}..{end} ns, holds {min(times)}..{max(times)}", off, topic)
    return chunk


def _inner_record(
    v: Verification,
    raw: bytes,
    roff: int,
    op: int,
    r0: int,
    r1: int,
    off: int,
    st: ScanState,
    chunk: Chunk,
    times: list[int],
) -> None:
    """One record inside the chunk at byte off."""
    rb = Body(raw, r0, r1)
    if op == OP_SCHEMA:
        schema = parse_schema(rb)
        st.schemas.setdefault(schema.id, schema)
    elif op == OP_CHANNEL:
        ch = parse_channel(rb)
        if ch.schema_id not in st.schemas and ch.schema_id != 0:
            v.add(f"channel {ch.id} ({ch.topic}) refers to undefined schema {ch.schema_id}", off, ch.topic)
        st.channels.setdefault(ch.id, ch)
    elif op == OP_MESSAGE:
        cid, _seq, t, _pub = message_header(rb)
        if cid not in st.channels:
            v.add(f"message on undefined channel {cid} inside the chunk", off)
        chunk.messages.setdefault(cid, set()).add((t, roff))
        st.counts[cid] = st.counts.get(cid, 0) + 1
        if st.keep is not None:
            st.keep_message(cid, t, raw[r0 + MESSAGE_HEADER_BYTES : r1])
        if st.keep_samples:
            # the leading fields are enough (header, indices, the first array's length);
            # a block's declared skip comes after its arrays: read now
            p0 = r0 + MESSAGE_HEADER_BYTES
            kept = st.samples.setdefault(cid, [])
            kept.append((off, t, raw[p0 : min(r1, p0 + SAMPLE_PREFIX)]))
            if cid not in st.declares:
                own = st.channels.get(cid)
                st.declares[cid] = declares_skip(st.schemas.get(own.schema_id) if own else None)
            if st.declares[cid]:
                skipped = skipped_of(raw[p0:r1])
                if skipped:
                    st.skipped[(cid, len(kept) - 1)] = skipped
        times.append(t)
    else:
        v.add(f"record opcode 0x{op:02x} is not allowed inside a chunk", off)


def _message_index(
    v: Verification,
    buf: mmap.mmap,
    off: int,
    b0: int,
    b1: int,
    st: ScanState,
    chunk: Chunk | None,
    full: bool,
) -> None:
    b = Body(buf, b0, b1)
    cid = b.u("H")
    n = b.u("I")
    if n % 16 or b.pos + n != b1:
        raise RecordError("message index length is not a multiple of 16 or disagrees with the record")
    entries = {struct.unpack_from("<QQ", buf, b.pos + 16 * k) for k in range(n // 16)}
    st.index_counts[cid] = st.index_counts.get(cid, 0) + len(entries)
    topic = st.topic(cid)
    if chunk is None:
        v.add("message index without a chunk before it", off, topic)
        return
    chunk.index_offsets[cid] = off
    chunk.index_end = b1
    if full and chunk.decoded and entries != chunk.messages.get(cid, set()):
        v.add(f"message index disagrees with the chunk at byte {chunk.offset}", off, topic)
