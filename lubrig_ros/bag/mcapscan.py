"""Sequential scanner of an MCAP file's records that survives truncation and damaged chunks.

The scanner never trusts the summary section: it walks the data section record by record,
decompresses each chunk and checks its size and CRC, and reports where and why it stopped.
"""

from __future__ import annotations

import struct
from binascii import crc32
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

from backports import zstd

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
OP_DATA_END = 0x0F
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
class ScanResult:
    """Outcome of a scan: how the data section ended and what was skipped."""

    complete: bool = False  # reached DataEnd / Footer with no damage
    stop_reason: str = ""  # why the scan stopped early ("" if complete)
    damaged_chunks: list[str] = field(default_factory=list)
    chunks: int = 0


def _string(buf: bytes, pos: int) -> tuple[str, int]:
    (n,) = struct.unpack_from("<I", buf, pos)
    return buf[pos + 4 : pos + 4 + n].decode(), pos + 4 + n


def _parse(op: int, body: bytes) -> Schema | Channel | Message | None:
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
        (n,) = struct.unpack_from("<I", body, p)
        p += 4
        end = p + n
        meta: dict[str, str] = {}
        while p < end:
            key, p = _string(body, p)
            meta[key], p = _string(body, p)
        return Channel(cid, sid, topic, enc, meta)
    if op == OP_MESSAGE:
        cid, seq, log_time, pub_time = struct.unpack_from("<HIQQ", body, 0)
        return Message(cid, seq, log_time, pub_time, body[22:])
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
        raise ValueError("chunk CRC mismatch")
    return raw


def _iter_inner(raw: bytes) -> Iterator[tuple[int, bytes]]:
    pos = 0
    while pos < len(raw):
        op = raw[pos]
        (n,) = struct.unpack_from("<Q", raw, pos + 1)
        yield op, raw[pos + 9 : pos + 9 + n]
        pos += 9 + n


def scan(path: str | Path, result: ScanResult) -> Iterator[Schema | Channel | Message]:
    """Yield schema, channel and message records of the data section in file order.

    Damaged chunks whose record frame is intact are skipped (listed in result.damaged_chunks);
    the scan stops at the first truncated or unreadable record frame (result.stop_reason).
    """
    with open(path, "rb") as f:
        yield from _scan_file(f, result)


def _scan_file(f: BinaryIO, result: ScanResult) -> Iterator[Schema | Channel | Message]:
    if f.read(8) != MAGIC:
        result.stop_reason = "file does not start with the MCAP magic"
        return
    while True:
        offset = f.tell()
        head = f.read(9)
        if not head:
            result.stop_reason = f"file ends at byte {offset} without a summary (not finalized)"
            return
        if len(head) < 9:
            result.stop_reason = f"record header truncated at byte {offset}"
            return
        op = head[0]
        (n,) = struct.unpack_from("<Q", head, 1)
        if op not in _VALID_OPS or n > 1 << 40:
            result.stop_reason = f"invalid record (opcode 0x{op:02x}) at byte {offset}"
            return
        body = f.read(n)
        if len(body) < n:
            result.stop_reason = f"record at byte {offset} truncated ({len(body)} of {n} bytes)"
            return
        if op in (OP_DATA_END, OP_FOOTER):
            result.complete = not result.damaged_chunks
            if result.damaged_chunks:
                result.stop_reason = f"{len(result.damaged_chunks)} damaged chunk(s)"
            return
        if op == OP_CHUNK:
            try:
                raw = _chunk_records(body)
                records = [_parse(o, b) for o, b in _iter_inner(raw)]
            except (ValueError, struct.error, zstd.ZstdError, UnicodeDecodeError) as exc:
                result.damaged_chunks.append(f"chunk at byte {offset}: {exc}")
                continue
            result.chunks += 1
            for rec in records:
                if rec is not None:
                    yield rec
            continue
        try:
            rec = _parse(op, body)
        except (struct.error, UnicodeDecodeError) as exc:
            result.stop_reason = f"record at byte {offset} is unreadable: {exc}"
            return
        if rec is not None:
            yield rec
