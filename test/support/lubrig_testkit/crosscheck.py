"""Cross-check a bag with two independent readers: rosbags and mcap + mcap_ros2."""

from __future__ import annotations

from collections import Counter, defaultdict
from pathlib import Path

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

TS = get_typestore(Stores.ROS2_KILTED)


def value_of(msg: object) -> float | str:
    """Scalar value of a decoded test message (Clock, JointState position or data)."""
    if hasattr(msg, "clock"):
        return msg.clock.sec + msg.clock.nanosec * 1e-9
    if hasattr(msg, "position"):
        return float(msg.position[0])
    return msg.data


def read_rosbags(bag: Path) -> dict[str, list]:
    """Topic -> decoded values in log-time order, via rosbags (uses metadata.yaml)."""
    out: dict[str, list] = defaultdict(list)
    with Reader(bag) as reader:
        for conn, _t, data in reader.messages():
            out[conn.topic].append(value_of(TS.deserialize_cdr(data, conn.msgtype)))
    return dict(out)


def read_mcap(bag: Path) -> dict[str, list]:
    """Topic -> decoded values in log-time order, via mcap + mcap_ros2 (uses the summary)."""
    (path,) = Path(bag).glob("*.mcap")
    out: dict[str, list] = defaultdict(list)
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None, "no MCAP summary"
        for _s, channel, _m, msg in reader.iter_decoded_messages(log_time_order=True):
            out[channel.topic].append(value_of(msg))
    return dict(out)


def counts(values: dict[str, list]) -> Counter:
    """Messages per topic."""
    return Counter({k: len(v) for k, v in values.items()})
