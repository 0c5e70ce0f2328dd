"""MCAP record framing, written once: magic, opcodes, record frames, fields, records, chunks.

An MCAP file is the magic, then records of ``opcode (1 byte) | body length (u64) | body``, and
the magic again. Everything that walks one — the verifier (lubrig_ros.bag.verify), the tolerant
scanner behind repair and the reader (lubrig_ros.bag.mcapscan) — reads records through this
module: a record that does not parse is a :class:`RecordError` with one line saying why, never a
struct.error or an IndexError.
"""

from __future__ import annotations

import mmap
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass

from backports import zstd

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
OP_MESSAGE_INDEX, OP_CHUNK_INDEX, OP_ATTACHMENT, OP_ATTACHMENT_INDEX = 0x07, 0x08, 0x09, 0x0A
OP_STATISTICS, OP_METADATA, OP_METADATA_INDEX, OP_SUMMARY_OFFSET, OP_DATA_END = 0x0B, 0x0C, 0x0D, 0x0E, 0x0F
VALID_OPS = frozenset(range(OP_HEADER, OP_DATA_END + 1))
FRAME_BYTES = 1 + 8  # opcode and body length
FOOTER_BYTES = FRAME_BYTES + 8 + 8 + 4  # footer record; the file ends with it and the magic
MESSAGE_HEADER_BYTES = 2 + 4 + 8 + 8  # channel id, sequence, log time, publish time
#: A body length beyond this is a damaged length field, not a record (no bag holds 1 TiB records).
MAX_RECORD = 1 << 40
Buffer = bytes | memoryview | mmap.mmap


class RecordError(Exception):
    """A record (or its frame) does not parse; the message says where or why, in one line."""


class Body:
    """Little-endian field reader over buf[start:end] (one record body)."""

    def __init__(self, buf: Buffer, start: int = 0, end: int | None = None) -> None:
        self.buf, self.pos = buf, start
        self.end = len(buf) if end is None else end

    def take(self, n: int) -> bytes:
        """The next n bytes."""
        if n < 0 or self.pos + n > self.end:
            raise RecordError(f"field of {n} bytes runs past the record end")
        out = bytes(self.buf[self.pos : self.pos + n])
        self.pos += n
        return out

    def u(self, fmt: str) -> int:
        """The next unsigned integer of struct format fmt (B, H, I, Q)."""
        (value,) = struct.unpack("<" + fmt, self.take(struct.calcsize(fmt)))
        return int(value)

    def string(self) -> str:
        """A u32-prefixed UTF-8 string."""
        n = self.u("I")
        try:
            return self.take(n).decode()
        except UnicodeDecodeError as exc:
            raise RecordError(f"string is not UTF-8 ({exc.reason})") from None

    def data(self, width: str = "I") -> bytes:
        """Length-prefixed bytes (u32 by default)."""
        return self.take(self.u(width))

    def string_map(self) -> dict[str, str]:
        """A u32-byte-length-prefixed map of string to string."""
        n = self.u("I")
        end = self.pos + n
        if end > self.end:
            raise RecordError("map runs past the record end")
        out: dict[str, str] = {}
        while self.pos < end:
            key = self.string()
            out[key] = self.string()
        if self.pos != end:
            raise RecordError("map length disagrees with its entries")
        return out


def frame_at(buf: Buffer, pos: int, end: int) -> tuple[int, int]:
    """(opcode, body length) of the record frame at pos; RecordError naming the byte if it is broken."""
    if pos + FRAME_BYTES > end:
        raise RecordError(f"record header truncated at byte {pos}")
    op = buf[pos]
    (n,) = struct.unpack_from("<Q", buf, pos + 1)
    if op not in VALID_OPS or n > MAX_RECORD:
        raise RecordError(f"invalid record (opcode 0x{op:02x}) at byte {pos}")
    if pos + FRAME_BYTES + n > end:
        raise RecordError(
            f"record (opcode 0x{op:02x}) at byte {pos} runs past the end ({n} bytes, "
            f"{end - pos - FRAME_BYTES} left)"
        )
    return op, n


def frames(buf: Buffer, start: int, end: int) -> Iterator[tuple[int, int, int, int]]:
    """(offset, opcode, body start, body end) of the records of buf[start:end]; RecordError at a bad frame."""
    pos = start
    while pos < end:
        op, n = frame_at(buf, pos, end)
        yield pos, op, pos + FRAME_BYTES, pos + FRAME_BYTES + n
        pos += FRAME_BYTES + n


# ----------------------------------------------------------------------------- records


@dataclass(frozen=True)
class Schema:
    """An MCAP schema record."""

    id: int
    name: str
    encoding: str
    data: bytes


@dataclass(frozen=True)
class Channel:
    """An MCAP channel record."""

    id: int
    schema_id: int
    topic: str
    message_encoding: str
    metadata: dict[str, str]


@dataclass(frozen=True)
class Message:
    """An MCAP message record."""

    channel_id: int
    sequence: int
    log_time: int
    publish_time: int
    data: bytes


@dataclass(frozen=True)
class Metadata:
    """An MCAP metadata record (the writer's "rosbag2" record: serialized_metadata)."""

    name: str
    metadata: dict[str, str]


def parse_schema(b: Body) -> Schema:
    """The schema record of body b."""
    sid = b.u("H")
    name = b.string()
    encoding = b.string()
    return Schema(sid, name, encoding, b.data())


def parse_channel(b: Body) -> Channel:
    """The channel record of body b."""
    cid, sid = b.u("H"), b.u("H")
    topic = b.string()
    encoding = b.string()
    return Channel(cid, sid, topic, encoding, b.string_map())


def message_header(b: Body) -> tuple[int, int, int, int]:
    """(channel id, sequence, log time, publish time) of a message body; b is left at the payload."""
    return b.u("H"), b.u("I"), b.u("Q"), b.u("Q")


def parse_message(b: Body) -> Message:
    """The message record of body b (its payload copied)."""
    cid, seq, log_time, publish_time = message_header(b)
    return Message(cid, seq, log_time, publish_time, b.take(b.end - b.pos))


def parse_metadata(b: Body) -> Metadata:
    """The metadata record of body b."""
    name = b.string()
    return Metadata(name, b.string_map())


def parse_record(op: int, b: Body) -> Schema | Channel | Message | Metadata | None:
    """The record of opcode op (None for the kinds a reader passes over); RecordError if it does not parse."""
    if op == OP_SCHEMA:
        return parse_schema(b)
    if op == OP_CHANNEL:
        return parse_channel(b)
    if op == OP_MESSAGE:
        return parse_message(b)
    if op == OP_METADATA:
        return parse_metadata(b)
    return None


# ----------------------------------------------------------------------------- chunks


@dataclass(frozen=True)
class ChunkHeader:
    """The fields of a chunk record before its compressed records, and where those are."""

    start: int  # first log time, ns
    end: int  # last log time, ns
    uncompressed_size: int
    crc: int  # CRC-32 of the uncompressed records; 0: none
    compression: str
    compressed_size: int
    data_start: int  # offset of the compressed records in the buffer
    data_end: int


def chunk_header(buf: Buffer, b0: int, b1: int) -> ChunkHeader:
    """The header of the chunk whose body is buf[b0:b1]; RecordError if its sizes disagree."""
    b = Body(buf, b0, b1)
    start, end, usize, crc = b.u("Q"), b.u("Q"), b.u("Q"), b.u("I")
    comp = b.string()
    csize = b.u("Q")
    if b.pos + csize != b1:
        raise RecordError(f"chunk's compressed size {csize} disagrees with its record length")
    return ChunkHeader(start, end, usize, crc, comp, csize, b.pos, b1)


def chunk_records(buf: Buffer, h: ChunkHeader) -> bytes:
    """The uncompressed records of a chunk, size and CRC checked (a CRC of 0 is not checked).

    RecordError with the reason: unsupported compression, does not decompress, size or CRC mismatch.
    """
    data = bytes(buf[h.data_start : h.data_end])
    if h.compression == "zstd":
        try:
            raw = zstd.decompress(data)
        except zstd.ZstdError as exc:
            raise RecordError(f"chunk does not decompress ({exc})") from None
    elif h.compression == "":
        raw = data
    else:
        raise RecordError(f"chunk compression {h.compression!r} is not supported")
    if len(raw) != h.uncompressed_size:
        raise RecordError(f"chunk decompresses to {len(raw)} bytes, its header says {h.uncompressed_size}")
    if h.crc and zlib.crc32(raw) != h.crc:
        raise RecordError(f"chunk CRC mismatch (stored 0x{h.crc:08x}, computed 0x{zlib.crc32(raw):08x})")
    return raw


def footer_fields(buf: Buffer, size: int) -> tuple[int, int, int] | None:
    """(summary start, summary offset start, summary CRC) of the footer, None if the file has none."""
    footer = size - len(MAGIC) - FOOTER_BYTES
    if footer < len(MAGIC) or buf[size - len(MAGIC) : size] != MAGIC or buf[footer] != OP_FOOTER:
        return None
    if struct.unpack_from("<Q", buf, footer + 1)[0] != FOOTER_BYTES - FRAME_BYTES:
        return None
    start, offsets, crc = struct.unpack_from("<QQI", buf, footer + FRAME_BYTES)
    return int(start), int(offsets), int(crc)
