"""Sim: a run that cannot progress is reported as stalled (timing ERROR), and recovers (issue 11)."""

from __future__ import annotations

from lubrig_ros.app.plant.session import STALL_S, PlantSession, PlantSettings
from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import band_samples


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def _timing(session: PlantSession):
    return {s.name: s for s in session.diagnostics()}["timing"]


def test_no_band_sample_for_longer_than_the_stall_time_is_an_error_that_clears():
    config = load_case(1).with_overrides(duration=1.0)
    clock = Clock()
    session = PlantSession(config, PlantSettings("sim"), on_block=lambda b: None, clock=clock)
    assert _timing(session).level == "ok"  # not started: waiting is not a stall
    session.band_block(band_samples(config, 0, 100), segment=0, first_sample_index=0)
    clock.now += STALL_S * 0.9
    assert _timing(session).level == "ok"
    clock.now += STALL_S * 0.2  # beyond the stall time, 100 of 1000 samples done
    status = _timing(session)
    assert status.level == "error"
    assert status.message.startswith("stalled: no band sample for 1.1 s at rig time 0.100 s (100 of 1000")
    session.band_block(band_samples(config, 100, 100), segment=0, first_sample_index=100)  # flowing
    assert _timing(session).level == "ok"
    session.set_paused(True)
    clock.now += 10 * STALL_S
    assert _timing(session).level == "ok"  # paused on purpose: not a stall
