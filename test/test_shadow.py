"""Shadow mode without DDS: the pairing of measured values with samples, and a rig_in_loop session.

What is asserted is the rule of app/plant/session.py ("Shadow"): a measured value pairs with the
sample integrated with the band value of the same number, whichever comes first; rejected
measured values keep their number; held samples are not paired; a reset restarts the numbering.
The session runs its real-time loop for real (a few hundred ms); nothing about its speed is
asserted.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from lubrig_ros.app.interface import contract
from lubrig_ros.app.plant.output import PlantBlock
from lubrig_ros.app.plant.session import PlantSession, PlantSettings
from lubrig_ros.app.plant.shadow import ShadowPairing, measured_velocity
from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import band_samples, integrator_for

N = 300  # band values sent ahead (0.3 s at 1 kHz)


def test_pairs_by_number_whichever_comes_first():
    p = ShadowPairing(capacity=100)
    p.simulated(0, 1, 0.1, 0.01)  # sample first, measured after
    assert p.measured_value(0.15)
    assert p.measured_value(0.2)  # measured first (number 1), its sample after
    p.simulated(1, 2, 0.25, 0.02)
    out = p.take()
    assert out is not None and p.take() is None
    assert out.sample_index.tolist() == [1, 2]
    assert out.residual == pytest.approx([0.05, -0.05], abs=1e-15)
    assert out.residual_rms == pytest.approx([0.05, 0.05], abs=1e-15)
    assert out.measured.tolist() == [0.15, 0.2] and out.simulated.tolist() == [0.1, 0.25]
    assert out.band_velocity.tolist() == [0.01, 0.02]


def test_rejected_measured_values_keep_their_number_and_are_never_paired():
    p = ShadowPairing(capacity=100)
    for number in range(5):
        p.simulated(number, number + 1, 0.0, 0.0)
    assert p.measured_value(0.75)
    assert not p.measured_value(math.nan)
    assert not p.measured_value(math.inf)
    assert not p.measured_value(1e200)  # beyond MEASURED_LIMIT: its square would overflow the RMS
    assert p.measured_value(0.5)
    out = p.take()
    assert out is not None
    assert out.sample_index.tolist() == [1, 5]  # numbers 0 and 4
    assert out.measured.tolist() == [0.75, 0.5]
    assert out.rejected == 3 and p.last_rejected == 1e200
    assert np.isfinite(out.residual_rms).all()
    assert out.residual_rms[-1] == pytest.approx(math.sqrt((0.75**2 + 0.5**2) / 2))


def test_values_without_a_partner_are_dropped_after_capacity_numbers():
    p = ShadowPairing(capacity=10)
    for number in range(30):  # the measured values of numbers 0..29 never come
        p.simulated(number, number, 0.0, 0.0)
    assert len(p.simulated_by_number) <= 10 and p.unpaired == 20
    p.reset(segment=1)
    assert p.unpaired == 0 and p.measured_count == 0 and p.segment == 1


def test_measured_velocity_differences_consecutive_samples_only():
    index = np.array([5, 6, 7, 9, 10])
    x = np.array([0.0, 1.0, 3.0, 4.0, 4.5])
    v = measured_velocity(index, x, 0.5, previous=(4, -1.0))
    assert v.tolist() == [2.0, 2.0, 4.0, 0.0, 1.0]
    assert measured_velocity(index, x, 0.5, previous=None)[0] == 0.0


class Sink:
    def __init__(self) -> None:
        self.blocks: list[PlantBlock] = []
        self.on_block_hook = None

    def on_block(self, block: PlantBlock) -> None:
        self.blocks.append(block)
        if self.on_block_hook is not None:
            self.on_block_hook(block)


def _session(config, sink: Sink, **settings) -> PlantSession:
    return PlantSession(config, PlantSettings("rig_in_loop", **settings), on_block=sink.on_block)


def _run(session: PlantSession, count: int, limit: float = 30.0) -> None:
    end = time.monotonic() + limit
    session.run_realtime(lambda: session.published > count or time.monotonic() > end)


@pytest.fixture(scope="module")
def rig():
    config = load_case(4).with_overrides(duration=N / 1000, initial_perturbation=0.0)
    band = band_samples(config, 0, N)
    # the rig's displacement after each band value: the same integrator from the same start
    x = integrator_for(config).advance(band).displacement
    return config, band, x


@pytest.mark.parametrize("measured_first", [True, False])
def test_session_pairs_the_band_sent_ahead_with_its_measured_values(rig, measured_first):
    config, band, x = rig
    offset = 1e-9 * np.sin(np.arange(N) / 7.0)  # what the "real rig" does beyond the model
    sink = Sink()
    session = _session(config, sink, shadow=True, max_lag=10.0)  # no skip whatever the load
    session.band_block(band, segment=0, first_sample_index=0)
    measured = (x + offset).tolist()
    if measured_first:
        for value in measured:
            session.measured_input(value)
    else:  # each measured value after its sample, as a real rig's (numbers: the band's)
        sent = [0]

        def answer(block: PlantBlock) -> None:
            last = block.first_sample_index + len(block) - 1  # sample k used band value k - 1
            while sent[0] < min(last, N):
                session.measured_input(measured[sent[0]])
                sent[0] += 1

        sink.on_block_hook = answer
    _run(session, N)
    pairs = []
    while (taken := session.shadow_take()) is not None:
        pairs.append(taken)
    index = np.concatenate([p.sample_index for p in pairs])
    residual = np.concatenate([p.residual for p in pairs])
    simulated = np.concatenate([p.simulated for p in pairs])
    assert index.tolist() == list(range(1, len(index) + 1))  # every sample but the initial state
    assert len(index) >= N - 25  # the last block's answers may come after the loop stopped
    # the simulated side is the plant's published displacement of the same sample
    published = {
        b.first_sample_index + i: v for b in sink.blocks for i, v in enumerate(b.columns["displacement"])
    }
    assert simulated.tolist() == [published[k] for k in index.tolist()]
    np.testing.assert_allclose(residual, offset[index - 1], rtol=0, atol=1e-18)
    rms = np.concatenate([p.residual_rms for p in pairs])
    assert rms[-1] == pytest.approx(np.sqrt(np.mean(offset[index - 1] ** 2)), rel=1e-12)
    status = session.diagnostics()[-1]
    assert status.name == "shadow" and status.as_dict()["paired"] == str(len(index))


def test_float64_band_values_are_numbered_rejected_ones_included(rig):
    config, band, x = rig
    sink = Sink()
    session = _session(config, sink, shadow=True, max_lag=10.0)
    # one value before the loop starts: number 0; a rejected one: number 1 (never integrated)
    session.band_input(float(band[0]))
    session.band_input(math.nan)
    session.measured_input(float(x[0]) + 1e-9)
    session.measured_input(0.5)  # answers the rejected band value: never paired
    _run(session, 5)
    pairs = session.shadow_take()
    assert pairs is not None and pairs.sample_index.tolist() == [1]
    assert pairs.residual[0] == pytest.approx(1e-9, abs=1e-18)


def test_without_shadow_the_rules_are_the_plain_wall_clock_ones(rig):
    config, _, _ = rig
    session = _session(config, Sink())
    assert type(session.rules).__name__ == "WallClockRules"
    assert not session.measured_input(1.0) and session.shadow_take() is None
    assert [s.name for s in session.diagnostics()] == ["timing", "band input"]
    with pytest.raises(ValueError, match="shadow"):
        PlantSettings("rig_in_loop", shadow="yes")  # type: ignore[arg-type]


def test_a_reset_restarts_the_numbering_and_the_rms(rig):
    config, band, x = rig
    session = _session(config, Sink(), shadow=True, max_lag=10.0)
    session.band_block(band[:50], segment=0, first_sample_index=0)
    for value in x[:50]:
        session.measured_input(float(value) + 1e-6)  # a large residual in segment 0
    _run(session, 60)
    first = session.shadow_take()
    assert first is not None and first.segment == 0 and first.residual_rms[-1] == pytest.approx(1e-6)
    session.reset(config)
    session.band_block(band[:50], segment=1, first_sample_index=0)  # the rig numbers from 0 again
    for value in x[:50]:
        session.measured_input(float(value))
    _run(session, 60)
    again = session.shadow_take()
    assert again is not None and again.segment == 1
    assert again.sample_index.tolist() == list(range(1, 51))
    # (the plant restarts at equilibrium for the band value it held, the rig's x from band[0]'s:
    # a residual of a few nm, but its RMS is the new segment's alone, not segment 0's 1e-6 m)
    np.testing.assert_array_equal(again.residual, again.measured - again.simulated)
    assert again.residual_rms[-1] == pytest.approx(np.sqrt(np.mean(again.residual**2)), rel=1e-12)
    assert again.residual_rms[-1] < 1e-7


def test_the_shadow_topics_are_contract_topics_recorded_from_a_rig_in_loop_plant():
    recorded = contract.recorded_topics("rig_in_loop")
    for name in contract.SHADOW_TOPICS:
        spec = contract.topic(name)  # KeyError if not in the contract
        # the measured input is one message per sample: its values are recorded in shadow_block
        assert (name in recorded) == (name not in contract.PER_SAMPLE_TOPICS), spec
