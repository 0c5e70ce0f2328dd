"""The verifier's check of an MCAP file's footer and summary section against its data section."""

from __future__ import annotations

import mmap
import struct
import zlib

from lubrig_ros.bag.findings import Verification
from lubrig_ros.bag.frames import (
    FOOTER_BYTES,
    FRAME_BYTES,
    MAGIC,
    OP_CHANNEL,
    OP_CHUNK,
    OP_CHUNK_INDEX,
    OP_DATA_END,
    OP_FOOTER,
    OP_HEADER,
    OP_MESSAGE,
    OP_MESSAGE_INDEX,
    OP_METADATA_INDEX,
    OP_SCHEMA,
    OP_STATISTICS,
    OP_SUMMARY_OFFSET,
    Body,
    RecordError,
    frames,
    parse_channel,
    parse_schema,
)
from lubrig_ros.bag.verify_data import Chunk, ScanState, offset_of


def check_summary(v: Verification, buf: mmap.mmap, size: int, data_end: int, st: ScanState) -> None:
    """Footer, summary CRC and every summary record against what the data section holds."""
    footer = size - len(MAGIC) - FOOTER_BYTES
    if footer < data_end:
        v.add("file ends after the data section without a footer (truncated?)", data_end)
        return
    if buf[size - len(MAGIC) : size] != MAGIC:
        v.add("file does not end with the MCAP magic (truncated or damaged footer)", size - len(MAGIC))
        return
    if buf[footer] != OP_FOOTER or struct.unpack_from("<Q", buf, footer + 1)[0] != FOOTER_BYTES - FRAME_BYTES:
        v.add("footer record is damaged", footer)
        return
    summary_start, offset_start, crc = struct.unpack_from("<QQI", buf, footer + FRAME_BYTES)
    if summary_start == 0:
        v.add("the footer points to no summary (no index: readers must scan the file)", footer)
        return
    if summary_start != data_end:
        v.add(f"footer's summary start {summary_start} is not the end of the data section {data_end}", footer)
        return
    if crc == 0:
        v.notes.append("the summary carries no CRC (an earlier writer's bag)")
    elif zlib.crc32(buf[summary_start : footer + FRAME_BYTES + 16]) != crc:
        v.add("summary CRC mismatch (summary or footer damaged)", summary_start)
    if offset_start and not summary_start <= offset_start <= footer:
        v.add(f"footer's summary offset start {offset_start} lies outside the summary", footer)
    seen_index: set[int] = set()
    chunk_at = {c.offset: c for c in st.chunks}
    stats_seen = False
    try:
        for off, op, b0, b1 in frames(buf, summary_start, footer):
            try:
                stats_seen |= _summary_record(
                    v, buf, Body(buf, b0, b1), op, off, st, (chunk_at, seen_index), (summary_start, footer)
                )
            except (RecordError, struct.error) as exc:
                v.add(f"summary record (opcode 0x{op:02x}) is unreadable: {exc}", off)
    except RecordError as exc:
        v.add(f"summary section broken: {exc}", offset_of(str(exc)))
        return
    missing = [c for c in st.chunks if c.offset not in seen_index]
    if missing:
        v.add(
            f"{len(missing)} chunk(s) have no chunk index in the summary",
            missing[0].offset,
            st.topics_of(missing[0].index_offsets),
        )
    if not stats_seen:
        v.add("the summary has no statistics record", summary_start)
    if not v.structural:
        v.finalized = True


def _summary_record(
    v: Verification,
    buf: mmap.mmap,
    b: Body,
    op: int,
    off: int,
    st: ScanState,
    chunks: tuple[dict[int, Chunk], set[int]],
    bounds: tuple[int, int],
) -> bool:
    """Check one summary record; True if it is the statistics record.

    chunks: the data section's chunks by offset and the offsets their chunk indexes named so far.
    """
    if op == OP_SCHEMA:
        schema = parse_schema(b)
        if not v.full or schema.id not in st.schemas:
            # not scanned (the definitions are inside the chunks), or defined in the summary
            # only: the writer puts a definition into the data section with its first
            # message, so a topic without messages (an empty bag) has none
            st.schemas.setdefault(schema.id, schema)
        elif st.schemas[schema.id] != schema:
            v.add(f"summary schema {schema.id} ({schema.name}) differs from the data section", off)
    elif op == OP_CHANNEL:
        ch = parse_channel(b)
        if not v.full or ch.id not in st.channels:  # as for schemas
            st.channels.setdefault(ch.id, ch)
        elif st.channels[ch.id] != ch:
            v.add(f"summary channel {ch.id} differs from the data section", off, ch.topic)
    elif op == OP_STATISTICS:
        _statistics(v, b, off, st)
        return True
    elif op == OP_CHUNK_INDEX:
        _chunk_index(v, b, off, chunks[0], chunks[1], st)
    elif op == OP_METADATA_INDEX:
        moff, _mlen = b.u("Q"), b.u("Q")
        name = b.string()
        if st.metadata.get(moff) != name:
            v.add(f"metadata index points to byte {moff}, no metadata record {name!r} there", off)
    elif op == OP_SUMMARY_OFFSET:
        gop, gstart, glen = b.u("B"), b.u("Q"), b.u("Q")
        inside = bounds[0] <= gstart and gstart + glen <= bounds[1]
        if glen and not (inside and buf[gstart] == gop):
            v.add(f"summary offset for opcode 0x{gop:02x} points to byte {gstart}, no such group", off)
    elif op in (OP_MESSAGE, OP_CHUNK, OP_MESSAGE_INDEX, OP_DATA_END, OP_HEADER):
        v.add(f"record opcode 0x{op:02x} is not allowed in the summary", off)
    return False


def _statistics(v: Verification, b: Body, off: int, st: ScanState) -> None:
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
        v.add(
            f"summary statistics count {total} messages, the data section holds {sum(counts.values())}", off
        )
    for cid, count in sorted(per.items()):
        if counts.get(cid, 0) != count:
            v.add(
                f"summary statistics count {count} messages, the data section holds {counts.get(cid, 0)}",
                off,
                st.topic(cid),
            )
    if n_chunk != len(st.chunks) or (v.full and (n_schema, n_channel) != (len(st.schemas), len(st.channels))):
        v.add(
            f"summary statistics list {n_chunk} chunks / {n_schema} schemas / {n_channel} channels, the "
            f"data section has {len(st.chunks)} / {len(st.schemas)} / {len(st.channels)}",
            off,
        )
    if total and v.full and (t0, t1) != (st.start, st.end):
        v.add(f"summary statistics log times {t0}..{t1} ns differ from the data {st.start}..{st.end}", off)


def _chunk_index(
    v: Verification, b: Body, off: int, chunk_at: dict[int, Chunk], seen: set[int], st: ScanState
) -> None:
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
    topic = st.topics_of(offsets)
    actual = (
        chunk.length,
        chunk.start,
        chunk.end,
        chunk.compression,
        chunk.compressed_size,
        chunk.uncompressed_size,
    )
    if (clen, t0, t1, comp, csize, usize) != actual:
        v.add(f"chunk index disagrees with the chunk at byte {coff}", off, topic)
    if offsets != chunk.index_offsets:
        v.add(
            f"chunk index's message index offsets disagree with the file (chunk at byte {coff})", off, topic
        )
    elif offsets and ilen != chunk.index_end - (coff + clen):
        v.add(
            f"chunk index's message index length disagrees with the file (chunk at byte {coff})", off, topic
        )
