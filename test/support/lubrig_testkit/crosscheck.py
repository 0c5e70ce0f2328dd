"""Cross-check a bag with two independent readers: rosbags and mcap + mcap_ros2.

Neither uses lubrig_ros' type store: rosbags' AnyReader registers the message definitions stored
in the bag (custom types included), mcap_ros2 decodes from the MCAP schemas. Values per topic:
Clock its time, RigState its displacement, a block its samples (flattened into the topic's
list), FlowProgress its samples, scalar types their data, other types None (counted only).
"""

from __future__ import annotations

from collections import Counter, defaultdict
from pathlib import Path

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

TS = get_typestore(Stores.ROS2_KILTED)  # the stock types only: custom ones come from the bag


def values_of(msg: object) -> list:
    """Values of a decoded test message (see the module docstring)."""
    if hasattr(msg, "clock"):
        return [msg.clock.sec + msg.clock.nanosec * 1e-9]
    if hasattr(msg, "sample_index"):
        return [float(msg.displacement)]
    if hasattr(msg, "first_sample_index"):
        samples = msg.displacement if hasattr(msg, "displacement") else msg.band_velocity
        return [float(v) for v in samples]
    if hasattr(msg, "participant"):
        return [int(msg.samples)]
    if hasattr(msg, "position"):  # legacy layout: sensor_msgs/JointState on state
        return [float(msg.position[0])]
    data = getattr(msg, "data", None)
    if isinstance(data, (bool, int, float, str)):
        return [data]
    return [None]  # other types (diagnostics, images, arrays): counted, not compared


def value_of(msg: object) -> float | str:
    """The one value of a per-sample message."""
    (value,) = values_of(msg)
    return value


def read_rosbags(bag: Path) -> dict[str, list]:
    """Topic -> decoded values in log-time order, via rosbags (metadata.yaml, the bag's msgdefs)."""
    out: dict[str, list] = defaultdict(list)
    with AnyReader([Path(bag)], default_typestore=TS) as reader:
        for conn, _t, data in reader.messages():
            out[conn.topic].extend(values_of(reader.deserialize(data, conn.msgtype)))
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
            out[channel.topic].extend(values_of(msg))
    return dict(out)


def counts(values: dict[str, list]) -> Counter:
    """Messages per topic."""
    return Counter({k: len(v) for k, v in values.items()})
