"""The few CDR (ROS 2 wire format) reads done by hand, in one place.

Raw subscriptions and the bag code read serialized payloads directly where a full
deserialization would cost too much per message: a std_msgs/msg/Float64 value and the time stamp
at the start of a stamped message. A CDR payload starts with a 4-byte encapsulation header whose
second byte is 1 for little endian and 0 for big endian; the body follows (aligned to 8 from the
body's start, so a float64 right after the header sits at byte 4).
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

from lubrig_ros.core.errors import InputError
from lubrig_ros.core.schema import SAMPLE_FIELDS

_F64 = {1: struct.Struct("<d"), 0: struct.Struct(">d")}
_STAMP = {1: struct.Struct("<iI"), 0: struct.Struct(">iI")}


def float64_value(data: bytes) -> float:
    """Value of a serialized std_msgs/msg/Float64; NaN when the payload is malformed.

    (NaN is what the callers reject as bad input, so a malformed message is counted, never used.)
    """
    if len(data) < 12 or data[1] not in (0, 1):
        return math.nan
    return float(_F64[data[1]].unpack_from(data, 4)[0])


def leading_stamp_ns(data: bytes) -> int:
    """Time stamp (ns) at the start of a payload whose first field is a Header or a Time.

    ValueError when the payload is too short or the encapsulation is unknown.
    """
    if len(data) < 12:
        raise InputError(f"payload of {len(data)} bytes is too short for a time stamp")
    if data[1] not in (0, 1):
        raise InputError(f"unknown CDR encapsulation {data[:2].hex()!r}")
    sec, nsec = _STAMP[data[1]].unpack_from(data, 4)
    return int(sec) * 1_000_000_000 + int(nsec)


def stamp_of(t: float) -> tuple[int, int]:
    """(sec, nanosec) of a time in seconds, as builtin_interfaces/Time holds it (nanosec < 1e9)."""
    sec = math.floor(t)
    return int(sec), min(round((t - sec) * 1e9), 999_999_999)


#: CDR encapsulation header of little-endian plain CDR (what rclpy writes on this machine kind).
LITTLE_ENDIAN_CDR = b"\x00\x01\x00\x00"
#: struct format and size of each fixed-size scalar type rosidl names in get_fields_and_field_types().
_SCALARS = {
    "int32": ("i", 4),
    "uint32": ("I", 4),
    "int64": ("q", 8),
    "uint64": ("Q", 8),
    "double": ("d", 8),
}


class StampedEncoder:
    """Serializes a message of a std_msgs/Header and fixed-size scalars with one struct.pack.

    `fields` is the message class's get_fields_and_field_types() (names and types, in order):
    the layout is derived from the interface, not written here. The header's frame_id is empty.
    `encode(sec, nanosec, values)` returns the little-endian CDR payload, equal to rclpy's
    serialize_message of the same message and publishable as it is (Publisher.publish(bytes)):
    about a third of the cost of filling and publishing a message object, per message.
    """

    def __init__(self, fields: dict[str, str]) -> None:
        items = list(fields.items())
        if not items or items[0][1] != "std_msgs/Header":
            raise InputError(f"a stamped message starts with a std_msgs/Header; got fields {items[:1]}")
        fmt, pos = "<4siIIB", 13  # body: sec, nanosec, frame_id length 1, its NUL byte
        for name, kind in items[1:]:
            if kind not in _SCALARS:
                raise InputError(
                    f"field {name!r} of type {kind!r} is not a fixed-size scalar; valid: {list(_SCALARS)}"
                )
            code, size = _SCALARS[kind]
            pad = -pos % size
            fmt, pos = fmt + "x" * pad + code, pos + pad + size
        self.names = tuple(name for name, _ in items[1:])  # the values encode() takes, in order
        self._pack = struct.Struct(fmt).pack

    def encode(self, sec: int, nanosec: int, values: tuple[float | int, ...]) -> bytes:
        """The payload of the message with this stamp and these values (in `names` order)."""
        return self._pack(LITTLE_ENDIAN_CDR, sec, nanosec, 1, 0, *values)


_U32 = {1: struct.Struct("<I"), 0: struct.Struct(">I")}
_U64 = {1: struct.Struct("<Q"), 0: struct.Struct(">Q")}
_ALIGN_BASE = 4  # CDR alignment counts from the body, after the 4-byte encapsulation header


def _align(pos: int, size: int) -> int:
    body = pos - _ALIGN_BASE
    return _ALIGN_BASE + (body + size - 1) // size * size


@dataclass(frozen=True)
class SampleSpan:
    """Which samples one RigState / RigStateBlock / BandVelocityBlock message carries."""

    stamp_ns: int  # rig time of the first sample (header stamp)
    segment: int
    first_index: int  # sample_index (RigState) or first_sample_index (blocks)
    count: int  # 1 for RigState, the array length for blocks
    period_ns: float | None  # sample_period of a block, ns; None for RigState
    skipped: int = 0  # RigStateBlock: indices before first_index the plant declared skipped


#: Message types whose samples carry an index (sample_index / first_sample_index) and a segment.
INDEXED_TYPES: tuple[str, ...] = (
    "lubrig_interfaces/msg/RigState",
    "lubrig_interfaces/msg/RigStateBlock",
    "lubrig_interfaces/msg/BandVelocityBlock",
)


def sample_span(msgtype: str, data: bytes) -> SampleSpan:
    """The SampleSpan of a serialized message of one of INDEXED_TYPES, read from the CDR bytes.

    Layout (lubrig_interfaces/msg/*.msg): Header (int32 sec, uint32 nanosec, string frame_id),
    then for RigState uint64 sample_index, uint32 segment; for the blocks float64 sample_period,
    uint64 first_sample_index, uint32 segment and the first float64[] (its uint32 length).
    ValueError for another type or a malformed payload (too short, unknown encapsulation).
    """
    if msgtype not in INDEXED_TYPES:
        raise InputError(f"message type {msgtype!r} carries no sample index; valid: {INDEXED_TYPES}")
    stamp = leading_stamp_ns(data)  # checks length >= 12 and the encapsulation
    endian = data[1]
    u32, u64, f64 = _U32[endian], _U64[endian], _F64[endian]
    try:
        (name_len,) = u32.unpack_from(data, 12)
        pos = 16 + name_len
        if msgtype == INDEXED_TYPES[0]:
            pos = _align(pos, 8)
            (index,) = u64.unpack_from(data, pos)
            (segment,) = u32.unpack_from(data, pos + 8)
            return SampleSpan(stamp, int(segment), int(index), 1, None)
        pos = _align(pos, 8)
        (period,) = f64.unpack_from(data, pos)
        (first,) = u64.unpack_from(data, pos + 8)
        (segment,) = u32.unpack_from(data, pos + 16)
        (count,) = u32.unpack_from(data, _align(pos + 20, 4))
    except struct.error as exc:
        raise InputError(f"{msgtype} payload of {len(data)} bytes is truncated") from exc
    skipped = block_skipped(data, pos + 20) if msgtype == INDEXED_TYPES[1] else 0
    return SampleSpan(stamp, int(segment), int(first), int(count), float(period) * 1e9, skipped)


#: float64[] fields of RigStateBlock before its `skipped`: the sample arrays and `lateness`.
_BLOCK_ARRAYS = len(SAMPLE_FIELDS) + 1


def block_skipped(data: bytes, pos: int) -> int:
    """RigStateBlock.skipped, walking the float64[] fields that start at byte `pos`.

    CDR: each sequence is a uint32 length (aligned to 4) and, when not empty, its elements
    aligned to 8; `skipped` (uint64) follows, aligned to 8. 0 for a payload that ends before it
    (a block of a message definition without the field).
    """
    u32, u64 = _U32[data[1]], _U64[data[1]]
    try:
        for _ in range(_BLOCK_ARRAYS):
            pos = _align(pos, 4)
            (n,) = u32.unpack_from(data, pos)
            pos += 4
            if n:
                pos = _align(pos, 8) + 8 * n
        (skipped,) = u64.unpack_from(data, _align(pos, 8))
    except struct.error:
        return 0
    return int(skipped)
