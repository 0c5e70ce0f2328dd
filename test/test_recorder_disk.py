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
from lubrig_testkit.crosscheck import read_mcap, read_rosbags
from lubrig_testkit.harness import PYTHON
from lubrig_testkit.synthetic import PER_SAMPLE_TOPICS, SCALAR_TOPICS, START_NS

from lubrig_ros.app.interface.contract import resolve
from lubrig_ros.bag import BagError, check_bag, repair_bag

SOURCE_TOPICS = (*PER_SAMPLE_TOPICS, *SCALAR_TOPICS)
LIMIT = 120_000  # bytes per file; 3,000 samples x 6 topics make ~460 kB of bag
SAMPLES = 3000


def _file_size_cap(limit: int):
    """preexec_fn: the process's files may not grow beyond limit bytes (write fails with EFBIG)."""

    def cap() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # EFBIG instead of being killed

    return cap


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_file_size_limit_stops_recording_cleanly(procs, tmp_path: Path) -> None:
    cfg = tmp_path / "run.yaml"
    cfg.write_text("plant:\n  mass_kg: 1.0\n")
    bag = tmp_path / "bag"
    argv = [
        PYTHON,
        "-m",
        "lubrig_ros.nodes.recorder",
        "-o",
        str(bag),
        "--config",
        str(cfg),
        "--flush-interval",
        "0.2",
    ]
    rec = procs.command("recorder", argv, preexec_fn=_file_size_cap(LIMIT))
    rec.wait_for_output("recording", timeout=90)
    # flow control: the publisher goes on once the recorder has every sample (or has stopped)
    pub = procs.run_module(
        "lubrig_testkit.synthetic",
        "publish",
        "--samples",
        str(SAMPLES),
        "--flow-control",
        "100",
        "--scalars",
        "--clock",
        timeout=180,
    )
    assert pub.returncode == 0, pub.stdout + pub.stderr
    published = json.loads(pub.stdout.strip().splitlines()[-1])["published"]
    # the recorder stops by itself (no signal sent): exit status 1
    assert rec.wait(timeout=120) == 1, rec.log()
    errors = rec.errors()
    assert "Traceback" not in errors, errors
    mine = [line for line in errors.splitlines() if line.startswith("recorder:")]
    assert len(mine) == 1, errors  # one line naming the problem (Fast DDS may log its own)
    assert "File too large" in mine[0] and str(bag) in mine[0] and "recording stopped" in mine[0]

    mcap = bag / "bag.mcap"
    assert 0 < mcap.stat().st_size <= LIMIT
    # the in-place finalization needs space too, so it fails under the cap: the bag is left
    # unfinalized (no summary, no metadata.yaml), the failed attempt leaves no temporary files
    # (accounting.json, a few hundred bytes written after the stop, fits under the cap)
    assert sorted(p.name for p in bag.iterdir()) == ["accounting.json", "bag.mcap", "run_config.yaml"]
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
    assert set(published) == {*(resolve("/lubrig", n) for n in SOURCE_TOPICS), "/clock"}
    for topic in published:
        got = by_rosbags.get(topic, [])
        # what was flushed before the error, in order: a gap-free prefix of the published run
        assert 100 <= len(got) < SAMPLES, (topic, len(got))
        if topic == "/clock":
            expected = [(START_NS + k * 1_000_000) / 1e9 for k in range(len(got))]
            assert got == pytest.approx(expected, abs=1e-9), topic
        else:
            assert got == [float(k) for k in range(len(got))], f"{topic} damaged or out of order"
