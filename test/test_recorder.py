"""Recorder acceptance tests: real recorder and publisher processes over DDS.

The synthetic publisher runs with flow control (it waits for the recorder's acknowledgements every
100 samples), so "every message is in the bag" holds whatever the machine's load. Under a realtime
source (paced, no flow control) a starved recorder can lose samples; that test asserts the
accounting instead: what the recorder reports equals what is in the bag, in order, no duplicates.
The recorder's throughput is a benchmark figure (bench/bench_recorder.py).
"""

from __future__ import annotations

import itertools
import json
import shutil
import signal
from pathlib import Path

import yaml
from lubrig_testkit.crosscheck import read_mcap, read_rosbags
from lubrig_testkit.harness import wait_until

from lubrig_ros.bag import check_bag, read_arrays, repair_bag

SAMPLES = 3000  # 6 topics: 18,000 messages
#: what the synthetic source publishes per sample (--scalars --clock): RigState on state
SOURCE_TOPICS = {
    "/lubrig/state",
    "/lubrig/band_velocity",
    "/lubrig/displacement",
    "/lubrig/velocity",
    "/lubrig/friction_coefficient",
    "/clock",
}


def _record(
    procs,
    tmp_path: Path,
    samples: int,
    extra: tuple[str, ...] = (),
    source: tuple[str, ...] = ("--flow-control", "100"),
):
    cfg = tmp_path / "run.yaml"
    cfg.write_text("plant:\n  mass_kg: 1.0\nbelt:\n  velocity_m_s: 0.2\n")
    bag = tmp_path / "bag"
    rec = procs.module("lubrig_ros.nodes.recorder", "-o", str(bag), "--config", str(cfg), *extra)
    rec.wait_for_output("recording", timeout=90)
    pub = procs.run_module(
        "lubrig_testkit.synthetic",
        "publish",
        "--samples",
        str(samples),
        "--scalars",
        "--clock",
        *source,
        timeout=180,
    )
    assert pub.returncode == 0, pub.stdout + pub.stderr
    published = json.loads(pub.stdout.strip().splitlines()[-1])["published"]
    return rec, bag, cfg, published


def _reported_counts(output: str) -> dict[str, int]:
    """The counts of the recorder's last line, `recorder: stopped; bag B: topic=n, ...`."""
    line = [line for line in output.splitlines() if line.startswith("recorder: stopped;")][-1]
    pairs = line.split(": ", 2)[2].split(", ")
    return {topic: int(n) for topic, n in (pair.rsplit("=", 1) for pair in pairs)}


def _on_disk(bag: Path, scratch: Path) -> dict[str, int]:
    """Messages per topic a repair of the bag's current on-disk state would keep."""
    shutil.rmtree(scratch, ignore_errors=True)
    shutil.copytree(bag, scratch)
    repair_bag(scratch)
    return {t.name: t.count for t in check_bag(scratch).topics if t.count and t.name != "/lubrig/run_config"}


def _expect_all(bag: Path, published: dict[str, int]) -> None:
    for reader in (read_rosbags, read_mcap):
        values = reader(bag)
        for topic, n in published.items():
            got = values.get(topic, [])
            assert len(got) == n, f"{reader.__name__} {topic}: {len(got)} of {n}"
            if topic != "/clock":
                assert got == [float(k) for k in range(n)], f"{topic} out of order"


def test_sigint_finalizes_complete_bag(procs, tmp_path: Path) -> None:
    rec, bag, cfg, published = _record(procs, tmp_path, SAMPLES)
    assert rec.stop(signal.SIGINT, timeout=60) == 0, rec.log()
    assert set(published) == SOURCE_TOPICS
    _expect_all(bag, published)
    # what it says it wrote is what it wrote: every sample, and the run configuration once
    assert _reported_counts(rec.output()) == {**published, "/lubrig/run_config": 1}
    summary = check_bag(bag)  # finalized: no repair needed
    assert summary.run_config == cfg.read_text()
    assert yaml.safe_load(summary.run_config)["plant"]["mass_kg"] == 1.0
    assert summary.custom_data["lubrig_ros.version"]
    assert read_rosbags(bag)["/lubrig/run_config"] == [cfg.read_text()]
    arrays = read_arrays(bag)
    assert arrays["/lubrig/state"]["displacement"].shape == (SAMPLES,)
    assert (arrays["/lubrig/state"]["sample_index"] == range(SAMPLES)).all()
    assert (arrays["/lubrig/displacement"]["data"] == range(SAMPLES)).all()


def test_sigkill_then_repair_keeps_flushed_messages(procs, tmp_path: Path) -> None:
    rec, bag, _cfg, published = _record(procs, tmp_path, 2000, ("--flush-interval", "0.3"))
    # kill once every published message is flushed: a repair of a copy of the files keeps them all
    wait_until(
        lambda: _on_disk(bag, tmp_path / "copy") == published,
        120,
        "all messages flushed",
        alive=(rec,),
        every=0.5,
    )
    rec.kill()
    assert not (bag / "metadata.yaml").exists()
    report = repair_bag(bag)
    assert report.rewritten and not report.damaged_chunks
    _expect_all(bag, published)
    assert check_bag(bag).run_config is not None  # recovered from the /lubrig/run_config message


def test_sigkill_of_the_recorder_alone_leaves_no_process_behind(procs, tmp_path: Path) -> None:
    """The fork server and the workers die with the recorder, even of a SIGKILL no handler sees."""
    import os

    import psutil

    rec, _bag, _cfg, _published = _record(procs, tmp_path, 200)
    helpers = psutil.Process(rec.pid).children(recursive=True)
    assert len(helpers) >= 2, helpers  # the fork server and at least one worker (and a resource tracker)
    os.kill(rec.pid, signal.SIGKILL)  # the recorder only, not its process group
    rec.popen.wait(timeout=10)
    _gone, alive = psutil.wait_procs(helpers, timeout=10)
    assert not alive, [(p.pid, p.name(), p.cmdline()[:4]) for p in alive]


def test_a_required_stream_that_got_no_sample_makes_the_recording_incomplete(procs, tmp_path: Path) -> None:
    """A stream lost whole has no gap to show: --require-samples names it, exit 1, the rest kept."""
    extra = ("--require-samples", "state", "state_block")  # the source publishes no state_block
    rec, bag, _cfg, published = _record(procs, tmp_path, 500, extra)
    assert rec.stop(signal.SIGINT, timeout=60) == 1, rec.log()
    assert "incomplete recording: /lubrig/state_block: no samples recorded" in rec.errors()
    assert "/lubrig/state:" not in rec.errors()  # the stream that has its samples is fine
    accounting = json.loads((bag / "accounting.json").read_text())
    assert not accounting["complete"] and len(accounting["problems"]) == 1
    _expect_all(bag, published)  # nothing recorded is lost


def test_realtime_source_counts_reported_equal_the_bag(procs, tmp_path: Path) -> None:
    """A paced 1 kHz source without flow control: samples a starved recorder loses are accounted.

    Exit 0 exactly when the state stream is complete; else 1 with the stream and its first gap
    named, as accounting.json and the bag itself (its sample indices) say.
    """
    rec, bag, _cfg, published = _record(procs, tmp_path, 2000, source=("--rate", "1000"))
    status = rec.stop(signal.SIGINT, timeout=60)
    reported = _reported_counts(rec.output())
    accounting = json.loads((bag / "accounting.json").read_text())
    state = accounting["streams"]["/lubrig/state"]
    indices = read_arrays(bag)["/lubrig/state"]["sample_index"].tolist()
    missing = sorted(set(range(indices[-1] + 1)) - set(indices))  # the stream starts at index 0
    assert state["samples"] == len(indices) and state["duplicates"] == 0
    if missing:  # a starved recorder: loud, named, exit 1
        assert status == 1, rec.log()
        assert state["gaps"][0]["first_index"] == missing[0]
        assert f"/lubrig/state: {len(missing)} samples missing" in rec.errors()
    else:
        assert status == 0 and state["complete"], rec.log()
    by_rosbags, by_mcap = read_rosbags(bag), read_mcap(bag)
    assert by_rosbags == by_mcap
    assert reported == {topic: len(values) for topic, values in by_rosbags.items()}
    assert set(reported) == {*published, "/lubrig/run_config"}
    assert reported["/lubrig/state"] == len(indices)
    for topic, n in published.items():
        got = by_rosbags[topic]
        assert 0 < len(got) <= n, (topic, len(got))
        if topic == "/clock":
            got = [round((v - 1.0) * 1000) for v in got]  # sample k is at 1 s + k ms
        # what is there is in order, once each, with its own value: a loss is a gap, nothing else
        assert all(a < b for a, b in itertools.pairwise(got)), f"{topic} out of order"
        assert set(got) <= {float(k) for k in range(n)}, topic
    assert reported["/lubrig/run_config"] == 1


def test_unwritable_output_is_one_clear_error(procs, tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    res = procs.run_module("lubrig_ros.nodes.recorder", "-o", str(blocker / "bag"))
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "not writable" in lines[0] and str(blocker) in lines[0], res.stderr
    res = procs.run_module("lubrig_ros.nodes.recorder", "-o", str(blocker))
    assert res.returncode == 2 and "already exists" in res.stderr
    res = procs.run_module("lubrig_ros.nodes.recorder", "--topics", "nope")
    assert res.returncode == 2 and "'nope'" in res.stderr and "/lubrig/state" in res.stderr
    # a required stream must be a recorded sample stream; nothing is created
    out = tmp_path / "never"
    argv = ("-o", str(out), "--topics", "state", "displacement", "--require-samples", "displacement")
    res = procs.run_module("lubrig_ros.nodes.recorder", *argv)
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2 and len(lines) == 1, res.stderr
    assert "--require-samples '/lubrig/displacement' is invalid" in lines[0] and "/lubrig/state" in lines[0]
    assert not out.exists()


def test_worker_dying_before_ready_is_one_error_line(procs, ros_env, tmp_path: Path) -> None:
    """A worker that cannot start its node (domain id out of range) names its topics; exit 2.

    The error is the worker's exit, seen as it happens, not the 30 s ready timeout (whose message
    is "not ready after"); how quickly is not a test's business.
    """
    env = {**ros_env, "ROS_DOMAIN_ID": "99999"}
    res = procs.run_module(
        "lubrig_ros.nodes.recorder", "-o", str(tmp_path / "bag"), "--topics", "state", env=env
    )
    assert res.returncode == 2, res.stderr
    ours = [line for line in res.stderr.splitlines() if line.startswith("recorder:")]
    assert ours == [ours[0]] and "worker 0 (/lubrig/state) exited with status" in ours[0], res.stderr
    assert "not ready after" not in res.stderr
    assert "Traceback" not in res.stderr.split("recorder:")[-1] and "queue.Empty" not in res.stderr


def test_sigint_while_the_workers_start_gives_a_finalized_empty_bag(procs, tmp_path: Path) -> None:
    """Ctrl-C at once (before the workers are ready, on a loaded machine): no wait for them.

    The recorder stops, exit 0, and leaves a finalized bag that verifies (no message but the
    stored run configuration); it says which of the two moments the stop came at.
    """
    from lubrig_ros.bag.verify import verify_bag

    bag = tmp_path / "bag"
    rec = procs.module("lubrig_ros.nodes.recorder", "-o", str(bag), "--use-sim-time")
    wait_until(lambda: (bag / "bag.mcap").exists(), 90, "the bag file created")
    assert rec.stop(signal.SIGINT, timeout=60) == 0, rec.log()
    out = rec.output()
    assert "stop requested while the workers were starting" in out or "recording" in out, out
    assert "recorder: stopped; bag" in out and "Traceback" not in rec.errors(), rec.log()
    assert (bag / "metadata.yaml").exists()
    result = verify_bag(bag)
    assert not result.structural and not result.problems, result.problems
