"""The wall-clock plant session without DDS: blocks, band sent ahead, falling behind, lockstep.

`run_realtime` runs for real here (absolute sleeps at 1 kHz, a few hundred ms per test); what is
asserted is what it emits, never how fast: every sample once and in order, in blocks of
output_block_length with its lateness, values equal to core.run.simulate of the same band
sequence, and, when a sink stalls the loop past max_lag, the declared gap (skip) or the fault (stop).
"""

from __future__ import annotations

import re
import time

import numpy as np
import pytest

from lubrig_ros.app.plant.output import PlantBlock, PlantSample
from lubrig_ros.app.plant.session import PlantSession, PlantSettings
from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import band_samples, simulate

N = 400  # band samples sent ahead (0.4 s at 1 kHz)


@pytest.fixture(scope="module")
def case1():
    config = load_case(1).with_overrides(duration=N / 1000)
    return config, band_samples(config, 0, config.samples), simulate(config)


class Sink:
    """What the session emits; `stall` sleeps once in on_sample, at the first sample from that index.

    (From, not at: on a loaded machine the loop may already have fallen behind and skipped the
    very index.)
    """

    def __init__(self, stall: int | None = None, seconds: float = 0.08) -> None:
        self.samples: list[PlantSample] = []
        self.blocks: list[PlantBlock] = []
        self.logs: list[tuple[str, str]] = []
        self.faults: list[str] = []
        self.stall, self.seconds = stall, seconds

    def on_sample(self, s: PlantSample) -> None:
        self.samples.append(s)
        if self.stall is not None and s.sample_index >= self.stall and s.segment == 0:
            self.stall = None
            time.sleep(self.seconds)  # the loop thread is held: its next samples are late

    def session(self, config, mode="realtime", **settings) -> PlantSession:
        return PlantSession(
            config,
            PlantSettings(mode, **settings),
            on_sample=self.on_sample,
            on_block=self.blocks.append,
            on_fault=self.faults.append,
            log=lambda level, text: self.logs.append((level, text)),
        )


def _run_until(session: PlantSession, sink: Sink, count: int, limit: float = 30.0) -> None:
    end = time.monotonic() + limit
    session.run_realtime(
        lambda: len(sink.samples) >= count or time.monotonic() > end or session.fault is not None
    )


def _indices(blocks: list[PlantBlock]) -> list[int]:
    return [b.first_sample_index + i for b in blocks for i in range(len(b))]


def test_band_sent_ahead_gives_the_simulation_in_blocks_with_lateness(case1):
    config, band, ref = case1
    sink = Sink()
    session = sink.session(config, max_lag=10.0)  # no skip whatever the machine's load
    session.band_block(band, segment=0, first_sample_index=0)  # all of it ahead
    _run_until(session, sink, 301)
    # the initial state alone, then blocks of output_block_length (20), the last one flushed at stop
    assert len(sink.blocks[0]) == 1 and sink.blocks[0].first_sample_index == 0
    assert {len(b) for b in sink.blocks[1:-1]} == {20}
    indices = _indices(sink.blocks)
    assert indices == list(range(len(indices))) == [s.sample_index for s in sink.samples]
    assert all(b.skipped == 0 for b in sink.blocks)
    lateness = np.concatenate([b.lateness for b in sink.blocks])
    assert lateness.size == len(indices) and np.all(lateness >= 0) and np.all(np.isfinite(lateness))
    # sample k used band index k - 1: bit for bit core.run.simulate of the same band sequence
    x = np.concatenate([b.displacement for b in sink.blocks])
    assert np.array_equal(x, ref.displacement[: x.size])
    assert np.array_equal([s.displacement for s in sink.samples], x)
    assert session.held_samples == 0 and session.held_real_time


@pytest.mark.parametrize("stall", [0.08, 0.3])
def test_falling_behind_skips_declares_the_gap_and_keeps_the_physics(case1, stall):
    config, band, ref = case1
    sink = Sink(stall=40, seconds=stall)
    session = sink.session(config, max_lag=0.02, lag_policy="skip")
    session.band_block(band, segment=0, first_sample_index=0)
    _run_until(session, sink, 200)
    assert sink.stall is None  # the stall happened
    assert not session.held_real_time and session.skipped > 0 and session.skip_events >= 1
    # the overdue samples (about the stall, 1 per ms) are never emitted; the block after them says so
    gapped = [b for b in sink.blocks if b.skipped]
    assert sum(b.skipped for b in gapped) == session.skipped
    assert session.skipped >= round(stall * 1000) - 25
    emitted = _indices(sink.blocks)
    assert emitted == sorted(set(emitted)) == [s.sample_index for s in sink.samples]
    first = gapped[0]
    before = [i for i in emitted if i < first.first_sample_index]
    assert first.first_sample_index - first.skipped == before[-1] + 1  # exactly the gap declared
    # the skipped interval was integrated with the band values sent for it: every emitted sample
    # is still the simulation's own
    x = {s.sample_index: s.displacement for s in sink.samples}
    assert all(x[i] == ref.displacement[i] for i in emitted if i < ref.displacement.size)
    errors = [text for level, text in sink.logs if level == "error"]
    assert errors and "fell behind real time" in errors[0] and "max_lag 20 ms" in errors[0]
    timing = {s.name: s for s in session.diagnostics()}["timing"]
    assert timing.level == "error" and "skipped" in timing.message
    values = timing.as_dict()
    assert values["skipped_samples"] == str(session.skipped) and values["held_real_time"] == "false"


def test_falling_behind_with_stop_faults_once_and_a_reset_recovers(case1):
    config, band, _ = case1
    sink = Sink(stall=30, seconds=0.1)
    session = sink.session(config, max_lag=0.02, lag_policy="stop")
    session.band_block(band, segment=0, first_sample_index=0)
    _run_until(session, sink, 10_000, limit=10.0)  # ends at the fault
    assert len(sink.faults) == 1 and "could not hold real time" in sink.faults[0]
    assert "lag_policy stop" in sink.faults[0] and not session.held_real_time
    emitted = [s.sample_index for s in sink.samples]
    # nothing after the sample that started late: the stall's next one (or, on a loaded machine,
    # an earlier one that came late anyway)
    late = int(re.search(r"sample (\d+) of segment 0 started", sink.faults[0]).group(1))
    assert emitted == list(range(late)) and late <= 31, (late, emitted[-3:])
    assert _indices(sink.blocks) == emitted  # what was buffered was flushed, nothing more
    timing = {s.name: s for s in session.diagnostics()}["timing"]
    assert timing.level == "error" and timing.message == session.fault
    # a reset clears the fault: segment 1 from sample 0
    session.reset(config)
    session.band_block(band, segment=1, first_sample_index=0)
    seen = len(sink.samples)
    session.run_realtime(lambda: len(sink.samples) >= seen + 50)
    new = [s for s in sink.samples[seen:]]
    assert new[0].segment == 1 and [s.sample_index for s in new] == list(range(len(new)))


def test_lockstep_one_sample_per_band_value_and_repeats_dropped(case1):
    config, band, ref = case1
    sink = Sink()
    session = sink.session(config, mode="lockstep")
    session.emit_initial()  # at once: the rig software answers it
    assert [s.sample_index for s in sink.samples] == [0]
    for k in range(50):
        assert session.band_block(band[k : k + 1], segment=0, first_sample_index=k) == 1
        if k % 10 == 3:  # the answer to a repeated state: dropped by its index
            assert session.band_block(band[k : k + 1], segment=0, first_sample_index=k) == 0
    assert [s.sample_index for s in sink.samples] == list(range(51))
    assert np.array_equal([s.displacement for s in sink.samples], ref.displacement[:51])
    assert session.repeated_blocks == 5 and session.index_gaps == 0
    assert session.round_trips.count == 50
    values = {s.name: s for s in session.diagnostics()}["timing"].as_dict()
    assert values["round_trips"] == "50" and values["mode"] == "lockstep"


def test_settings_of_the_lag_rule_are_checked():
    for bad in (
        {"lag_policy": "drift"},
        {"max_lag": 0.0},
        {"max_lag": float("nan")},
        {"output_block_length": 0},
    ):
        with pytest.raises(ValueError, match=next(iter(bad))):
            PlantSettings("realtime", **bad)


@pytest.mark.parametrize("mode", ["realtime", "rig_in_loop"])
def test_a_reset_holding_a_band_at_rest_in_all_but_name_restarts_at_rest(case1, mode):
    """A held band value 0 < |v| below the integrator's resolution (e.g. -5e-324, a parameter
    fuzz's) is a band at rest: a reset restarts there, with a warning, instead of raising."""
    config, _, _ = case1
    sink = Sink()
    session = sink.session(config, mode, max_lag=10.0)
    session.band_input(-5e-324)  # a good value for the input check (finite, within the limit)
    session.latest_band = -5e-324  # held (realtime takes indexed values; the held one is this)
    session.reset(config)
    assert session.integrator.current().band_velocity[0] == 0.0
    assert session.integrator.current().displacement[0] == 0.0  # equilibrium at rest: μ(0) = 0
    assert any(level == "warning" and "restarted at rest" in text for level, text in sink.logs)
