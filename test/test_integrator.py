"""The Radau IIA rig integrator: accuracy against references, determinism, stepping, sticking."""

from dataclasses import replace

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from lubrig_ros.core.friction import friction_coefficient, friction_slope
from lubrig_ros.core.integrator import RigIntegrator
from lubrig_ros.core.kernels import (
    RIG_DAMPING,
    RIG_LAYOUT,
    RIG_MASS,
    RIG_NORMAL_FORCE,
    RIG_SIZE,
    RIG_STIFFNESS,
    RIG_VELOCITY_FACTOR,
)
from lubrig_ros.core.params import FrictionParameters, RigParameters
from lubrig_ros.core.presets import load_case
from lubrig_ros.core.profiles import ConstantBand
from lubrig_ros.core.run import band_samples, integrator_for, simulate


def reference(
    rig: RigParameters, band, duration: float, x0: float, rate: float = 1000.0, stiff: bool = False
):
    """Tight scipy solution of the same equation, band velocity linear between samples."""
    t_samples = np.arange(0, round(duration * rate) + 1) / rate
    v_samples = band(t_samples)
    m, c, k, gamma = rig.mass, rig.damping, rig.stiffness, rig.velocity_factor
    normal = rig.friction.normal_force

    def rhs(t, y):
        vb = np.interp(t, t_samples, v_samples)
        mu = friction_coefficient(vb - gamma * y[1], rig.friction)
        return [y[1], (normal * float(mu) - c * y[1] - k * y[0]) / m]

    def jac(t, y):
        vb = np.interp(t, t_samples, v_samples)
        slope = float(friction_slope(vb - gamma * y[1], rig.friction))
        return [[0.0, 1.0], [-k / m, (-gamma * normal * slope - c) / m]]

    scale = 1e-2 * normal / k
    options = {"method": "Radau", "jac": jac, "rtol": 1e-10} if stiff else {"method": "DOP853", "rtol": 1e-12}
    sol = solve_ivp(
        rhs,
        (0, duration),
        [x0, 0.0],
        t_eval=t_samples,
        atol=[1e-12 * scale, 1e-12 * scale * rig.angular_frequency],
        **options,
    )
    assert sol.success
    return sol.y[0], sol.y[1]


def test_case1_matches_tight_reference():
    config = load_case(1).with_overrides(duration=2.0)
    traj = simulate(config)
    integ = integrator_for(config)
    x_ref, w_ref = reference(config.rig, config.band, 2.0, integ.equilibrium_displacement * 1.01)
    amplitude = np.ptp(x_ref)
    # rtol 1e-8 integrator: errors far below the oscillation amplitude (1e-9 m)
    assert np.max(np.abs(traj.displacement - x_ref)) < 1e-6 * amplitude
    assert np.max(np.abs(traj.velocity - w_ref)) < 1e-6 * np.ptp(w_ref)


def test_damped_oscillator_without_friction_matches_analytic_solution():
    # A vanishing contact area removes friction (F_t = A σ): a free damped oscillator remains.
    rig = RigParameters(damping_ratio=0.01, friction=FrictionParameters(contact_area=1e-300))
    integ = RigIntegrator(rig, 1e-7, initial_displacement=1e-8)
    traj = integ.advance(np.full(3000, 1e-7))
    w0, zeta = rig.angular_frequency, rig.damping_ratio
    wd = w0 * np.sqrt(1 - zeta**2)
    t = traj.time
    x_exact = 1e-8 * np.exp(-zeta * w0 * t) * (np.cos(wd * t) + zeta * w0 / wd * np.sin(wd * t))
    assert np.max(np.abs(traj.displacement - x_exact)) < 1e-7 * 1e-8


def test_energy_conserved_without_friction_and_damping():
    rig = RigParameters(damping_ratio=0.0, friction=FrictionParameters(contact_area=1e-300))
    integ = RigIntegrator(rig, 1e-7, initial_displacement=1e-8)
    traj = integ.advance(np.full(10000, 1e-7))
    energy = 0.5 * rig.mass * traj.velocity**2 + 0.5 * rig.stiffness * traj.displacement**2
    e0 = 0.5 * rig.stiffness * 1e-16
    assert np.max(np.abs(energy / e0 - 1)) < 1e-7


@pytest.mark.parametrize("case", [1, 4])
def test_rig_array_is_laid_out_as_the_kernel_reads_it(case):
    """The rig array the stepper reads holds each RigParameters attribute at its named index."""
    config = load_case(case)
    rig_array = integrator_for(config)._rig_array
    assert rig_array.shape == (RIG_SIZE,) and rig_array.dtype == np.float64
    named = (RIG_MASS, RIG_DAMPING, RIG_STIFFNESS, RIG_VELOCITY_FACTOR, RIG_NORMAL_FORCE)
    assert [RIG_LAYOUT[i] for i in named] == [
        "mass",
        "damping",
        "stiffness",
        "velocity_factor",
        "normal_force",
    ]
    for index, name in enumerate(RIG_LAYOUT):
        assert rig_array[index] == getattr(config.rig, name), name


def test_two_runs_bit_identical():
    config = load_case(4).with_overrides(duration=3.0)
    a, b = simulate(config), simulate(config)
    for name in ("displacement", "velocity", "friction_coefficient", "relative_velocity"):
        assert np.array_equal(getattr(a, name), getattr(b, name))


@pytest.mark.parametrize("convention", ["paper", "physical"])
def test_sample_by_sample_equals_one_call(convention):
    config = load_case(1).with_overrides(duration=1.5, convention=convention)
    whole = simulate(config)
    integ = integrator_for(config)
    band = band_samples(config, 0, config.samples)
    xs = [integ.advance(band[k : k + 1]).displacement[0] for k in range(band.size)]
    assert np.array_equal(np.array(xs), whole.displacement[1:])


# issue 11's rig-in-the-loop sequence, then stick-slip: samples of 1 to several hundred substeps
IN_LOOP_SEQUENCE = [1e-7, -1e-7, 1e-7, 5e-324, 1e-7] * 3 + [2e-8] * 300


@pytest.mark.parametrize("attempts", [1, 2, 7, 50])
def test_a_bounded_sample_resumed_over_calls_equals_one_unbounded_call(attempts):
    rig = RigParameters()  # physical: sticking, many substeps per sample
    whole = RigIntegrator(rig, 1e-7)
    bounded = RigIntegrator(rig, 1e-7)
    expected = [whole.advance([v]) for v in IN_LOOP_SEQUENCE]
    calls = []
    for v in IN_LOOP_SEQUENCE:
        n, traj = 0, None
        while traj is None and n < 100_000:
            n += 1
            before = bounded.substeps
            traj = bounded.advance_bounded(v, attempts)
            assert bounded.substeps - before <= attempts  # never more work than allowed
            if traj is None:
                assert bounded.in_progress
                assert bounded.time == pytest.approx(expected[len(calls)].time[0] - 1e-3)
        calls.append(n)
        assert traj is not None
        assert not bounded.in_progress
        ref = expected[len(calls) - 1]
        assert traj == ref.sample(0)  # every column, bit for bit
    assert whole.substeps == bounded.substeps
    if attempts < 7:
        assert max(calls) > 1  # the budget did cut samples short
    assert max(calls) >= max(1, whole.substeps // len(IN_LOOP_SEQUENCE) // attempts)


def test_a_sample_in_progress_must_be_finished_before_an_unbounded_advance():
    integ = RigIntegrator(RigParameters(), 1e-7)
    integ.advance(np.full(10, 1e-7))
    assert integ.advance_bounded(-1e-7, 1) is None
    with pytest.raises(RuntimeError, match="in progress"):
        integ.advance([1e-7])
    with pytest.raises(ValueError, match="max_attempts=0"):
        integ.advance_bounded(-1e-7, 0)
    integ.reset()
    assert not integ.in_progress and integ.time == 0.0


def test_sticking_is_integrated_cheaply_and_stays_on_the_stuck_branch():
    # Physical convention at 2e-8 m/s: the mass sticks (|v_rel| < peak velocity) while the spring
    # loads; an integrator that jumps to the zone-2 root of equal μ would chatter.
    rig = RigParameters()
    integ = RigIntegrator(rig, 2e-8)
    traj = integ.advance(np.full(5000, 2e-8))
    stuck = np.abs(traj.relative_velocity[2000:]) < 4.08e-12
    assert stuck.all()
    assert np.all(np.diff(traj.displacement[2000:]) > 0)  # carried by the band
    assert integ.substeps < 3 * 5000


def test_stick_slip_events_resolved_against_reference():
    rig = RigParameters()
    config = load_case(1).with_overrides(convention="physical", duration=0.6)
    traj = simulate(config)
    integ = integrator_for(config)
    x_ref, _ = reference(rig, config.band, 0.6, integ.equilibrium_displacement * 1.01, stiff=True)
    assert np.mean(np.abs(traj.relative_velocity) < 4.08e-12) > 0.3  # it does stick
    assert np.max(np.abs(traj.displacement - x_ref)) < 1e-4 * np.ptp(x_ref)


def test_bad_band_velocity_rejected():
    integ = RigIntegrator(RigParameters(), 1e-7)
    with pytest.raises(ValueError, match="nan"):
        integ.advance([1e-7, float("nan")])


def test_a_band_below_the_resolved_velocity_is_integrated_at_rest():
    # after a band at rest, a subnormal band stalled the stage solve (20 samples in 100 s): values
    # below the velocity tolerance are integrated as 0 (what they are to the tolerance); the
    # outputs keep the value given
    band = np.concatenate([[0.0], np.tile([5e-324, -1e-310, 0.0], 200)])
    tiny = RigIntegrator(RigParameters(), 0.0, rtol=1e-11)
    at_rest = RigIntegrator(RigParameters(), 0.0, rtol=1e-11)
    traj = tiny.advance(band)
    assert np.array_equal(traj.displacement, at_rest.advance(np.zeros(band.size)).displacement)
    assert np.array_equal(traj.band_velocity, band)
    sample = tiny.advance_bounded(5e-324, 10)
    assert sample is not None and sample.band_velocity == 5e-324


def test_reset_returns_to_initial_condition():
    integ = RigIntegrator(RigParameters(convention="paper"), 1e-7)
    first = integ.advance(np.full(100, 1e-7)).displacement.copy()
    integ.reset()
    assert integ.time == 0.0
    assert np.array_equal(integ.advance(np.full(100, 1e-7)).displacement, first)


def test_constant_band_zone3_settles_at_equilibrium():
    rig = replace(RigParameters(), damping_ratio=0.05)
    band = ConstantBand(1e-6)
    integ = RigIntegrator(rig, band.velocity)
    traj = integ.advance(np.full(20000, 1e-6))
    x0 = integ.equilibrium_displacement
    assert abs(traj.displacement[-1] - x0) < 1e-6 * x0


def test_reset_at_a_later_time_keeps_the_sample_grid():
    integ = RigIntegrator(RigParameters(convention="paper"), 1e-7)
    integ.advance(np.full(250, 1e-7))
    integ.reset(band_velocity=2e-7, time=integ.time)
    traj = integ.advance(np.full(10, 2e-7))
    assert np.allclose(traj.time, 0.25 + 1e-3 * np.arange(1, 11), rtol=0, atol=1e-12)
    assert integ.initial_band_velocity == 2e-7
