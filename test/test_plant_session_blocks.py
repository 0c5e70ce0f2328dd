"""The plant's block path (app/plant/session.py band_block / on_block), without DDS.

A sim run fed in blocks of any length equals core.run.simulate bit for bit, one PlantBlock per
band block (the first with the initial state); segments and sample indices across resets; stale
and gappy blocks; bad values in a block; blocks in realtime mode; a failed block redone sample by
sample.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from lubrig_ros.app.plant.session import PlantBlock, PlantSample, PlantSession, PlantSettings
from lubrig_ros.core.presets import default_config, load_case
from lubrig_ros.core.run import band_samples, simulate

DURATION = 0.3  # s: 300 samples at 1 kHz


class Sink:
    def __init__(self) -> None:
        self.blocks: list[PlantBlock] = []
        self.samples: list[PlantSample] = []
        self.complete: list[bool] = []
        self.logs: list[tuple[str, str]] = []

    def session(self, config, mode="sim", per_sample=False) -> PlantSession:
        extra = {"on_sample": self.samples.append} if per_sample else {}
        return PlantSession(
            config,
            PlantSettings(mode),
            on_block=self.blocks.append,
            on_complete=self.complete.append,
            log=lambda lv, t: self.logs.append((lv, t)),
            **extra,
        )

    def column(self, name: str) -> np.ndarray:
        return np.concatenate([getattr(b, name) for b in self.blocks])


@pytest.fixture(scope="module")
def case1():
    config = load_case(1).with_overrides(duration=DURATION)
    return config, simulate(config)


def _feed_blocks(session: PlantSession, config, length: int, start: int = 0, end: int | None = None):
    end = config.samples if end is None else end
    k = start
    while k < end:
        n = min(length, end - k)
        session.band_block(band_samples(config, k, n), segment=session.segment, first_sample_index=k)
        k += n


@pytest.mark.parametrize("length", [1, 7, 100, 300, 1000])
def test_blocks_of_any_length_equal_core_simulate(case1, length):
    config, ref = case1
    sink = Sink()
    session = sink.session(config)
    _feed_blocks(session, config, length)
    assert len(sink.blocks) == math.ceil(config.samples / length)  # one output block per band block
    assert len(sink.blocks[0]) == min(length, config.samples) + 1  # the initial state first
    for name in ("displacement", "velocity", "friction_coefficient", "band_velocity", "relative_velocity"):
        assert np.array_equal(sink.column(name), getattr(ref, name)), name
    assert np.allclose(sink.column("time"), ref.time, rtol=0.0, atol=1e-12)
    n = config.rig.friction.normal_force
    assert np.array_equal(sink.column("friction_force"), ref.friction_coefficient * n)
    travel = np.concatenate([[0.0], np.cumsum(0.5 * (ref.band_velocity[1:] + ref.band_velocity[:-1]) * 1e-3)])
    assert np.allclose(sink.column("belt_travel"), travel, rtol=1e-12, atol=1e-20)
    starts = [b.first_sample_index for b in sink.blocks]
    assert starts == [0, *np.cumsum([len(b) for b in sink.blocks])[:-1].tolist()]
    assert all(b.segment == 0 and b.sample_period == 1e-3 for b in sink.blocks)
    assert session.published == config.samples + 1 and sink.complete == [True]
    assert session.index_gaps == 0 and session.stale_blocks == 0


def test_block_results_do_not_depend_on_the_block_length(case1):
    """Two block lengths give the same bits, including the belt travel."""
    config, _ = case1
    runs = []
    for length in (3, 128):
        sink = Sink()
        _feed_blocks(sink.session(config), config, length)
        runs.append({n: sink.column(n) for n in ("displacement", "belt_travel", "time")})
    for name in runs[0]:
        assert np.array_equal(runs[0][name], runs[1][name]), name


def test_per_sample_sink_gets_every_sample_with_index_and_segment(case1):
    config, ref = case1
    sink = Sink()
    session = sink.session(config, per_sample=True)
    _feed_blocks(session, config, 64)
    assert [s.sample_index for s in sink.samples] == list(range(config.samples + 1))
    assert np.array_equal([s.displacement for s in sink.samples], ref.displacement)
    assert {s.segment for s in sink.samples} == {0}


def test_values_beyond_the_end_are_ignored_and_counted(case1):
    config, _ = case1
    sink = Sink()
    session = sink.session(config)
    _feed_blocks(session, config, 100, end=config.samples + 50)
    assert session.published == config.samples + 1 and session.ignored_after_end == 50
    assert sink.complete == [True]


def test_reset_starts_a_new_segment_and_drops_stale_blocks(case1):
    config, ref = case1
    sink = Sink()
    session = sink.session(config)
    _feed_blocks(session, config, 50, end=120)
    session.reset(config)
    assert session.segment == 1 and session.published == 0 and session.sample_index == 0
    assert sink.complete == [False]
    # a block the drive sent for segment 0 before it saw the reset
    assert session.band_block(band_samples(config, 120, 50), segment=0, first_sample_index=120) == 0
    assert session.stale_blocks == 1
    sink.blocks.clear()
    _feed_blocks(session, config, 50)
    assert sink.blocks[0].first_sample_index == 0 and sink.blocks[0].segment == 1
    assert sink.blocks[0].time[0] == 0.0 and sink.blocks[0].belt_travel[0] == 0.0
    assert np.array_equal(sink.column("displacement"), ref.displacement)  # the same run again
    assert sink.complete == [False, True]
    status = {s.name: s for s in session.diagnostics()}["band input"].as_dict()
    assert status["segment"] == "1" and status["stale_blocks"] == "1"


def test_an_unexpected_first_sample_index_is_counted_and_logged(case1):
    config, _ = case1
    sink = Sink()
    session = sink.session(config)
    session.band_block(band_samples(config, 0, 10), segment=0, first_sample_index=0)
    session.band_block(band_samples(config, 20, 10), segment=0, first_sample_index=20)
    assert session.index_gaps == 1
    assert any("starts at sample 20, expected 10" in t for lv, t in sink.logs if lv == "warning")


def test_bad_values_in_a_block_are_rejected_and_the_rest_integrated(case1):
    config, _ = case1
    sink = Sink()
    session = sink.session(config)
    values = band_samples(config, 0, 10)
    values[3], values[7] = math.nan, 5.0
    assert session.band_block(values) == 8
    assert session.rejected == 2 and session.last_rejected == 5.0 and session.sample_index == 8
    assert np.isfinite(sink.column("displacement")).all()
    assert session.band_block("not numbers") == 0 and session.rejected == 3


def test_paused_blocks_wait_and_are_integrated_in_order_on_resume(case1):
    config, ref = case1
    sink = Sink()
    session = sink.session(config)
    _feed_blocks(session, config, 100, end=100)
    session.set_paused(True)
    _feed_blocks(session, config, 100, start=100, end=200)
    assert session.sample_index == 100
    session.set_paused(False)
    _feed_blocks(session, config, 100, start=200)
    assert np.array_equal(sink.column("displacement"), ref.displacement)


def test_realtime_takes_band_values_by_sample_index():
    """realtime: band values sent ahead are used for their sample index, whatever the arrival order."""
    sink = Sink()
    session = sink.session(default_config(), mode="realtime", per_sample=True)
    session.emit_initial()
    assert session.band_block([3e-7, 4e-7], segment=0, first_sample_index=2) == 2  # ahead
    assert session.band_block([1e-7, 2e-7], segment=0, first_sample_index=0) == 2
    session.band_input(9e-7)  # a Float64 changes the held value, not the indexed ones
    for _ in range(5):
        session.tick()
    assert [s.band_velocity for s in sink.samples[1:]] == [1e-7, 2e-7, 3e-7, 4e-7, 4e-7]
    assert session.held_samples == 1  # sample 5 had no value of its own: the last one held
    assert session.band_block([5e-7], segment=0, first_sample_index=1) == 1  # too late
    assert session.band_block([5e-7], segment=7, first_sample_index=6) == 0  # another segment
    assert session.stale_blocks == 1 and session.rules.late_band() == 1
    session.reset(default_config())
    session.band_block([6e-7], segment=1, first_sample_index=0)
    session.tick()
    assert sink.samples[-1].segment == 1 and sink.samples[-1].band_velocity == 6e-7


def test_rig_in_loop_uses_a_block_one_value_per_tick():
    sink = Sink()
    session = sink.session(default_config(), mode="rig_in_loop", per_sample=True)
    session.emit_initial()
    assert session.band_block([1e-7, 2e-7, 3e-7]) == 3
    for _ in range(5):
        session.tick()
    assert [s.band_velocity for s in sink.samples[1:]] == [1e-7, 2e-7, 3e-7, 3e-7, 3e-7]
    assert [s.sample_index for s in sink.samples] == list(range(6))
    session.band_block([4e-7, 5e-7])
    session.band_input(6e-7)  # a single value replaces what a block queued
    session.tick()
    assert sink.samples[-1].band_velocity == 6e-7
    session.reset(default_config())
    session.tick()
    assert sink.samples[-1].segment == 1 and sink.samples[-1].sample_index == 0


class FailingBlocks:
    """A RigIntegrator whose advance of more than one sample fails `times` times."""

    def __init__(self, integrator, times: int) -> None:
        self.inner, self.left = integrator, times

    def __getattr__(self, name):
        return getattr(self.inner, name)

    def advance(self, band):
        if np.size(band) > 1 and self.left:
            self.left -= 1
            self.inner.advance(band[: len(band) // 2])  # half done, then the failure
            raise ArithmeticError("step size collapsed")
        return self.inner.advance(band)


def test_a_failed_block_is_redone_sample_by_sample_from_its_start(case1):
    config, ref = case1
    sink = Sink()
    session = sink.session(config)
    _feed_blocks(session, config, 100, end=100)
    session.integrator = FailingBlocks(session.integrator, times=1)
    _feed_blocks(session, config, 100, start=100)
    assert np.array_equal(sink.column("displacement"), ref.displacement)  # nothing lost, no jump
    assert session.integration_errors == 0 and session.complete
