"""Steps that span samples (core/stepper.py): where they happen, what a kink does, determinism.

A step may span samples where the band is a straight line; its samples are read off the step's
collocation polynomial, and a sample off the line ends the step at the sample before it. The
reference is lubrig_testkit.reference_rig (the model document's equations, scipy LSODA at rtol
1e-12, steps of at most one sample period), which shares no code with the kernel. Accuracy is
asked at the default run's tolerance (config/rig.yaml): at loose tolerances a stick-slip run with
spans is less accurate than one with a step per sample (docs/integrator.md, Speed).
"""

from __future__ import annotations

import numpy as np
import pytest
from lubrig_testkit.reference_rig import reference_displacement

from lubrig_ros.core.errors import InputError
from lubrig_ros.core.integrator import RigIntegrator
from lubrig_ros.core.params import RigParameters
from lubrig_ros.core.presets import default_config, load_case
from lubrig_ros.core.run import simulate
from lubrig_ros.core.stepper import PENDING, STEP_T

RATE = 1000.0
RTOL = default_config().rtol


def run(band: np.ndarray, **options) -> tuple[RigIntegrator, np.ndarray]:
    """x at t = 0 and at every sample of `band` (the band at rest at band[0] before t = 0)."""
    integrator = RigIntegrator(RigParameters(), float(band[0]), rtol=RTOL, **options)
    x = np.concatenate([integrator.current().displacement, integrator.advance(band).displacement])
    return integrator, x


def reference(band: np.ndarray, x: np.ndarray) -> np.ndarray:
    time = np.arange(band.size + 1) / RATE
    velocities = np.concatenate([[band[0]], band])
    return reference_displacement(time, velocities, float(x[0]), RigParameters().velocity_factor)


def test_steps_span_samples_on_a_constant_band_and_agree_with_the_reference() -> None:
    # physical stick-slip at 2e-8 m/s (config/stickslip.yaml's band): stuck most of the time
    band = np.full(8000, 2e-8)
    spanning, x = run(band)
    one_per_sample, x_one = run(band, max_step_samples=1)
    assert spanning.substeps < band.size / 3 < one_per_sample.substeps
    x_ref = reference(band, x)
    scale = np.ptp(x_ref)
    assert np.max(np.abs(x - x_ref)) < 1e-5 * scale
    assert np.max(np.abs(x - x_one)) < 1e-5 * scale


def test_a_kink_after_a_long_line_is_integrated_as_the_reference() -> None:
    # a constant band, then a ramp up, then a jump down: speculative steps made on the first line
    # are found invalid at the kinks and integrated again up to the sample before each
    band = np.concatenate(
        [np.full(1500, 2e-8), np.linspace(2e-8, 2e-7, 700), np.full(800, 5e-8), np.full(1000, 3e-8)]
    )
    spanning, x = run(band)
    assert spanning.substeps < band.size
    x_ref = reference(band, x)
    assert np.max(np.abs(x - x_ref)) < 1e-5 * np.ptp(x_ref)


def test_a_stuck_mass_turns_at_a_corner_of_the_band_in_a_few_steps() -> None:
    # Stuck on a constant band, then a ramp: the mass's velocity turns to the band's new slope in
    # about a nanosecond, a transient that the first error estimate of every step from the corner
    # reports whatever the step size. The refined estimate after a rejection (Hairer & Wanner
    # IV.8) damps it: the corner's sample takes a few steps, not a descent to nanosecond steps
    # (ten accepted, twenty rejected, without the refinement), and stays on the reference.
    band = np.concatenate([np.full(3000, 2e-8), 2e-8 + 1e-10 * np.arange(1, 401)])
    integrator = RigIntegrator(RigParameters(), float(band[0]), rtol=RTOL)
    x = [integrator.current().displacement[0]]
    steps = []
    for value in band:
        before = integrator.substeps
        x.append(integrator.advance(np.array([value])).displacement[0])
        steps.append(integrator.substeps - before)
    assert steps[3000] <= 3
    x_ref = reference(band, np.array(x))
    assert np.max(np.abs(np.array(x) - x_ref)) < 1e-5 * np.ptp(x_ref)


def test_a_long_step_nearing_a_slip_onset_is_judged_by_its_stages_stiffness() -> None:
    # Physical case 1's first slip (2.819 s), after stick phases stepped in long spans: the mass
    # nears its friction peak within a step and loses its stiffness there. The error estimate
    # filtered with the step start's Jacobian called a step good whose ẋ was 436 × the tolerance
    # off, and the slip came tens of µs early (7e-5 of the range); with the stages' least damped
    # one the run stays on the reference.
    config = load_case(1).with_overrides(convention="physical", duration=3.0)
    run = simulate(config)
    x_ref = reference_displacement(
        run.time, run.band_velocity, float(run.displacement[0]), config.rig.velocity_factor
    )
    assert np.max(np.abs(run.displacement - x_ref)) < 1e-5 * np.ptp(x_ref)


def test_a_band_with_a_kink_at_every_sample_is_stepped_sample_by_sample() -> None:
    # a measured band's noise: no three samples on a line, so no step spans one, and the run is
    # the one with max_step_samples=1 bit for bit
    rng = np.random.default_rng(3)
    band = 1e-7 * (1.0 + 0.05 * rng.standard_normal(3000))
    spanning, x = run(band)
    one_per_sample, x_one = run(band, max_step_samples=1)
    assert np.array_equal(x, x_one)
    assert spanning.substeps == one_per_sample.substeps >= band.size


@pytest.mark.parametrize("budget", [1, 3, 0])
def test_blocks_samples_and_budgets_give_the_run_of_one_call(budget: int) -> None:
    # the band's lines, kinks and stick-slip of the tests above, fed in random blocks (budget 0)
    # or sample by sample with a step budget that cuts samples short
    band = np.concatenate([np.full(2000, 2e-8), np.linspace(2e-8, 1e-7, 300), np.full(700, 1e-7)])
    band[2600] *= 1.01  # one sample off its line
    whole, x_whole = run(band)
    integrator = RigIntegrator(RigParameters(), float(band[0]), rtol=RTOL)
    rng = np.random.default_rng(budget)
    parts, start = [], 0
    while start < band.size:
        if budget:
            sample = None
            while sample is None:
                sample = integrator.advance_bounded(float(band[start]), budget)
            parts.append([sample.displacement])
            start += 1
        else:
            count = int(rng.integers(1, 60))
            parts.append(integrator.advance(band[start : start + count]).displacement)
            start += count
    assert np.array_equal(np.concatenate(parts), x_whole[1:])
    assert integrator.substeps == whole.substeps


@pytest.mark.parametrize("bad", [0, -3, 2.5, True])
def test_a_bad_step_span_is_refused(bad) -> None:
    with pytest.raises(InputError, match=f"max_step_samples={bad!r} must be an integer >= 1"):
        RigIntegrator(RigParameters(), 1e-7, max_step_samples=bad)


def test_a_span_set_later_applies_to_the_next_steps_and_is_checked() -> None:
    integrator = RigIntegrator(RigParameters(), 2e-8, rtol=RTOL)
    integrator.advance(np.full(300, 2e-8))
    assert integrator.snapshot()[PENDING] > 2.0 * integrator.dt  # a step spanning samples
    integrator.max_step_samples = 2
    begun = integrator.snapshot()[STEP_T]  # the step pending when it was set may end as it was
    new_steps = 0
    for _ in range(RigIntegrator.max_step_samples + 100):  # past the end of the longest step
        integrator.advance([2e-8])
        state = integrator.snapshot()
        if state[PENDING] > 0.0 and state[STEP_T] != begun:
            new_steps += 1
            assert state[PENDING] <= 2.0 * integrator.dt * (1.0 + 1e-12)
    assert new_steps > 10
    integrator.max_step_samples = 0
    with pytest.raises(InputError, match="max_step_samples=0 must be an integer >= 1"):
        integrator.advance([2e-8])
    with pytest.raises(InputError, match="max_step_samples=0 must be an integer >= 1"):
        integrator.advance_bounded(2e-8, 5)


@pytest.mark.parametrize("bad", [0, 3, 1.5, True])
def test_a_bad_newton_minimum_is_refused(bad) -> None:
    with pytest.raises(InputError, match=f"min_newton_iterations={bad!r} must be 1 or 2"):
        RigIntegrator(RigParameters(), 1e-7, min_newton_iterations=bad)


@pytest.mark.parametrize("case", [1, 4])
def test_accepting_the_first_newton_iterate_keeps_the_reference(case: int) -> None:
    # the default accepts a stage solve's first iterate when the last solve's contraction says it
    # is converged (a sliding mass then takes one iteration); the fit's setting never does
    band = simulate(load_case(case).with_overrides(convention="physical", duration=4.0)).band_velocity
    _, x = run(band)
    _, x_two = run(band, min_newton_iterations=2)
    x_ref = reference(band, x)
    scale = np.ptp(x_ref)
    assert np.max(np.abs(x - x_ref)) < 1e-5 * scale
    assert np.max(np.abs(x - x_two)) < 1e-5 * scale
    assert not np.array_equal(x, x_two)  # the setting is used


def test_a_step_integrated_again_on_a_budget_gives_the_run_of_one_call() -> None:
    # sliding; with a step spanning samples pending, the span set to 1, then a band step: the
    # pending step is integrated again up to the sample before in several substeps, which a
    # budget of one attempt per call interrupts; each substep must be predicted as in one call
    band = np.full(2000, 1e-6)
    band[1008:] = 1.001e-6
    whole, budgeted = (RigIntegrator(RigParameters(), 1e-6, rtol=RTOL) for _ in range(2))
    for integrator in (whole, budgeted):
        integrator.advance(band[:1000])
        assert integrator.snapshot()[PENDING] > 0.0
        integrator.max_step_samples = 1
    x_whole = whole.advance(band[1000:]).displacement
    x_budgeted = []
    for v in band[1000:]:
        while (sample := budgeted.advance_bounded(float(v), 1)) is None:
            pass
        x_budgeted.append(sample.displacement)
    assert np.array_equal(x_whole, x_budgeted)


def test_a_stuck_mass_takes_no_first_iterate_on_trust() -> None:
    # physical case 8 sticks at every corner of its band: a stuck mass's band-following guess is
    # not what the last solve's contraction was measured from, so its first iterate is never
    # accepted on that rate; at a loose tolerance the run stays within it of the reference
    config = load_case(8).with_overrides(convention="physical", duration=20.0)
    band = simulate(config).band_velocity
    integrator = RigIntegrator(config.rig, float(band[0]), rtol=1e-6)
    x = np.concatenate([integrator.current().displacement, integrator.advance(band[1:]).displacement])
    time = np.arange(band.size) / RATE
    x_ref = reference_displacement(time, band, float(x[0]), config.rig.velocity_factor)
    assert np.max(np.abs(x - x_ref)) < 1e-6 * np.ptp(x_ref)


def test_a_snapshot_of_another_layout_is_refused() -> None:
    integrator = RigIntegrator(RigParameters(), 1e-7)
    with pytest.raises(InputError, match=r"a snapshot of 27 values; expected \d+"):
        integrator.restore(integrator.snapshot()[:27])
