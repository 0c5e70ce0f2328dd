"""Recorder acceptance tests: real recorder and publisher processes over DDS."""

from __future__ import annotations

import json
import signal
import time
from pathlib import Path

import pytest
import yaml
from ros_harness import ros_env, run_module, start_module

from lubrig_ros.app.contract import plant_topics
from lubrig_ros.bag import check_bag, read_arrays, repair_bag
from lubrig_ros.bag.crosscheck import read_mcap, read_rosbags

pytestmark = pytest.mark.ros
SAMPLES = 3000  # 3 s at 1 kHz, 6 topics = 6,000 messages/s


def _record(tmp_path: Path, samples: int, extra: tuple[str, ...] = ()):
    env = ros_env()
    cfg = tmp_path / "run.yaml"
    cfg.write_text("plant:\n  mass_kg: 1.0\nbelt:\n  velocity_m_s: 0.2\n")
    bag = tmp_path / "bag"
    rec = start_module(
        "lubrig_ros.nodes.recorder", "-o", str(bag), "--config", str(cfg), *extra, env=env
    )
    rec.wait_for_output("recording", timeout=30)
    pub = run_module(
        "lubrig_ros.bag.synthetic", "publish", "--samples", str(samples), env=env, timeout=60
    )
    assert pub.returncode == 0, pub.stdout + pub.stderr
    published = json.loads(pub.stdout.strip().splitlines()[-1])["published"]
    return rec, bag, cfg, published


def _wait_until_quiet(bag: Path, quiet: float, timeout: float) -> None:
    """Wait until the bag's .mcap has not grown for `quiet` seconds."""
    end = time.monotonic() + timeout
    last_size, last_change = -1, time.monotonic()
    while time.monotonic() < end:
        size = sum(p.stat().st_size for p in bag.glob("*.mcap"))
        if size != last_size:
            last_size, last_change = size, time.monotonic()
        elif time.monotonic() - last_change > quiet:
            return
        time.sleep(0.05)
    raise AssertionError(f"bag still growing after {timeout} s")


def _expect_all(bag: Path, published: dict[str, int]) -> None:
    for reader in (read_rosbags, read_mcap):
        values = reader(bag)
        for topic, n in published.items():
            got = values.get(topic, [])
            assert len(got) == n, f"{reader.__name__} {topic}: {len(got)} of {n}"
            if topic != "/clock":
                assert got == [float(k) for k in range(n)], f"{topic} out of order"


def test_sigint_finalizes_complete_bag(tmp_path: Path) -> None:
    rec, bag, cfg, published = _record(tmp_path, SAMPLES)
    with rec:
        assert rec.stop(signal.SIGINT, timeout=20) == 0, rec.errors()
    assert set(published) == set(plant_topics())
    _expect_all(bag, published)
    summary = check_bag(bag)  # finalized: no repair needed
    assert summary.run_config == cfg.read_text()
    assert yaml.safe_load(summary.run_config)["plant"]["mass_kg"] == 1.0
    assert summary.custom_data["lubrig_ros.version"]
    assert read_rosbags(bag)["/lubrig/run_config"] == [cfg.read_text()]
    arrays = read_arrays(bag)
    assert arrays["/lubrig/state"]["position"].shape == (SAMPLES,)
    assert (arrays["/lubrig/displacement"]["data"] == range(SAMPLES)).all()


def test_sigkill_then_repair_keeps_flushed_messages(tmp_path: Path) -> None:
    rec, bag, _cfg, published = _record(tmp_path, 2000, ("--flush-interval", "0.3"))
    with rec:
        rec.wait_for_output("recording")
        # every message received and flushed once the file stops growing for > 3 flush intervals
        # (a fixed sleep was too short on a loaded machine: the recorder may lag the publisher)
        _wait_until_quiet(bag, quiet=1.0, timeout=30.0)
        rec.kill()
    assert not (bag / "metadata.yaml").exists()
    report = repair_bag(bag)
    assert report.rewritten and not report.damaged_chunks
    _expect_all(bag, published)
    assert check_bag(bag).run_config is not None  # recovered from the /lubrig/run_config message


def test_unwritable_output_is_one_clear_error(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    res = run_module("lubrig_ros.nodes.recorder", "-o", str(blocker / "bag"), env=ros_env())
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "not writable" in lines[0] and str(blocker) in lines[0], res.stderr
    res = run_module("lubrig_ros.nodes.recorder", "-o", str(blocker), env=ros_env())
    assert res.returncode == 2 and "already exists" in res.stderr
    res = run_module("lubrig_ros.nodes.recorder", "--topics", "nope", env=ros_env())
    assert res.returncode == 2 and "'nope'" in res.stderr and "/lubrig/state" in res.stderr


def test_worker_dying_before_ready_is_one_error_line(tmp_path: Path) -> None:
    """A worker that cannot start its node (domain id out of range) names its topics; exit 2."""
    env = {**ros_env(), "ROS_DOMAIN_ID": "99999"}
    started = time.monotonic()
    res = run_module("lubrig_ros.nodes.recorder", "-o", str(tmp_path / "bag"), "--topics", "state",
                     env=env)
    assert time.monotonic() - started < 20  # not the 30 s ready timeout
    assert res.returncode == 2, res.stderr
    ours = [line for line in res.stderr.splitlines() if line.startswith("recorder:")]
    assert ours == [ours[0]] and "worker 0 (/lubrig/state) exited with status" in ours[0], res.stderr
    assert "Traceback" not in res.stderr.split("recorder:")[-1] and "queue.Empty" not in res.stderr
