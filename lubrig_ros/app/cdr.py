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
        raise ValueError(f"payload of {len(data)} bytes is too short for a time stamp")
    if data[1] not in (0, 1):
        raise ValueError(f"unknown CDR encapsulation {data[:2].hex()!r}")
    sec, nsec = _STAMP[data[1]].unpack_from(data, 4)
    return int(sec) * 1_000_000_000 + int(nsec)


def stamp_of(t: float) -> tuple[int, int]:
    """(sec, nanosec) of a time in seconds, as builtin_interfaces/Time holds it (nanosec < 1e9)."""
    sec = math.floor(t)
    return int(sec), min(round((t - sec) * 1e9), 999_999_999)
