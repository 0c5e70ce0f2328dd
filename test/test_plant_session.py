"""The plant's rules (app/plant/session.py) in all three modes, without DDS.

Sim sequencing equals core.run.simulate bit for bit; band input rejection, hold and staleness;
pause/reset; a failed sample restarts the rig at the next sample time; timing statistics;
configuration rebuild from parameters; diagnostics as plain data.
"""

from __future__ import annotations

import math
import struct
import time

import numpy as np
import pytest

from lubrig_ros.app.interface import cdr
from lubrig_ros.app.plant.session import (
    CONFIG_PARAMETERS,
    RUNTIME_PARAMETERS,
    PlantSample,
    PlantSession,
    PlantSettings,
    config_from,
    parameter_defaults,
)
from lubrig_ros.core.params import ParameterError
from lubrig_ros.core.presets import default_config, load_case
from lubrig_ros.core.run import band_samples, integrator_for, simulate
from lubrig_ros.core.trajectory import Trajectory

DURATION = 0.3  # s: 300 samples at 1 kHz


class FakeClock:
    """A settable clock for staleness and latency (seconds)."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


class Recorder:
    """Collects what the session hands to its sinks."""

    def __init__(self) -> None:
        self.samples: list[PlantSample] = []
        self.complete: list[bool] = []
        self.logs: list[tuple[str, str]] = []
        self.failures: list[str] = []

    def session(self, config, mode="sim", clock=None, **settings) -> PlantSession:
        return PlantSession(
            config,
            PlantSettings(mode, **settings),
            on_sample=self.samples.append,
            on_complete=self.complete.append,
            on_failure=self.failures.append,
            log=lambda level, text: self.logs.append((level, text)),
            clock=clock or FakeClock(),
        )

    def column(self, name: str) -> np.ndarray:
        return np.array([getattr(s, name) for s in self.samples])


@pytest.fixture(scope="module")
def case1():
    config = load_case(1).with_overrides(duration=DURATION)
    return config, simulate(config)


def _feed(session: PlantSession, config, start: int, count: int) -> None:
    for value in band_samples(config, start, count):
        session.band_input(float(value))


def _assert_equal_run(rec: Recorder, ref: Trajectory) -> None:
    # rig time accumulates sample by sample (the plant's stamps), so it matches to rounding only;
    # the state itself is bit-identical
    assert np.allclose(rec.column("time"), ref.time, rtol=0.0, atol=1e-12)
    assert np.array_equal(rec.column("displacement"), ref.displacement)
    assert np.array_equal(rec.column("velocity"), ref.velocity)
    assert np.array_equal(rec.column("friction_coefficient"), ref.friction_coefficient)
    assert np.array_equal(rec.column("band_velocity"), ref.band_velocity)


def test_sim_sequencing_is_bit_identical_to_core_simulate(case1):
    config, ref = case1
    rec = Recorder()
    session = rec.session(config)
    _feed(session, config, 0, config.samples)
    assert len(rec.samples) == config.samples + 1  # the initial state, then one per band value
    _assert_equal_run(rec, ref)
    assert rec.complete == [True]
    assert session.complete and ("info", f"sim: run complete at t = {session.time:g} s") in rec.logs
    # belt travel: trapezoid integral of the band velocity; friction force μ·N
    dt = 1.0 / config.sample_rate
    travel = np.concatenate([[0.0], np.cumsum(0.5 * (ref.band_velocity[1:] + ref.band_velocity[:-1]) * dt)])
    assert np.allclose(rec.column("belt_travel"), travel, rtol=1e-12, atol=1e-20)
    n = config.rig.friction.normal_force
    assert np.array_equal(rec.column("friction_force"), ref.friction_coefficient * n)


def test_sim_values_after_the_end_are_ignored_and_counted(case1):
    config, _ = case1
    rec = Recorder()
    session = rec.session(config)
    _feed(session, config, 0, config.samples + 5)
    assert len(rec.samples) == config.samples + 1
    assert session.ignored_after_end == 5
    assert rec.complete == [True]  # completion is reported once
    band = {s.name: s for s in session.diagnostics()}["band input"].as_dict()
    assert band["ignored_after_run_end"] == "5"


def test_sim_pause_queues_and_resume_integrates_in_order(case1):
    config, ref = case1
    rec = Recorder()
    session = rec.session(config)
    _feed(session, config, 0, 100)
    assert session.set_paused(True) == "paused"
    _feed(session, config, 100, 50)
    assert len(rec.samples) == 101  # nothing integrated while paused
    assert session.set_paused(False) == "running"
    assert len(rec.samples) == 151  # the queued samples, in order
    _feed(session, config, 150, config.samples - 150)
    _assert_equal_run(rec, ref)


def test_sim_reset_starts_over_at_t0_with_the_new_configuration(case1):
    config, ref = case1
    rec = Recorder()
    session = rec.session(config)
    _feed(session, config, 0, 120)
    session.reset(config)
    assert rec.complete == [False] and session.time == 0.0 and not session.complete
    rec.samples.clear()
    _feed(session, config, 0, config.samples)
    _assert_equal_run(rec, ref)  # the same run again from t = 0, initial state first
    assert rec.samples[0].belt_travel == 0.0
    # a reset with other rig parameters integrates those
    damped = config_from(config, {"rig.damping_ratio": 0.05})
    session.reset(damped)
    rec.samples.clear()
    _feed(session, config, 0, config.samples)
    _assert_equal_run(rec, simulate(damped))


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, 1.0, -5.0, 0.0100001, 3])
def test_bad_band_values_are_rejected_in_sim(case1, bad):
    config, _ = case1
    rec = Recorder()
    session = rec.session(config)
    _feed(session, config, 0, 10)
    assert session.band_input(bad) is False
    assert session.sample_index == 10 and len(rec.samples) == 11  # not integrated
    _feed(session, config, 10, config.samples - 10)  # the run goes on undisturbed
    assert session.complete and session.rejected == 1
    status = {s.name: s for s in session.diagnostics()}["band input"]
    assert status.level == "warn" and "1 bad band value(s) rejected" in status.message
    values = status.as_dict()
    assert values["rejected"] == "1" and values["last_rejected_value"] == repr(bad)
    again = {s.name: s for s in session.diagnostics()}["band input"]
    assert again.level == "ok" and again.as_dict()["rejected_since_last_report"] == "0"


def test_the_limit_itself_is_accepted():
    rec = Recorder()
    session = rec.session(default_config(), mode="rig_in_loop", band_velocity_limit=1e-2)
    assert session.band_input(1e-2) and session.band_input(-1e-2)
    assert not session.band_input(np.nextafter(1e-2, 1.0))


@pytest.mark.parametrize("mode", ["realtime", "rig_in_loop"])
def test_realtime_holds_the_last_good_value(mode):
    rec = Recorder()
    clock = FakeClock()
    session = rec.session(default_config(), mode=mode, clock=clock)
    session.emit_initial()
    session.band_input(2e-7)
    session.tick()
    for bad in (math.nan, -5.0, math.inf):
        session.band_input(bad)
        session.tick()
    session.tick()  # no input at all
    assert [s.band_velocity for s in rec.samples[1:]] == [2e-7] * 5
    times = rec.column("time")
    assert np.allclose(np.diff(times), 1e-3) and times[0] == 0.0
    assert session.rejected == 3 and session.received == 4
    assert all(math.isfinite(s.displacement) for s in rec.samples)


def test_a_sample_over_the_tick_budget_is_an_overrun_finished_at_later_ticks():
    # rig in the loop: the sign change of issue 11's sequence needs tens of substeps in the
    # physical convention; with 2 attempts per tick it spans several ticks, none of which blocks
    config = default_config().with_overrides(convention="physical")
    rec, ref = Recorder(), Recorder()
    bounded = rec.session(config, mode="rig_in_loop", tick_step_attempts=2)
    unbounded = ref.session(config, mode="rig_in_loop", tick_step_attempts=1_000_000)
    sequence = [1e-7, -1e-7, 1e-7, 5e-324, 1e-7]
    for session in (bounded, unbounded):
        session.emit_initial()
    for value in sequence:
        bounded.band_input(value)
        unbounded.band_input(value)
        unbounded.tick()
        ticks = 0
        while len(rec.samples) < len(ref.samples):
            before = bounded.integrator.substeps
            bounded.tick()
            assert bounded.integrator.substeps - before <= 2
            ticks += 1
            assert ticks < 10_000
    assert unbounded.overruns == 0 and bounded.overruns > 0
    assert bounded.ticks == unbounded.ticks == len(sequence)
    assert [s.displacement for s in rec.samples] == [s.displacement for s in ref.samples]
    assert [s.band_velocity for s in rec.samples[1:]] == sequence
    assert [s.sample_index for s in rec.samples] == list(range(len(sequence) + 1))
    timing = {s.name: s for s in bounded.diagnostics()}["timing"]
    assert timing.level == "warn" and "tick overrun" in timing.message
    assert timing.as_dict()["tick_overruns"] == str(bounded.overruns)
    again = {s.name: s for s in bounded.diagnostics()}["timing"]
    assert "overrun" not in again.message  # counted since the last report


def test_the_realtime_loop_retries_an_overrun_tick_and_loses_no_sample():
    config = default_config().with_overrides(convention="physical")
    rec = Recorder()
    # max_lag far beyond this run's lateness: the overrun rule alone (falling behind: below)
    session = rec.session(
        config, mode="rig_in_loop", clock=time.perf_counter, tick_step_attempts=1, max_lag=10.0
    )
    session.band_input(2e-8)  # sticking: several substeps per sample
    session.run_realtime(lambda: len(rec.samples) >= 60)
    assert session.overruns > 0
    assert [s.sample_index for s in rec.samples] == list(range(len(rec.samples)))
    integ = integrator_for(config)
    expected = integ.advance(np.full(len(rec.samples) - 1, 2e-8))
    assert np.array_equal(rec.column("displacement")[1:], expected.displacement)


def test_a_reset_drops_the_sample_in_progress():
    config = default_config().with_overrides(convention="physical")
    rec = Recorder()
    session = rec.session(config, mode="rig_in_loop", tick_step_attempts=1)
    session.emit_initial()
    session.band_input(-1e-7)
    session.tick()
    assert session.integrator.in_progress and session.overruns == 1
    session.reset(config)
    assert not session.integrator.in_progress
    session.band_input(1e-7)
    session.tick()
    session.tick()  # no sample of the old segment is emitted after the reset
    assert all(s.segment == 1 for s in rec.samples[2:]) and rec.samples[-1].band_velocity == 1e-7


def test_staleness_follows_the_input_age():
    clock = FakeClock()
    rec = Recorder()
    session = rec.session(default_config(), mode="rig_in_loop", clock=clock, stale_timeout=0.05)

    def band() -> dict[str, str]:
        return {s.name: s for s in session.diagnostics()}["band input"].as_dict()

    values = band()  # no input yet: waiting, not stale (no warning before the rig could run)
    assert not session.stale() and values["input_age_s"] == "none"
    assert values["_message"] == "waiting for band input"
    session.band_input(1e-7)
    clock.now += 0.04
    assert not session.stale() and band()["stale"] == "false"
    clock.now += 0.02  # 0.06 s > stale_timeout
    values = band()
    assert values["stale"] == "true" and "stale input, holding last good value" in values["_message"]
    assert values["held_band_velocity_m_s"] == repr(1e-7)
    session.band_input(math.nan)  # a rejected value does not refresh the input
    assert session.stale()
    session.set_paused(True)
    assert not session.stale()  # a paused rig is not starved
    session.set_paused(False)
    session.band_input(1.5e-7)
    assert not session.stale()


def test_realtime_input_sent_ahead_is_stale_only_once_the_plant_holds():
    """realtime: band values come in blocks ahead of their samples; in hand, they are not stale."""
    clock = FakeClock()
    rec = Recorder()
    session = rec.session(default_config(), mode="realtime", clock=clock, stale_timeout=0.05)
    session.emit_initial()
    assert session.band_block([1e-7] * 200, segment=0, first_sample_index=0) == 200
    for _ in range(150):  # 0.15 s after the block came, its values still in hand
        clock.now += 0.001
        session.tick()
    assert not session.stale() and session.held_samples == 0
    for _ in range(100):  # the values run out at sample 200: the plant holds from then
        clock.now += 0.001
        session.tick()
    assert session.held_samples == 50 and session.stale()
    status = {s.name: s for s in session.diagnostics()}["band input"].as_dict()
    assert "stale input, holding last good value" in status["_message"]


def test_sim_is_never_stale(case1):
    config, _ = case1
    session = Recorder().session(config, clock=FakeClock())
    assert not session.stale()


def test_timing_statistics_latency_and_deadline_misses():
    clock = FakeClock()
    rec = Recorder()
    session = rec.session(default_config(), mode="rig_in_loop", clock=clock)
    period = session.period
    session.band_input(1e-7)
    clock.now += 0.0005
    session.tick(deadline=clock.now, late=0.0)  # on time, new input 0.5 ms old
    session.tick(deadline=clock.now, late=0.0)  # no new input: no latency sample
    session.tick(deadline=clock.now - 3 * period, late=2 * period)  # finished 3 periods late
    assert session.ticks == 3 and session.misses == 1 and session.latencies.count == 1
    p50, _ = session.latencies.percentiles()
    assert 0.0005 <= p50 <= 0.0005 + 2e-5
    timing = {s.name: s for s in session.diagnostics()}["timing"]
    values = timing.as_dict()
    assert values["deadline_misses"] == "1" and values["samples"] == "3"
    assert float(values["max_lateness_s"]) == pytest.approx(3 * period)  # finished 3 periods late
    assert float(values["lag_s"]) == pytest.approx(3 * period)  # the newest sample
    assert timing.level == "warn" and timing.message == "1 deadline misses in 3 samples"


def test_realtime_reset_and_resume_restart_the_clock():
    rec = Recorder()
    session = rec.session(default_config(), mode="realtime")
    session.band_input(3e-7)
    for _ in range(5):
        session.tick()
    assert not session.take_restart_clock()
    session.reset(default_config())
    assert session.take_restart_clock() and not session.take_restart_clock()
    assert session.time == 0.0 and rec.complete == [False]
    session.tick()
    assert rec.samples[-1].band_velocity == 3e-7  # starts from the band value it holds
    assert rec.samples[-1].belt_travel == 0.0
    session.set_paused(True)
    assert not session.take_restart_clock()
    session.set_paused(False)
    assert session.take_restart_clock()


class FailingOnce:
    """Wraps a RigIntegrator so that its next advance fails (raises, or returns NaN)."""

    def __init__(self, integrator, how: str) -> None:
        self.inner, self.how, self.armed = integrator, how, True

    def __getattr__(self, name):
        return getattr(self.inner, name)

    def advance(self, band):
        if self.armed:
            self.armed = False
            if self.how == "raise":
                raise ArithmeticError("Newton did not converge")
            traj = self.inner.advance(band)
            return Trajectory(
                traj.time,
                traj.displacement * np.nan,
                traj.velocity,
                traj.friction_coefficient,
                traj.band_velocity,
                traj.relative_velocity,
            )
        return self.inner.advance(band)

    def advance_bounded(self, band, max_attempts):
        return self.advance([band]).sample(0)


@pytest.mark.parametrize("how", ["raise", "nan"])
def test_a_failed_sample_ends_the_run_and_nothing_is_made_up(case1, how):
    config, ref = case1
    rec = Recorder()
    session = rec.session(config)
    _feed(session, config, 0, 50)
    session.integrator = FailingOnce(session.integrator, how)
    _feed(session, config, 50, config.samples - 50)
    # the initial state and the 50 samples before the failure, equal to the simulation; no more
    assert len(rec.samples) == 51 and not session.complete and rec.complete == []
    assert np.array_equal(rec.column("displacement"), ref.displacement[:51])
    assert session.integration_errors == 1 and session.ignored_after_end == config.samples - 50
    # one ERROR and one on_failure, naming the time, the band value and the parameters
    errors = [t for level, t in rec.logs if level == "error"]
    assert len(errors) == 1 and rec.failures == [session.fault]
    band = float(band_samples(config, 50, 1)[0])
    assert "integration failed at t = 0.051 s" in errors[0] and f"band velocity {band!r} m/s" in errors[0]
    assert "mass" in errors[0] and "rtol" in errors[0] and "no more output until a reset" in errors[0]
    timing = {s.name: s for s in session.diagnostics()}["timing"]
    assert timing.level == "error" and timing.message == session.fault
    assert timing.as_dict()["integration_errors"] == "1"
    # a reset clears the fault: the next segment runs
    session.reset(config)
    assert session.fault is None
    _feed(session, config, 0, 10)
    assert [s.segment for s in rec.samples[51:]] == [1] * 11


@pytest.mark.parametrize("how", ["raise", "nan"])
def test_a_failed_realtime_sample_stops_the_output_until_a_reset(how):
    rec = Recorder()
    config = default_config()
    session = rec.session(config, mode="rig_in_loop")
    session.band_input(3e-7)
    session.emit_initial()
    for _ in range(5):
        assert session.tick()
    session.integrator = FailingOnce(session.integrator, how)
    assert not session.tick() and session.fault is not None
    for _ in range(5):  # no output, no further error, the failure is not an overrun
        assert not session.tick()
    assert len(rec.samples) == 6 and all(math.isfinite(s.displacement) for s in rec.samples)
    assert len(rec.failures) == 1 and len([1 for level, _ in rec.logs if level == "error"]) == 1
    assert session.overruns == 0 and session.integration_errors == 1
    assert {s.name: s for s in session.diagnostics()}["timing"].level == "error"
    session.reset(config)
    session.emit_initial()
    assert session.fault is None and session.tick()
    assert [s.segment for s in rec.samples[6:]] == [1, 1]


def test_parameter_defaults_and_configuration_rebuild():
    base = load_case(3)
    defaults = parameter_defaults(base)
    assert set(defaults) == set(CONFIG_PARAMETERS)
    assert defaults["rig.mass"] == base.rig.mass and defaults["sample_rate"] == base.sample_rate
    assert defaults["rig.normal_force"] == base.rig.friction.normal_force
    assert defaults["friction.shear_modulus"] == base.rig.friction.shear_modulus
    assert config_from(base, defaults) == base  # the defaults rebuild the same configuration
    assert config_from(base, {"convention": ""}).rig.convention == base.rig.convention
    changed = config_from(base, {"rig.damping_ratio": 0.05, "friction.shear_modulus": 4e6})
    assert changed.rig.damping_ratio == 0.05 and changed.rig.friction.shear_modulus == 4e6
    with pytest.raises(ParameterError, match="mass"):
        config_from(base, {"rig.mass": -1.0})


def test_parameter_updates_are_checked_and_applied_only_at_reset(case1):
    config, _ = case1
    session = Recorder().session(config)
    current = parameter_defaults(config)
    assert session.check_update(current, {"rig.damping_ratio": 0.05}) is None
    reason = session.check_update(current, {"rig.mass": -1.0})
    assert reason is not None and "rig.mass=-1.0 refused" in reason and "mass=-1.0" in reason
    assert session.check_update(current, {"rtol": 1.0}) is not None
    assert session.check_update(current, {"unrelated": 1}) is None  # not configuration
    assert session.config.rig.damping_ratio == config.rig.damping_ratio  # nothing applied yet
    assert {"rig.mass", "rtol", "convention", "friction.shear_modulus"} <= RUNTIME_PARAMETERS
    assert "sample_rate" not in RUNTIME_PARAMETERS and "duration" not in RUNTIME_PARAMETERS


@pytest.mark.parametrize(
    "kwargs",
    [
        {"mode": "fast"},
        {"band_velocity_limit": 0.0},
        {"stale_timeout": math.nan},
        {"tick_step_attempts": 0},
        {"tick_step_attempts": 2.5},
        {"tick_step_attempts": True},
    ],
)
def test_settings_are_validated(kwargs):
    with pytest.raises(ParameterError):
        PlantSettings(**kwargs)


def test_diagnostics_are_plain_data(case1):
    config, _ = case1
    session = Recorder().session(config)
    statuses = session.diagnostics()
    assert [s.name for s in statuses] == ["timing", "band input"]
    assert all(isinstance(k, str) and isinstance(v, str) for s in statuses for k, v in s.values)
    assert statuses[0].message == "running" and statuses[1].as_dict()["valid_range_m_s"] == (
        "finite, |v| <= 0.01"
    )


def test_cdr_float64_decoding():
    assert cdr.float64_value(b"\x00\x01\x00\x00" + struct.pack("<d", 1.5e-7)) == 1.5e-7
    assert cdr.float64_value(b"\x00\x00\x00\x00" + struct.pack(">d", -2.5)) == -2.5
    assert math.isnan(cdr.float64_value(b"\x00\x01\x00\x00\x00"))  # too short
    assert math.isnan(cdr.float64_value(b"\x00\x07\x00\x00" + struct.pack("<d", 1.0)))  # encoding
    stamp = b"\x00\x01\x00\x00" + struct.pack("<iI", 3, 250_000_000)
    assert cdr.leading_stamp_ns(stamp) == 3_250_000_000
    with pytest.raises(ValueError):
        cdr.leading_stamp_ns(b"\x00\x01")
    assert cdr.stamp_of(1.0005) == (1, 500_000)


def test_cdr_matches_rclpy_serialization():
    pytest.importorskip("rclpy")
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64

    for value in (0.0, -1e-7, 1e300, math.inf):
        assert cdr.float64_value(serialize_message(Float64(data=value))) == value
    msg = JointState()
    msg.header.stamp.sec, msg.header.stamp.nanosec = 12, 345
    assert cdr.leading_stamp_ns(serialize_message(msg)) == 12_000_000_345
