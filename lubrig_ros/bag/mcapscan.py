"""Sequential scanner of an MCAP file's records that survives truncation and damaged chunks.

The scanner never trusts the summary section: it walks the data section record by record,
decompresses each chunk and checks its size and CRC, and reports where and why it stopped.
After a broken record frame (a damaged length, a truncation) it looks for the next chunk record
further on (the "zstd" compression field at its fixed place) and goes on from there if that
chunk verifies (a CRC-32 that matches), so damage in the middle costs only what it hit.
"""

from __future__ import annotations

import mmap
import struct
from binascii import crc32
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from backports import zstd

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
OP_MESSAGE_INDEX, OP_METADATA, OP_DATA_END = 0x07, 0x0C, 0x0F
_VALID_OPS = set(range(0x01, 0x10))


@dataclass
class Schema:
    """An MCAP schema record."""

    id: int
    name: str
    encoding: str
    data: bytes


@dataclass
class Channel:
    """An MCAP channel record."""

    id: int
    schema_id: int
    topic: str
    message_encoding: str
    metadata: dict[str, str]


@dataclass
class Message:
    """An MCAP message record."""

    channel_id: int
    sequence: int
    log_time: int
    publish_time: int
    data: bytes


@dataclass
class Metadata:
    """An MCAP metadata record (the writer's "rosbag2" record: serialized_metadata)."""

    name: str
    metadata: dict[str, str]


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


def _string(buf: bytes, pos: int) -> tuple[str, int]:
    (n,) = struct.unpack_from("<I", buf, pos)
    return buf[pos + 4 : pos + 4 + n].decode(), pos + 4 + n


def _string_map(body: bytes, pos: int) -> tuple[dict[str, str], int]:
    (n,) = struct.unpack_from("<I", body, pos)
    pos += 4
    end = pos + n
    out: dict[str, str] = {}
    while pos < end:
        key, pos = _string(body, pos)
        out[key], pos = _string(body, pos)
    return out, pos


def _parse(op: int, body: bytes) -> Schema | Channel | Message | Metadata | None:
    if op == OP_SCHEMA:
        (sid,) = struct.unpack_from("<H", body, 0)
        name, p = _string(body, 2)
        enc, p = _string(body, p)
        (n,) = struct.unpack_from("<I", body, p)
        return Schema(sid, name, enc, body[p + 4 : p + 4 + n])
    if op == OP_CHANNEL:
        cid, sid = struct.unpack_from("<HH", body, 0)
        topic, p = _string(body, 4)
        enc, p = _string(body, p)
        meta, p = _string_map(body, p)
        return Channel(cid, sid, topic, enc, meta)
    if op == OP_MESSAGE:
        cid, seq, log_time, pub_time = struct.unpack_from("<HIQQ", body, 0)
        return Message(cid, seq, log_time, pub_time, body[22:])
    if op == OP_METADATA:  # informative only: a damaged one is passed over, never a stop
        try:
            name, p = _string(body, 0)
            return Metadata(name, _string_map(body, p)[0])
        except (struct.error, UnicodeDecodeError):
            return None
    return None


def _chunk_records(body: bytes) -> bytes:
    _start, _end, size, crc = struct.unpack_from("<QQQI", body, 0)
    comp, p = _string(body, 28)
    (n,) = struct.unpack_from("<Q", body, p)
    data = body[p + 8 : p + 8 + n]
    if len(data) != n:
        raise ValueError("chunk payload is truncated")
    if comp == "zstd":
        raw = zstd.decompress(data)
    elif comp == "":
        raw = data
    else:
        raise ValueError(f"unsupported chunk compression {comp!r}")
    if len(raw) != size:
        raise ValueError(f"chunk size {len(raw)} differs from the recorded {size}")
    if crc and crc32(raw) != crc:
        raise ValueError(f"chunk CRC mismatch (stored 0x{crc:08x}, computed 0x{crc32(raw):08x})")
    return raw


def _iter_inner(raw: bytes) -> Iterator[tuple[int, bytes]]:
    pos = 0
    while pos < len(raw):
        op = raw[pos]
        (n,) = struct.unpack_from("<Q", raw, pos + 1)
        yield op, raw[pos + 9 : pos + 9 + n]
        pos += 9 + n


_CHUNK_COMPRESSION_AT = 1 + 8 + 8 + 8 + 8 + 4  # op, length, start, end, size, crc
_ZSTD_FIELD = b"\x04\x00\x00\x00zstd"


def _next_chunk(buf: mmap.mmap | bytes, after: int, size: int) -> int | None:
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
        (n,) = struct.unpack_from("<Q", buf, start + 1)
        if start + 9 + n > size:
            continue
        body = bytes(buf[start + 9 : start + 9 + n])
        (crc,) = struct.unpack_from("<I", body, 24)
        if not crc:
            continue  # without a CRC a false match cannot be told apart
        try:
            _chunk_records(body)
        except (ValueError, struct.error, zstd.ZstdError, UnicodeDecodeError):
            continue
        return start


def scan(path: str | Path, result: ScanResult) -> Iterator[Schema | Channel | Message | Metadata]:
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


def _scan_buffer(
    buf: mmap.mmap, size: int, result: ScanResult
) -> Iterator[Schema | Channel | Message | Metadata]:
    if buf[:8] != MAGIC:
        result.stop_reason = "file does not start with the MCAP magic"
        return
    offset = 8
    last_damage: Damage | None = None
    while True:
        problem = ""
        if offset >= size:
            result.stop_reason = f"file ends at byte {offset} without a summary (not finalized)"
            return
        if offset + 9 > size:
            problem = f"record header truncated at byte {offset}"
        else:
            op = buf[offset]
            (n,) = struct.unpack_from("<Q", buf, offset + 1)
            if op not in _VALID_OPS or n > 1 << 40:
                problem = f"invalid record (opcode 0x{op:02x}) at byte {offset}"
            elif offset + 9 + n > size:
                problem = f"record at byte {offset} truncated ({size - offset - 9} of {n} bytes)"
        if problem:
            resume = _next_chunk(buf, offset, size)
            if resume is None:
                result.stop_reason = problem
                result.damage.append(Damage(offset, problem))
                return
            result.resyncs += 1
            result.damaged_chunks.append(f"data at bytes {offset}..{resume}: {problem}")
            result.damage.append(Damage(offset, problem, resume))
            last_damage, offset = None, resume
            continue
        body = bytes(buf[offset + 9 : offset + 9 + n])
        start, offset = offset, offset + 9 + n
        if op in (OP_DATA_END, OP_FOOTER):
            result.complete = not result.damaged_chunks
            if result.damaged_chunks:
                result.stop_reason = f"{len(result.damaged_chunks)} damaged part(s) of the data section"
            return
        if op == OP_MESSAGE_INDEX:
            if last_damage is not None and len(body) >= 6:
                (cid,) = struct.unpack_from("<H", body, 0)
                (length,) = struct.unpack_from("<I", body, 2)
                last_damage.dropped[cid] = last_damage.dropped.get(cid, 0) + length // 16
            continue
        last_damage = None
        if op == OP_CHUNK:
            try:
                raw = _chunk_records(body)
                records = [_parse(o, b) for o, b in _iter_inner(raw)]
            except (ValueError, struct.error, zstd.ZstdError, UnicodeDecodeError) as exc:
                result.damaged_chunks.append(f"chunk at byte {start}: {exc}")
                reason = str(exc) if str(exc).startswith("chunk") else f"chunk: {exc}"
                last_damage = Damage(start, reason, offset)
                result.damage.append(last_damage)
                continue
            result.chunks += 1
            for rec in records:
                if rec is not None:
                    yield rec
            continue
        try:
            rec = _parse(op, body)
        except (struct.error, UnicodeDecodeError) as exc:
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
    footer = len(data) - 8 - 29
    if footer < 8 or data[-8:] != MAGIC or data[footer] != OP_FOOTER:
        return schemas, channels
    start, _offsets, crc = struct.unpack_from("<QQI", data, footer + 9)
    if not crc or not 8 <= start < footer or crc32(data[start : footer + 25]) != crc:
        return schemas, channels
    pos = start
    try:
        while pos + 9 <= footer:
            op = data[pos]
            (n,) = struct.unpack_from("<Q", data, pos + 1)
            body = data[pos + 9 : pos + 9 + n]
            pos += 9 + n
            if op in (OP_SCHEMA, OP_CHANNEL):
                rec = _parse(op, body)
                if isinstance(rec, Schema):
                    schemas[rec.id] = rec
                elif isinstance(rec, Channel):
                    channels[rec.id] = rec
    except (struct.error, UnicodeDecodeError):
        return {}, {}
    return schemas, channels
