"""Bounded loss (issue 15): a SIGKILL or a full disk costs at most the writer's flush bound.

A real recorder records a sim run from the synthetic plant (``--blocks``: RigStateBlock and
BandVelocityBlock of BLOCK samples, /clock, FlowProgress), which is paced on the recorder's own
FlowProgress like belt_drive: the recorder reports the samples it has *written* (given to the bag
writer) after every state block. The probe listens to those reports, so the test knows how many
samples the writer held when it died; the bag, repaired beside the original and read by the
independent mcap reader with CRC validation, must hold a gap-free prefix of them that misses at
most the flush bound: the pending chunk spans at most FLUSH_PERIOD_S of rig time, i.e.
FLUSH_PERIOD_S x RATE samples plus the block that crossed the bound (docs/recording.md).

The recorder's wall-clock fsync (--flush-interval) is set far out, so only the rig-time bound
can have flushed. The kill comes at a random rig moment of a 20 s run (fixed seeds).

Needs the block-writing recorder and the synthetic plant's ``--blocks``/``--consumer`` of issue 12
(branch h-rec).
"""

from __future__ import annotations

import resource
import signal
import subprocess
from pathlib import Path

import numpy as np
import pytest
from lubrig_testkit.harness import PYTHON, wait_until
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from lubrig_ros.bag import repair_bag
from lubrig_ros.bag.verify import verify_bag
from lubrig_ros.bag.writer import FLUSH_MESSAGES, FLUSH_PERIOD_NS

pytestmark = [pytest.mark.ros, pytest.mark.slow]

RATE = 1000  # samples per rig second (the synthetic plant's default)
BLOCK = 50
SAMPLES = 20 * RATE  # a 20 s sim run
FLUSH_PERIOD_S = FLUSH_PERIOD_NS / 1e9
BOUND = round(FLUSH_PERIOD_S * RATE) + BLOCK  # samples the pending chunk can hold at most
RECORDER = "/lubrig/lubrig_recorder"
WINDOW = 2 * BLOCK  # the plant runs at most this far ahead of the recorder's reports
TOPICS = ("state_block", "band_velocity_block", "flow_progress", "/clock")


def _recorder_argv(bag: Path, cfg: Path) -> list[str]:
    return [
        PYTHON,
        "-m",
        "lubrig_ros.nodes.recorder",
        "-o",
        str(bag),
        "--config",
        str(cfg),
        "--use-sim-time",
        "--topics",
        *TOPICS,
        "--flush-interval",
        "600",
    ]


def _publisher(procs):
    return procs.module(
        "lubrig_testkit.synthetic",
        "publish",
        "--blocks",
        str(BLOCK),
        "--samples",
        str(SAMPLES),
        "--consumer",
        RECORDER,
        "--flow-window",
        str(WINDOW),
        "--wait-subscribers",
        "90",
    )


def _listen_progress(probe) -> list:
    from lubrig_interfaces.msg import FlowProgress
    from lubrig_ros.app.interface.contract import documented_topics
    from lubrig_ros.nodes.interfaces import qos_profile

    spec = documented_topics("/lubrig")["/lubrig/flow_progress"]
    probe.subscribe(spec.name, FlowProgress, qos_profile(spec.qos))
    return probe.messages[spec.name]


def _written(progress: list, participant: str = RECORDER) -> int:
    """Samples the participant (the recorder by default) reported in its FlowProgress."""
    return max((int(m.samples) for m in progress if m.participant == participant), default=0)


def _settled(progress: list) -> int:
    """The recorder's last report once no more arrive (those in flight at the kill)."""
    seen = [-1, len(progress)]

    def quiet() -> bool:
        if seen[1] == len(progress):
            seen[0] += 1
        else:
            seen[:] = [0, len(progress)]
        return seen[0] >= 10  # no new message for 10 polls of 0.05 s

    wait_until(quiet, 30, "flow progress settled", every=0.05)
    return _written(progress)


def _published_settled(pub) -> int:
    """What the paced synthetic plant published (its stderr) once it has stalled on a dead consumer.

    Its own count, not its FlowProgress heard by the probe: beside two CPU hogs the probe had
    matched the plant too late and heard none of the few reports sent before the recorder died.
    """
    seen = [-1, ""]

    def quiet() -> bool:
        text = pub.errors()
        if text == seen[1]:
            seen[0] += 1
        else:
            seen[:] = [0, text]
        return seen[0] >= 20  # no new block for 20 polls of 0.05 s

    wait_until(quiet, 60, "the paced plant stalled", every=0.05)
    counts = [int(line.split()[1]) for line in pub.errors().splitlines() if line.startswith("published ")]
    return max(counts, default=0)


def _blocks_in(bag: Path) -> tuple[list[int], list[float], dict[str, int]]:
    """(first_sample_index per state block, displacements, messages per topic) via mcap, CRCs checked."""
    (path,) = bag.glob("*.mcap")
    firsts: list[int] = []
    values: list[float] = []
    counts: dict[str, int] = {}
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True, decoder_factories=[DecoderFactory()])
        assert reader.get_summary() is not None
        for _s, channel, _m, msg in reader.iter_decoded_messages(log_time_order=False):
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.topic == "/lubrig/state_block":
                firsts.append(int(msg.first_sample_index))
                values.extend(float(v) for v in msg.displacement)
    return firsts, values, counts


def _gap_free_prefix(firsts: list[int], values: list[float]) -> int:
    assert firsts == list(range(0, BLOCK * len(firsts), BLOCK)), "state blocks missing or out of order"
    assert values == [float(k) for k in range(len(values))], "samples damaged"
    return len(values)


def _config(tmp_path: Path) -> Path:
    cfg = tmp_path / "run.yaml"
    cfg.write_text("simulation:\n  sample_rate: 1000\n")
    return cfg


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_sigkill_at_a_random_moment_loses_at_most_the_flush_bound(
    procs, probe, tmp_path: Path, seed: int
) -> None:
    progress = _listen_progress(probe)
    bag = tmp_path / "bag"
    rec = procs.command("recorder", _recorder_argv(bag, _config(tmp_path)))
    rec.wait_for_output("recording", timeout=90)
    pub = _publisher(procs)
    target = int(np.random.default_rng(seed).integers(2 * RATE, SAMPLES - 2 * RATE))
    wait_until(
        lambda: _written(progress) >= target,
        240,
        f"recorder wrote {target} samples",
        alive=(rec,),
        every=0.005,
    )
    rec.popen.send_signal(signal.SIGKILL)  # the writer process only, as a crash would
    rec.kill()  # then its worker processes
    written = _settled(progress)
    published = _published_settled(pub)  # paced on the recorder: at least what was written
    pub.kill()
    assert not (bag / "metadata.yaml").exists()

    report = repair_bag(bag, output=tmp_path / "repaired")
    assert report.rewritten
    assert not verify_bag(tmp_path / "repaired").structural
    firsts, values, _counts = _blocks_in(tmp_path / "repaired")
    kept = _gap_free_prefix(firsts, values)
    lost = written - kept
    print(
        f"seed {seed}: killed at {written} samples written ({published} published), {kept} in the "
        f"bag, lost {lost} ({lost / RATE:.3f} s of rig time); bound {BOUND}; repair: {report.damage}"
    )
    assert lost <= BOUND, (written, kept)  # what the recorder said it had written
    assert kept <= published and published - kept <= BOUND + WINDOW  # what the plant published
    assert kept >= target - BOUND


LIMIT = 60_000  # bytes: the bag reaches it after about 5 s of the 20 s run


def _file_size_cap(limit: int):
    def cap() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # EFBIG (like ENOSPC) instead of a kill

    return cap


def _reported_counts(output: str) -> dict[str, int]:
    line = [line for line in output.splitlines() if line.startswith("recorder: stopped;")][-1]
    pairs = line.split(": ", 2)[2].split(", ")
    return {topic: int(n) for topic, n in (pair.rsplit("=", 1) for pair in pairs)}


@pytest.fixture
def small_file_system(tmp_path: Path):
    """A real tmpfs of LIMIT bytes mounted at tmp_path/fs (needs CAP_SYS_ADMIN; skipped otherwise)."""
    mount = tmp_path / "fs"
    mount.mkdir()
    res = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={LIMIT}", "tmpfs", str(mount)],
        capture_output=True,
        text=True,
        check=False,
    )
    if res.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs here: {res.stderr.strip()}")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], capture_output=True, check=False)


def test_full_disk_loses_at_most_the_flush_bound_and_counts_are_the_bag(procs, probe, tmp_path: Path) -> None:
    """The file size capped (RLIMIT_FSIZE): EFBIG, the same OSError path as a full disk."""
    _record_until_full(procs, probe, tmp_path, tmp_path / "bag", _file_size_cap(LIMIT), "File too large")


def test_small_file_system_loses_at_most_the_flush_bound(
    procs, probe, tmp_path: Path, small_file_system: Path
) -> None:
    """A real small file system (tmpfs of LIMIT bytes): ENOSPC."""
    _record_until_full(procs, probe, tmp_path, small_file_system / "bag", None, "No space left on device")


def _record_until_full(procs, probe, tmp_path: Path, bag: Path, preexec, error_text: str) -> None:
    rec = procs.command("recorder", _recorder_argv(bag, _config(tmp_path)), preexec_fn=preexec)
    rec.wait_for_output("recording", timeout=90)
    pub = _publisher(procs)
    assert rec.wait(timeout=240) == 1, rec.log()  # stops by itself on the write error
    published = _published_settled(pub)
    pub.kill()
    mine = [line for line in rec.errors().splitlines() if line.startswith("recorder:")]
    assert "Traceback" not in rec.errors()
    (error,) = [line for line in mine if error_text in line]
    unflushed = int(error.split(" messages not yet flushed are lost")[0].rsplit("(", 1)[1])
    assert (bag / "bag.mcap").stat().st_size <= LIMIT

    # beside it (the capped file system is full), unless the recorder's own repair fitted
    repaired = tmp_path / "repaired" if repair_bag(bag, output=tmp_path / "repaired").rewritten else bag
    assert not verify_bag(repaired).structural
    firsts, values, counts = _blocks_in(repaired)
    kept = _gap_free_prefix(firsts, values)
    print(
        f"disk full: {published} samples published, {kept} in the bag; the writer lost {unflushed} "
        f"messages not yet flushed"
    )
    assert 0 < kept < SAMPLES
    assert kept <= published and published - kept <= BOUND + WINDOW, (published, kept)
    assert unflushed < FLUSH_MESSAGES
    # the recorder's final counts are what is in the bag
    assert {t: n for t, n in _reported_counts(rec.output()).items() if n} == counts
