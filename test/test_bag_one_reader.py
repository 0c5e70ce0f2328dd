"""The one bag reader (issues 21, 22): streams come from the MCAP file, and none is skipped silently.

rosbags, the reader the project used before, follows metadata.yaml: given a metadata.yaml whose
QoS for a topic differs from the file's channel it yields no message of that topic. The project's
reader (lubrig_ros.bag.reader) reads the file's own channels; a message that does not decode and
a legacy stream that cannot be paired with the states are errors naming the stream in `lubrig
report`, not a report without them. Bags from lubrig_testkit.bagdamage (BagWriter) and
lubrig_testkit.legacy.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from lubrig_testkit.bagdamage import CASES, INFO, NS, STATE_BLOCK, messages, write_bag
from lubrig_testkit.cli import lubrig
from rosbags.rosbag2 import Reader

from lubrig_ros.bag import BagError, BagWriter, read_arrays, read_messages


def test_reader_reads_every_channel_whatever_metadata_yaml_says(tmp_path: Path) -> None:
    """The bag reader takes the streams from the MCAP, not metadata.yaml (which rosbags follows)."""
    bag = tmp_path / "bag"
    write_bag(bag)
    CASES["topic_qos_depth"][0](bag)
    expected = messages(bag / "bag.mcap")
    got = {(topic, t): data for topic, _type, t, data in read_messages(bag)}
    assert got == expected and any(topic == STATE_BLOCK for topic, _t in got)
    with Reader(bag) as reader:  # what the metadata-driven reader makes of it: the stream is gone
        assert not any(conn.topic == STATE_BLOCK for conn, _t, _d in reader.messages())
    res = lubrig("replay", str(bag))
    assert res.returncode != 0 and "offered_qos_profiles depth 10" in res.stderr, res.stderr


def test_a_stream_that_does_not_decode_is_an_error_not_a_skip(tmp_path: Path) -> None:
    """A sound file whose state stream holds a payload that does not decode: report names it."""
    bag = tmp_path / "bag"
    write_bag(bag)
    broken = tmp_path / "broken"
    config = yaml.safe_load((bag / "metadata.yaml").read_text())[INFO]["custom_data"]["lubrig_ros.run_config"]
    writer = BagWriter(broken, run_config=config)
    for topic, msgtype, t, data in read_messages(bag):
        if topic == STATE_BLOCK and t == 100_000_000:
            data = data[:40]  # cut inside its arrays: CRCs and counts are right, the message is not
        writer.write(topic, msgtype, t, data)
    writer.close()
    with pytest.raises(BagError, match=f"topic {STATE_BLOCK}"):
        read_arrays(broken, [STATE_BLOCK])
    res = lubrig("report", str(broken), "--out", str(tmp_path / "report"))
    assert res.returncode != 0 and "Traceback" not in res.stderr, res.stderr
    assert len(res.stderr.strip().splitlines()) == 1 and STATE_BLOCK in res.stderr, res.stderr
    assert "does not decode" in res.stderr


def test_legacy_stream_that_cannot_be_paired_is_named(tmp_path: Path) -> None:
    """A legacy friction stream with fewer values than states is an error naming it, not μ = F/N."""
    from lubrig_testkit.legacy import write_legacy_bag

    bag = tmp_path / "legacy"
    write_legacy_bag(bag, 0.2)
    lossy = tmp_path / "lossy"
    config = yaml.safe_load((bag / "metadata.yaml").read_text())[INFO]["custom_data"]["lubrig_ros.run_config"]
    writer = BagWriter(lossy, run_config=config)
    states = 0
    for topic, msgtype, t, data in read_messages(bag):
        states += topic == f"{NS}/state"
        if topic == f"{NS}/friction_coefficient" and t == 100_000_000:
            continue
        writer.write(topic, msgtype, t, data)
    writer.close()
    res = lubrig("report", str(lossy), "--out", str(tmp_path / "report"))
    assert res.returncode != 0 and "Traceback" not in res.stderr, res.stderr
    assert (
        f"{NS}/friction_coefficient holds {states - 1} std_msgs/msg/Float64 messages for {states}"
        in res.stderr
    )
    assert "cannot be paired" in res.stderr
