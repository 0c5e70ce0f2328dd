"""Disk full while recording: a real recorder process whose file size is capped (RLIMIT_FSIZE).

With RLIMIT_FSIZE and SIGXFSZ ignored, write() past the limit fails with EFBIG ("File too
large") like ENOSPC on a full disk: the same OSError path in the writer. The bag is read back
by two independent readers (rosbags, mcap + mcap_ros2).
"""

from __future__ import annotations

import hashlib
import json
import resource
import signal
from pathlib import Path

import pytest
from ros_harness import PYTHON, RosProcess, ros_env, run_module

from lubrig_ros.app.contract import plant_topics
from lubrig_ros.bag import BagError, check_bag, repair_bag
from lubrig_ros.bag.crosscheck import read_mcap, read_rosbags
from lubrig_ros.bag.synthetic import START_NS

pytestmark = pytest.mark.ros
LIMIT = 120_000  # bytes per file; 3,000 samples x 6 topics make ~460 kB of bag
SAMPLES = 3000


class LimitedProcess(RosProcess):
    """RosProcess whose files may not grow beyond `limit` bytes (write fails with EFBIG)."""

    def __init__(self, argv: list[str], env: dict[str, str], limit: int) -> None:
        def cap() -> None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # EFBIG instead of being killed

        super().__init__(argv, env, preexec_fn=cap)


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_file_size_limit_stops_recording_cleanly(tmp_path: Path) -> None:
    env = ros_env()
    cfg = tmp_path / "run.yaml"
    cfg.write_text("plant:\n  mass_kg: 1.0\n")
    bag = tmp_path / "bag"
    argv = [
        PYTHON, "-m", "lubrig_ros.nodes.recorder",
        "-o", str(bag), "--config", str(cfg), "--flush-interval", "0.2",
    ]
    with LimitedProcess(argv, env, LIMIT) as rec:
        rec.wait_for_output("recording", timeout=30)
        pub = run_module(
            "lubrig_ros.bag.synthetic", "publish", "--samples", str(SAMPLES), env=env, timeout=60
        )
        assert pub.returncode == 0, pub.stdout + pub.stderr
        published = json.loads(pub.stdout.strip().splitlines()[-1])["published"]
        # the recorder stops by itself (no signal sent): exit status 1
        assert rec.wait(timeout=30) == 1, rec.output() + rec.errors()
    errors = rec.errors()
    assert "Traceback" not in errors, errors
    mine = [line for line in errors.splitlines() if line.startswith("recorder:")]
    assert len(mine) == 1, errors  # one line naming the problem (Fast DDS may log its own)
    assert "File too large" in mine[0] and str(bag) in mine[0] and "recording stopped" in mine[0]

    mcap = bag / "bag.mcap"
    assert 0 < mcap.stat().st_size <= LIMIT
    # the in-place finalization needs space too, so it fails under the cap: the bag is left
    # unfinalized (no summary, no metadata.yaml), the failed attempt leaves no temporary files
    assert sorted(p.name for p in bag.iterdir()) == ["bag.mcap", "run_config.yaml"]
    with pytest.raises(BagError, match="repair"):
        check_bag(bag)

    before = _sha(mcap)
    report = repair_bag(bag)  # `lubrig bag repair DIR`
    assert report.rewritten and not report.complete and not report.damaged_chunks
    assert report.backup is not None and _sha(report.backup) == before  # original untouched
    summary = check_bag(bag)
    assert summary.run_config == cfg.read_text()  # from run_config.yaml / the latched message

    by_rosbags, by_mcap = read_rosbags(bag), read_mcap(bag)
    assert by_rosbags == by_mcap
    assert set(published) == set(plant_topics())
    for topic in published:
        got = by_rosbags.get(topic, [])
        # what was flushed before the error, in order: a gap-free prefix of the published run
        assert 100 <= len(got) < SAMPLES, (topic, len(got))
        if topic == "/clock":
            expected = [(START_NS + k * 1_000_000) / 1e9 for k in range(len(got))]
            assert got == pytest.approx(expected, abs=1e-9), topic
        else:
            assert got == [float(k) for k in range(len(got))], f"{topic} damaged or out of order"
