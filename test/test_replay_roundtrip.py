"""Round trip: record a rig run, replay the bag into a fresh analysis node, compare with offline.

Also covers replay options: --rate R (the schedule scaled by 1/R) and --start S (the first
replayed message is at or after S of log time), with --clock. How closely the schedule is kept
on the wall clock is a benchmark figure (bench/bench_replay.py), not asserted here.
"""

from __future__ import annotations

import json
import math
import struct
import time
from pathlib import Path

import pytest
from lubrig_testkit.harness import DomainLease, Probe, ros_env
from std_msgs.msg import Float64

from lubrig_ros.app.interface import contract
from lubrig_ros.bag import BagWriter, check_bag, read_arrays
from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import simulate
from lubrig_ros.core.wavelet_components import dominant_frequencies

DURATION = 6.0
SCALE_STEP = 2 ** (1 / 12)  # one wavelet scale step (dj = 1/12 octave)
WINDOW = 2048  # the analysis's window, samples
PUBLISH_PERIOD = 0.2  # s
BLOCK_S = contract.DEFAULT_BLOCK_LENGTH / 1000  # rig s per recorded block (1 kHz)
#: updates the replayed run must bring: one per publish_period or per block, whichever is longer,
#: from the block that fills the window to the end of the run
UPDATES = (
    math.floor((DURATION - math.ceil(WINDOW / 1000 / BLOCK_S) * BLOCK_S) / max(PUBLISH_PERIOD, BLOCK_S)) + 1
)


@pytest.mark.slow  # a 6 s `lubrig rig` run, then its replay
def test_recorded_run_replayed_into_analysis_matches_offline(procs, tmp_path: Path) -> None:
    run = tmp_path / "run"
    res = procs.run_module(
        "lubrig_ros.cli.main",
        "rig",
        "--case",
        "1",
        "--duration",
        str(DURATION),
        "--bag",
        str(run),
        "--no-report",
        timeout=240,
    )
    assert res.returncode == 0, res.stdout + res.stderr
    bag = run / "bag"

    # offline reference: the core run of the same configuration, and the recorded x(t)
    config = load_case(1).with_overrides(duration=DURATION)
    x = simulate(config).displacement
    fundamental = config.band.fundamental_hz
    offline = dominant_frequencies(x - x.mean(), 1e-3, fundamental_hz=fundamental)[0].frequency_hz
    assert 9.0 < offline < 10.0  # 2nd harmonic of 4.76 Hz
    recorded = read_arrays(bag)["/lubrig/state_block"]["displacement"]  # one entry per sample
    assert len(recorded) == len(x)
    from_bag = dominant_frequencies(recorded - recorded.mean(), 1e-3, fundamental_hz=fundamental)
    assert from_bag[0].frequency_hz == offline

    # replay on a fresh domain (nothing of the rig run's participants in its discovery) into a
    # fresh analysis node that follows the bag's clock
    with DomainLease() as fresh:
        env = ros_env(fresh)
        probe = Probe(fresh, name="roundtrip_probe")
        try:
            probe.subscribe("/lubrig/dominant_frequency", Float64)
            # 96 scales over 1.95..250 Hz (window 2048 at 1 kHz): 0.074 octave per scale < 1/12
            analysis = procs.script(
                "analysis",
                "--ros-args",
                "-p",
                "case:=1",
                "-p",
                "use_sim_time:=true",
                "-p",
                f"window:={WINDOW}",
                "-p",
                "n_scales:=96",
                "-p",
                f"publish_period:={PUBLISH_PERIOD}",
                env=env,
            )
            replay = procs.script(
                "lubrig",
                "replay",
                str(bag),
                "--clock",
                "--topics",
                "/lubrig/state_block",
                "/lubrig/band_velocity_block",
                "--wait-for-subscribers",
                "90",
                env=env,
            )
            assert replay.wait(timeout=180) == 0, replay.log()
            blocks = sum(
                t.count
                for t in check_bag(bag).topics
                if t.name in ("/lubrig/state_block", "/lubrig/band_velocity_block")
            )
            assert f"published {blocks} messages" in replay.output()  # the blocks as recorded
            # replayed at 1x, an update every max(publish_period, block span) of rig time once
            # WINDOW samples are in (docs/nodes.md "Block length"): one per state block from the
            # block that fills the window; on a loaded machine the analysis may still work
            # through its input after replay ends
            values = probe.messages["/lubrig/dominant_frequency"]
            assert probe.wait_for(lambda: len(values) >= UPDATES, 180), (values, analysis.log())
            values = [m.data for m in values]
            assert analysis.running(), analysis.log()  # still running: no crash
        finally:
            procs.stop_all()
            probe.close()
    assert len(values) >= UPDATES, values
    for f in values:
        assert offline / SCALE_STEP <= f <= offline * SCALE_STEP, (f, offline, values)
    assert math.isclose(values[-1], offline, rel_tol=SCALE_STEP - 1)


N, STEP_NS, T0 = 400, 50_000_000, 7_000_000_000  # 20 s of log time, 50 ms apart
RATE = 20.0  # 15 s of log time after --start, replayed in 0.75 s


def _f64(x: float) -> bytes:
    return b"\x00\x01\x00\x00" + struct.pack("<d", x)


def test_replay_rate_and_start(procs, tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    w = BagWriter(bag)
    for k in range(N):
        w.write("/lubrig/displacement", "std_msgs/msg/Float64", T0 + k * STEP_NS, _f64(k))
    w.close()
    out = tmp_path / "got.json"
    first = 100  # --start 5 s = 100 steps of 50 ms
    expected = N - first
    listener = procs.module(
        "lubrig_testkit.synthetic",
        "listen",
        "--topics",
        "displacement",
        "/clock",
        "--count",
        str(2 * expected),
        "--timeout",
        "120",
        "--output",
        str(out),
    )
    listener.wait_for_output("listening")
    started_ns = time.time_ns()
    replay = procs.module(
        "lubrig_ros.nodes.replay",
        str(bag),
        "--rate",
        str(RATE),
        "--start",
        "5",
        "--clock",
        "--wait-for-subscribers",
        "60",
    )
    assert replay.wait(timeout=120) == 0, replay.log()
    assert f"published {expected} messages" in replay.output()
    assert listener.wait(timeout=120) == 0, listener.log()
    got = json.loads(out.read_text())
    data = [(t, v) for name, t, v in got if name == "/lubrig/displacement"]
    clock = [v for name, _t, v in got if name == "/clock"]
    # --start: nothing before 5 s of log time; everything after, in order
    assert [v for _t, v in data] == [float(k) for k in range(first, N)]
    # --clock: /clock carries the log time of each replayed message
    assert clock == pytest.approx([(T0 + k * STEP_NS) / 1e9 for k in range(first, N)], abs=1e-9)
    # --rate 20 scales the schedule: never ahead of it (the last message cannot arrive before
    # 14.95 s / 20 have passed, whatever the load), and far from the unscaled 14.95 s (first to
    # last message in less than half of it: a guard only a delivery stalled for seconds could trip)
    span = (expected - 1) * STEP_NS / 1e9
    assert (data[-1][0] - started_ns) / 1e9 >= span / RATE
    assert (data[-1][0] - data[0][0]) / 1e9 < span / 2
