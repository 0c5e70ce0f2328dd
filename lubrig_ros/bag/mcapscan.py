"""Sequential scanner of an MCAP file's records that survives truncation and damaged chunks.

The scanner never trusts the summary section: it walks the data section record by record
(the framing of lubrig_ros.bag.frames), decompresses each chunk and checks its size and CRC,
and reports where and why it stopped. After a broken record frame (a damaged length, a
truncation) it looks for the next chunk record further on (the "zstd" compression field at its
fixed place) and goes on from there if that chunk verifies (a CRC-32 that matches), so damage
in the middle costs only what it hit.
"""

from __future__ import annotations

import mmap
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from lubrig_ros.bag.frames import (
    FOOTER_BYTES,
    FRAME_BYTES,
    MAGIC,
    OP_CHANNEL,
    OP_CHUNK,
    OP_DATA_END,
    OP_FOOTER,
    OP_MESSAGE_INDEX,
    OP_METADATA,
    OP_SCHEMA,
    Body,
    Buffer,
    Channel,
    Message,
    Metadata,
    RecordError,
    Schema,
    chunk_header,
    chunk_records,
    footer_fields,
    frame_at,
    frames,
    parse_record,
)

__all__ = ["Channel", "Damage", "Message", "Metadata", "ScanResult", "Schema", "scan", "summary_definitions"]

Record = Schema | Channel | Message | Metadata


@dataclass
class Damage:
    """A part of the data section whose messages were not kept."""

    offset: int
    reason: str
    end: int | None = None  # where the scan went on (None: it stopped there)
    dropped: dict[int, int] = field(default_factory=dict)  # channel id -> messages (message index)

    def line(self, topics: dict[int, str] | None = None) -> str:
        """One line naming the place, the reason and the messages lost (if known)."""
        text = f"bytes {self.offset}..{self.end}" if self.end is not None else f"from byte {self.offset}"
        text += f": {self.reason}"
        if self.dropped:
            names = topics or {}
            text += "; dropped " + ", ".join(
                f"{names.get(c, f'channel {c}')}={n}" for c, n in sorted(self.dropped.items())
            )
        return text


@dataclass
class ScanResult:
    """Outcome of a scan: how the data section ended and what was skipped."""

    complete: bool = False  # reached DataEnd / Footer with no damage
    stop_reason: str = ""  # why the scan stopped early ("" if complete)
    damaged_chunks: list[str] = field(default_factory=list)
    chunks: int = 0
    damage: list[Damage] = field(default_factory=list)
    resyncs: int = 0


def _chunk_contents(buf: Buffer, b0: int, b1: int) -> list[Record]:
    """The records of the chunk whose body is buf[b0:b1]; RecordError if it does not verify."""
    raw = chunk_records(buf, chunk_header(buf, b0, b1))
    out: list[Record] = []
    for _off, op, r0, r1 in frames(raw, 0, len(raw)):
        try:
            rec = parse_record(op, Body(raw, r0, r1))
        except RecordError:
            if op != OP_METADATA:
                raise
            continue  # informative only: a damaged metadata record is passed over
        if rec is not None:
            out.append(rec)
    return out


_CHUNK_COMPRESSION_AT = FRAME_BYTES + 8 + 8 + 8 + 4  # op, length, start, end, size, crc
_ZSTD_FIELD = b"\x04\x00\x00\x00zstd"


def _next_chunk(buf: bytes | mmap.mmap, after: int, size: int) -> int | None:
    """Offset of the next chunk record after byte `after` that decompresses and has a matching CRC."""
    pos = after
    while True:
        idx = buf.find(_ZSTD_FIELD, pos)
        if idx < 0:
            return None
        start = idx - _CHUNK_COMPRESSION_AT
        pos = idx + 1
        if start <= after or buf[start] != OP_CHUNK:
            continue
        try:
            _op, n = frame_at(buf, start, size)
            if not struct.unpack_from("<I", buf, start + FRAME_BYTES + 24)[0]:
                continue  # without a CRC a false match cannot be told apart
            _chunk_contents(buf, start + FRAME_BYTES, start + FRAME_BYTES + n)
        except RecordError:
            continue
        return start


def scan(path: str | Path, result: ScanResult) -> Iterator[Record]:
    """Yield schema, channel, message and metadata records of the data section in file order.

    Damaged chunks whose record frame is intact are skipped (listed in result.damaged_chunks and
    result.damage, with the messages their message index lists); at a broken record frame the
    scan goes on at the next chunk that verifies, or stops (result.stop_reason).
    """
    with open(path, "rb") as f:
        size = f.seek(0, 2)
        if size == 0:
            result.stop_reason = "file is empty"
            return
        with mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as buf:
            yield from _scan_buffer(buf, size, result)


def _scan_buffer(buf: mmap.mmap, size: int, result: ScanResult) -> Iterator[Record]:
    if buf[: len(MAGIC)] != MAGIC:
        result.stop_reason = "file does not start with the MCAP magic"
        return
    offset = len(MAGIC)
    last_damage: Damage | None = None
    while True:
        if offset >= size:
            result.stop_reason = f"file ends at byte {offset} without a summary (not finalized)"
            return
        try:
            op, n = frame_at(buf, offset, size)
        except RecordError as exc:
            resume = _next_chunk(buf, offset, size)
            if resume is None:
                result.stop_reason = str(exc)
                result.damage.append(Damage(offset, str(exc)))
                return
            result.resyncs += 1
            result.damaged_chunks.append(f"data at bytes {offset}..{resume}: {exc}")
            result.damage.append(Damage(offset, str(exc), resume))
            last_damage, offset = None, resume
            continue
        start, b0, offset = offset, offset + FRAME_BYTES, offset + FRAME_BYTES + n
        if op in (OP_DATA_END, OP_FOOTER):
            result.complete = not result.damaged_chunks
            if result.damaged_chunks:
                result.stop_reason = f"{len(result.damaged_chunks)} damaged part(s) of the data section"
            return
        if op == OP_MESSAGE_INDEX:
            if last_damage is not None and n >= 6:
                cid, length = struct.unpack_from("<HI", buf, b0)
                last_damage.dropped[cid] = last_damage.dropped.get(cid, 0) + length // 16
            continue
        last_damage = None
        if op == OP_CHUNK:
            try:
                records = _chunk_contents(buf, b0, offset)
            except RecordError as exc:
                result.damaged_chunks.append(f"chunk at byte {start}: {exc}")
                reason = str(exc) if str(exc).startswith("chunk") else f"chunk: {exc}"
                last_damage = Damage(start, reason, offset)
                result.damage.append(last_damage)
                continue
            result.chunks += 1
            yield from records
            continue
        try:
            rec = parse_record(op, Body(buf, b0, offset))
        except RecordError as exc:
            if op == OP_METADATA:
                continue  # informative only, as inside a chunk
            result.stop_reason = f"record at byte {start} is unreadable: {exc}"
            result.damage.append(Damage(start, result.stop_reason))
            return
        if rec is not None:
            yield rec


def summary_definitions(path: str | Path) -> tuple[dict[int, Schema], dict[int, Channel]]:
    """Schemas and channels of the file's summary section, if its footer and CRC verify.

    Repair's fallback when the chunk holding the definitions is damaged. Empty dicts otherwise.
    """
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError:
        return schemas, channels
    found = footer_fields(data, len(data))
    footer = len(data) - len(MAGIC) - FOOTER_BYTES
    if found is None:
        return schemas, channels
    start, _offsets, crc = found
    if (
        not crc
        or not len(MAGIC) <= start < footer
        or zlib.crc32(data[start : footer + FRAME_BYTES + 16]) != crc
    ):
        return schemas, channels
    try:
        for _off, op, b0, b1 in frames(data, start, footer):
            if op in (OP_SCHEMA, OP_CHANNEL):
                rec = parse_record(op, Body(data, b0, b1))
                if isinstance(rec, Schema):
                    schemas[rec.id] = rec
                elif isinstance(rec, Channel):
                    channels[rec.id] = rec
    except RecordError:
        return {}, {}
    return schemas, channels
