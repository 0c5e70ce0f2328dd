"""app/belt_session.py: the belt_drive's profile, its updates and its schedules, without ROS."""

from __future__ import annotations

import numpy as np
import pytest

from lubrig_ros.app.belt_session import AheadSchedule, ProfileState, SimSchedule
from lubrig_ros.app.flow import FlowGate
from lubrig_ros.app.selection import base_config
from lubrig_ros.core.params import ParameterError

PLANT, RECORDER = "/lubrig/plant", "/lubrig/lubrig_recorder"
RATE = 1000.0


def _profile(duration: float = 1.0, limit: float = 1e-3) -> ProfileState:
    config = base_config(case=1)
    state = ProfileState(config.band, RATE, duration, limit)
    state.start({"kind": config.band.kind})
    return state


def test_samples_are_the_profile_at_k_over_the_rate() -> None:
    state = _profile()
    k = np.arange(5, 11)
    np.testing.assert_array_equal(state.samples(5, 10), np.asarray(state.profile(k / RATE), dtype=float))


def test_an_update_is_taken_whole_or_refused_with_its_reason_and_no_trace() -> None:
    state = _profile()
    before = state.profile
    fields = state.parameters.flat()
    numeric = next(name for name, value in fields.items() if not isinstance(value, str))
    assert (
        state.update({numeric: "fast"}) == f"profile.{numeric}='fast' is not valid; expected a finite number"
    )
    assert state.update({numeric: float("nan")}) is not None
    assert state.update({"kind": 3}) == "profile.kind=3 is not valid; expected a string"
    assert state.update({"kind": "no_such_kind"}) is not None
    assert state.profile is before and state.parameters.flat() == fields  # nothing changed
    config = base_config(case=1)
    tight = ProfileState(config.band, RATE, 1.0, 1e-30)  # a band_velocity_limit no profile meets
    with pytest.raises(ParameterError, match="above the plant's band_velocity_limit"):
        tight.start({"kind": config.band.kind})


def test_sim_schedule_sends_in_order_within_the_gate_and_restarts_per_segment() -> None:
    state = _profile(duration=1.0)
    gate = FlowGate(300, PLANT, (RECORDER,))
    sim = SimSchedule(gate, RATE, 1.0, block_length=128)
    assert sim.blocks(state) == []  # the plant has not reported
    origin = 7_000_000_000  # the plant's clock: segment 0 starts 7 s into it
    assert sim.progress(PLANT, 0, 0, origin) and sim.progress(RECORDER, 0, 0, 0)
    sim.restarted()
    blocks = sim.blocks(state)
    indices = np.concatenate(
        [np.arange(b.first_sample_index, b.first_sample_index + b.band_velocity.size) for b in blocks]
    )
    assert indices.tolist() == list(range(indices.size)) and indices.size <= 300 + 1
    assert all(b.band_velocity.size <= 128 for b in blocks)
    assert [b.stamp_ns for b in blocks] == [round(b.first_sample_index + 1) * 1_000_000 for b in blocks]
    # the consumers took everything: the rest of the run goes out, never beyond N = 1000
    sim.progress(PLANT, 0, indices.size + 1, origin + indices.size * 1_000_000)
    sim.progress(RECORDER, 0, indices.size + 1, 0)
    for _ in range(10):
        blocks += sim.blocks(state)
        sim.progress(PLANT, 0, sim.next_k, origin)
        sim.progress(RECORDER, 0, sim.next_k, 0)
    assert sim.done and sum(b.band_velocity.size for b in blocks) == 1000
    # a plant reset: segment 1, profile from t = 0 again, stamped on the plant's running clock
    later = 30_000_000_000
    sim.progress(PLANT, 1, 0, later)
    sim.progress(RECORDER, 1, 0, 0)
    assert sim.restarted() == 1 and not sim.done
    first = sim.blocks(state)[0]
    assert (first.segment, first.first_sample_index, first.stamp_ns) == (1, 0, later + 1_000_000)
    np.testing.assert_array_equal(first.band_velocity, state.samples(1, first.band_velocity.size))


def test_ahead_schedule_keeps_lookahead_every_index_once_in_order() -> None:
    state = _profile()
    ahead = AheadSchedule(PLANT, RATE, lookahead=40)
    assert ahead.progress("/other/plant", 0, 0, 0, state) is None  # another node's progress
    due = 1_800_000_000 * 1_000_000_000
    first = ahead.progress(PLANT, 0, 1, due, state)
    assert first is not None and (first.first_sample_index, first.band_velocity.size) == (0, 40)
    assert first.stamp_ns == due + 1_000_000  # band index 0 integrates plant sample 1, due 1 ms on
    assert ahead.progress(PLANT, 0, 1, due, state) is None  # nothing new needed
    second = ahead.progress(PLANT, 0, 21, due + 20_000_000, state)
    assert second is not None and second.first_sample_index == 40 and second.band_velocity.size == 20
    assert second.stamp_ns == due + 41_000_000  # index 40 → plant sample 41, 21 after sample 20
    np.testing.assert_array_equal(second.band_velocity, state.samples(41, 60))
    reset = ahead.progress(PLANT, 1, 1, due + 5_000_000_000, state)
    assert ahead.restarted_segment == 1 and reset is not None and reset.first_sample_index == 0
