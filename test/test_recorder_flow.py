"""The recorder in the sim flow control and its accounting: real recorder and source processes.

The synthetic source (lubrig_testkit.synthetic) plays the plant of a sim run: RigStateBlock and
BandVelocityBlock blocks, /clock, its own FlowProgress as <ns>/plant, paced like belt_drive on the
recorder's FlowProgress (never more than --flow-window samples ahead of what the recorder
reported). Asserted: the recorder reports as /lubrig/lubrig_recorder, starts at 0, reaches every
sample; the bag holds every sample once, in order, decoded by two independent readers from the
schemas in the file; a skipped sample index ends the recording with exit 1 naming the stream
and the gap.
"""

from __future__ import annotations

import itertools
import json
import signal
from pathlib import Path

from lubrig_testkit.crosscheck import read_mcap, read_rosbags

from lubrig_ros.bag import read_arrays
from lubrig_ros.report.frombag import recording_summary

RECORDER_FQN = "/lubrig/lubrig_recorder"


def _recorder(procs, bag: Path):
    rec = procs.module("lubrig_ros.nodes.recorder", "-o", str(bag), "--use-sim-time")
    rec.wait_for_output("recording", timeout=180)
    return rec


def test_sim_blocks_paced_on_the_recorders_progress(procs, tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    rec = _recorder(procs, bag)
    samples, window = 6000, 500
    pub = procs.run_module(
        "lubrig_testkit.synthetic",
        "publish",
        "--blocks",
        "100",
        "--samples",
        str(samples),
        "--consumer",
        RECORDER_FQN,
        "--flow-window",
        str(window),
        "--wait-subscribers",
        "120",
        timeout=400,
    )
    assert pub.returncode == 0, pub.stdout + pub.stderr
    published = json.loads(pub.stdout.strip().splitlines()[-1])["published"]
    assert published["consumer_samples"] == samples  # the recorder reported every sample taken
    assert rec.stop(signal.SIGINT, timeout=120) == 0, rec.log()
    assert "/lubrig/state_block: 6000 in 60 messages, 0 missing, 0 duplicates" in rec.output()
    # two independent readers, custom types from the file's schemas: every sample once, in order
    by_rosbags, by_mcap = read_rosbags(bag), read_mcap(bag)
    assert by_rosbags == by_mcap
    for topic in ("/lubrig/state_block", "/lubrig/band_velocity_block"):
        assert by_rosbags[topic] == [float(k) for k in range(samples)], topic
    # the recorder's own FlowProgress is in the bag: from 0, never backwards, up to every sample,
    # and never more than window + one block behind the source (the source waits for it)
    arrays = read_arrays(bag, ["/lubrig/flow_progress"])["/lubrig/flow_progress"]
    mine = [m.samples for m in arrays["message"] if m.participant == RECORDER_FQN]
    plant = [m.samples for m in arrays["message"] if m.participant == "/lubrig/plant"]
    assert mine[0] == 0 and mine[-1] == samples, mine[:3]
    assert all(a <= b for a, b in itertools.pairwise(mine))
    assert plant == list(range(100, samples + 1, 100))
    accounting = json.loads((bag / "accounting.json").read_text())
    assert accounting["participant"] == RECORDER_FQN and accounting["complete"]
    assert accounting["streams"]["/lubrig/state_block"]["segments"]["0"]["announced"] == samples
    assert recording_summary(bag)["problems"] == []


def test_skipped_sample_index_ends_non_zero_naming_stream_and_gap(procs, tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    rec = _recorder(procs, bag)
    pub = procs.run_module(
        "lubrig_testkit.synthetic",
        "publish",
        "--samples",
        "1500",
        "--flow-control",
        "100",
        "--skip",
        "700",
        "701",
        "1200",
        timeout=300,
    )
    assert pub.returncode == 0, pub.stdout + pub.stderr
    assert rec.stop(signal.SIGINT, timeout=120) == 1, rec.log()
    errors = [line for line in rec.errors().splitlines() if line.startswith("recorder: error:")]
    assert errors == [
        "recorder: error: incomplete recording: /lubrig/state: 3 samples missing in 2 gap(s); "
        "first gap: 2 samples from index 700 of segment 0 at rig time 1.700000 s"
    ], rec.errors()
    accounting = json.loads((bag / "accounting.json").read_text())
    gaps = accounting["streams"]["/lubrig/state"]["gaps"]
    assert [(g["first_index"], g["count"]) for g in gaps] == [(700, 2), (1200, 1)]
    assert not accounting["complete"]
    # the bag says the same from its own sample indices (what the report marks)
    summary = recording_summary(bag)
    assert summary["streams"]["/lubrig/state"]["gaps"] == gaps
