"""`lubrig_ros.fit` on synthetic measurements made by an independent integrator.

The 'measured' records come from lubrig_testkit.reference_rig (the model document's equations
integrated by scipy's LSODA, no code of lubrig_ros), with rig and friction parameters away from the
defaults the fit starts from, and Gaussian noise of 1 % of each stream's range. A recovered
parameter must lie within 2 standard errors and within 5 % of its true value; a set the data
cannot separate must be named as such.
"""

from __future__ import annotations

import math
import os
import signal
import time
from pathlib import Path

import numpy as np
import pytest
from lubrig_testkit.measured import noisy_record

from lubrig_ros.core.errors import InputError
from lubrig_ros.core.presets import RunConfig, load_case
from lubrig_ros.fit import solve
from lubrig_ros.fit.data import MeasuredData, checked, load_csv
from lubrig_ros.fit.page import write_outputs
from lubrig_ros.fit.parameters import fittable_names, free_parameters
from lubrig_ros.fit.shooting import Runner, ShootingProblem
from lubrig_ros.fit.solve import FitResult, fit
from lubrig_ros.fit.uncertainty import (
    COVARIANCE_WEIGHT,
    MIN_RETAINED,
    covariance,
    parameter_information,
    undetermined,
)

#: The true rig of the synthetic records (the fit starts from the study's defaults).
TRUTH = {"damping_ratio": 0.012, "natural_frequency": 10.3, "shear_modulus": 4.1e6}
DURATION = 3.0  # s of 1 kHz data per record


def synthetic(config: RunConfig, truth: dict[str, float], seed: int = 1) -> MeasuredData:
    """A noisy record of the reference rig with `truth` driven by `config`'s band."""
    return checked(*noisy_record(config, truth, seed), "synthetic")


def assert_recovered(result: FitResult, truth: dict[str, float], only: list[str] | None = None) -> None:
    """Every free parameter (or those `only`) within 2 standard errors and 5 % of the truth.

    Without `only`, none may be undetermined.
    """
    if only is None:
        assert result.undetermined == {}, result.undetermined
    for name, value, error in zip(result.names, result.values, result.errors, strict=True):
        if only is not None and name not in only:
            continue
        true = truth[name]
        assert abs(value - true) <= 0.05 * abs(true), (name, value, true)
        assert abs(value - true) <= 2.0 * error, (name, value, true, error)


@pytest.mark.parametrize("case", [1, 4, 7])
def test_study_cases_recover_rig_and_friction_parameters(case: int) -> None:
    config = load_case(case).with_overrides(duration=DURATION)
    data = synthetic(config, TRUTH)
    result = fit(data, config, list(TRUTH))
    assert result.success, result.status
    assert_recovered(result, TRUTH)
    assert result.at_bound == []
    for name, rms in result.residual_rms.items():  # the model leaves the noise, no more
        assert rms < 1.1 * result.noise[name], (name, rms, result.noise[name])
    assert result.misfit() == {}


def test_one_measured_stream() -> None:
    """Displacement alone determines the three. μ alone (case 4, paper convention: μ sees the mass
    through v_rel = v_band − ẋ/ω0) determines G and f0 but not ζ, and says so wherever the fit
    stops (docs/fitting.md, "μ alone")."""
    config = load_case(4).with_overrides(duration=DURATION)
    time, band, x, mu = noisy_record(config, TRUTH)
    result = fit(checked(time, band, x, None, "x only"), config, list(TRUTH))
    assert_recovered(result, TRUTH)
    mu_only = checked(time, band, None, mu, "μ only")
    result = fit(mu_only, config, list(TRUTH))
    assert result.success, result.status
    assert set(result.undetermined) == {"damping_ratio"}, result.undetermined
    assert "standard error" in result.undetermined["damping_ratio"]
    assert_recovered(result, TRUTH, only=["shear_modulus", "natural_frequency"])
    for evaluations in (5, 20):  # stopped on the way, not converged: the same verdict
        early = fit(mu_only, config, list(TRUTH), max_evaluations=evaluations)
        assert not early.success and early.evaluations == evaluations, early.status
        assert set(early.undetermined) == {"damping_ratio"}, (evaluations, early.undetermined)


@pytest.fixture(scope="module")
def mu_only_jacobian() -> tuple[ShootingProblem, np.ndarray, np.ndarray]:
    """(problem, Jacobian, residuals) of 1 s of μ alone on case 4, 4 segments, at the truth with
    each segment's start x moved by 1e-3 of the stream's scale (continuity defects that are not 0)."""
    config = load_case(4).with_overrides(duration=1.0)
    time, band, _, mu = noisy_record(config, TRUTH)
    parameters = free_parameters(list(TRUTH), config)
    problem = ShootingProblem(checked(time, band, None, mu, "μ only"), config, parameters, 250)
    runner = Runner(problem, 1)
    try:
        values = np.array([TRUTH[p.name] for p in parameters])
        z = problem.pack(values, problem.initial_states(values))
        z[problem.state_columns()[:, 0]] += 1e-3
        return problem, runner.jacobian(z), runner.residuals(z)
    finally:
        runner.close()


def test_the_states_are_eliminated_without_cancellation(
    mu_only_jacobian: tuple[ShootingProblem, np.ndarray, np.ndarray],
) -> None:
    """The parameters' information with the segment states eliminated equals a QR of the weighted
    Jacobian with the state columns first, where the continuity rows carry most of each column
    (μ alone on case 4: formed from JᵀJ, f0's came out negative)."""
    problem, jac, _ = mu_only_jacobian
    info, retained = parameter_information(problem, jac)
    weighted = np.array(jac)
    weighted[problem.data_rows() :] *= COVARIANCE_WEIGHT / problem.defect_weight
    count = len(problem.parameters)
    r = np.linalg.qr(np.hstack([weighted[:, count:], weighted[:, :count]]), mode="r")
    tail = r[-count:, -count:]
    np.testing.assert_allclose(info, tail.T @ tail, rtol=1e-6, atol=1e-9 * np.abs(info).max())
    assert np.all(np.diag(info) > 0.0) and np.all(retained > 1e-3), (np.diag(info), retained)


def test_a_parameter_the_states_absorb_is_named(
    mu_only_jacobian: tuple[ShootingProblem, np.ndarray, np.ndarray],
) -> None:
    """ζ's column replaced by a combination of the state columns plus noise at the level forward
    differences leave: nothing of it is left once the states are fitted, and only ζ is named."""
    problem, jac, _ = mu_only_jacobian
    count = len(problem.parameters)
    absorbed = np.array(jac)
    rng = np.random.default_rng(5)
    column = jac[:, count:] @ rng.normal(size=jac.shape[1] - count)
    # plus what forward differences leave of an absorbed column: 3e-8 of its information from the
    # data rows (uncertainty.MIN_RETAINED)
    rows = problem.data_rows()
    noise = rng.normal(size=rows)
    noise *= np.sqrt(3e-8 * (column[:rows] @ column[:rows]) / (noise @ noise))
    absorbed[:, 0] = column
    absorbed[:rows, 0] += noise
    info, retained = parameter_information(problem, absorbed)
    assert 1e-8 < retained[0] < MIN_RETAINED < retained[1:].min(), retained
    names = undetermined(
        problem.parameters, np.ones(count), np.full(count, 0.01), np.eye(count), info, retained
    )
    assert set(names) == {"damping_ratio"} and "no information left" in names["damping_ratio"], names


def test_the_covariance_is_the_estimator_s(
    mu_only_jacobian: tuple[ShootingProblem, np.ndarray, np.ndarray],
) -> None:
    """s² A⁺ J_dᵀJ_d A⁺ (A = JᵀJ, J_d the data rows) equals s² J⁺_d J⁺_dᵀ from a QR of J, J⁺_d
    the data columns of the pseudo-inverse (J = QR, J⁺ = R⁻¹Qᵀ); not s² A⁺, which ignores that
    only the data rows carry noise."""
    problem, jac, residual = mu_only_jacobian
    samples = problem.data.time.size  # one stream, none left out: s² over its samples
    assert np.any(residual[samples:] != 0.0)  # continuity defects, which carry no noise
    q, r = np.linalg.qr(jac)
    data_pinv = np.linalg.solve(r, q[:samples].T)
    s2 = float(np.sum(residual[:samples] ** 2)) / (samples - jac.shape[1])
    expected = s2 * data_pinv @ data_pinv.T
    np.testing.assert_allclose(
        covariance(problem, jac, residual), expected, rtol=1e-6, atol=1e-12 * expected.max()
    )


def test_a_fit_that_does_not_explain_the_data_says_so() -> None:
    """Stick-slip data (case 1, physical γ = 1) fitted with the paper convention's γ = 1/ω0 held.

    No damping ratio in [0, 2] gives that rig stick-slip: the residuals stay far above the noise,
    and the result says so instead of passing the estimate off as a fit.
    """
    measured = load_case(1).with_overrides(convention="physical", duration=2.0)
    data = synthetic(measured, {})
    result = fit(data, load_case(1).with_overrides(duration=2.0), ["damping_ratio"])
    assert set(result.misfit()) == {"displacement", "friction_coefficient"}, result.residual_rms
    assert result.to_dict()["misfit"]["displacement"] > 1.5


def test_the_exact_step_budget() -> None:
    """20 s of x and μ at 1 kHz with five parameters (the benchmark) takes exact steps, 60 s not."""
    assert solve.step_kind(40002, 5 + 2 * 80) == "exact"
    assert solve.step_kind(120002, 5 + 2 * 240) == "lsmr"


def test_a_record_over_the_exact_step_budget_takes_lsmr_steps(monkeypatch: pytest.MonkeyPatch) -> None:
    """Above EXACT_STEP_BUDGET (here every record) the fit takes LSMR's steps and still recovers
    the rig; fit.json says which steps it took."""
    config = load_case(4).with_overrides(duration=DURATION)
    data = synthetic(config, TRUTH)
    assert (
        fit(data, config, ["damping_ratio"], max_evaluations=1).to_dict()["method"]["trust_region_steps"]
        == "exact"
    )
    monkeypatch.setattr(solve, "EXACT_STEP_BUDGET", 0.0)
    result = fit(data, config, list(TRUTH))
    assert result.success, result.status
    assert result.to_dict()["method"]["trust_region_steps"] == "lsmr"
    assert_recovered(result, TRUTH)


def test_a_parameter_left_on_its_bound_is_flagged(tmp_path: Path) -> None:
    """An undamped rig (ζ = 0, the bottom of its range): noise drives the estimate onto the bound
    (this seed), where the linear errors no longer hold; fit.json and fit.md say so."""
    config = load_case(4).with_overrides(duration=2.0)
    data = synthetic(config, {"damping_ratio": 0.0})
    result = fit(data, config, ["damping_ratio"])
    assert result.at_bound == ["damping_ratio"] and 0.0 <= result.values[0] < 1e-8, result.values
    document = write_outputs(tmp_path, data, result, "test")
    assert document["estimates"]["damping_ratio"]["at_bound"] is True
    page = (tmp_path / "fit.md").read_text()
    assert "**at a bound**: damping_ratio ended on a bound of its range [0, 2]" in page


def test_a_set_the_data_cannot_separate_is_named() -> None:
    """μ depends on A·G and A·η_ref only: the three together are one direction too many."""
    config = load_case(4).with_overrides(duration=2.0)
    data = synthetic(config, {})
    names = ["contact_area", "shear_modulus", "reference_viscosity"]
    result = fit(data, config, names)
    assert set(result.undetermined) == set(names), result.undetermined
    assert all("near-singular" in why or "correlation" in why for why in result.undetermined.values())
    assert result.to_dict()["estimates"]["contact_area"]["identifiable"] is False


def _handles(pid: int, signum: int) -> bool:
    """Whether process pid has a handler of its own for signal signum (/proc's SigCgt mask)."""
    with open(f"/proc/{pid}/status", encoding="ascii") as status:
        caught = next(line for line in status if line.startswith("SigCgt:"))
    return bool(int(caught.split()[1], 16) >> (signum - 1) & 1)


def test_pool_workers_die_on_sigterm_whatever_the_parent_handles() -> None:
    """A worker with the parent's Python SIGTERM handler can miss Pool.terminate's signal (one
    landing just before it blocks on the task lock) and hang the fit's end: it takes the default."""

    def parent_handler(signum: int, _frame: object) -> None:
        raise KeyboardInterrupt(signum)

    previous = signal.signal(signal.SIGTERM, parent_handler)
    try:
        config = load_case(4).with_overrides(duration=0.5)
        parameters = free_parameters(["damping_ratio"], config)
        problem = ShootingProblem(synthetic(config, {}), config, parameters, 250)
        runner = Runner(problem, 2)
        try:
            pids = [p.pid for p in runner.pool._pool]
            assert len(pids) == 2 and _handles(os.getpid(), signal.SIGTERM)
            deadline = time.monotonic() + 60.0  # the initializer runs as each worker starts
            while any(_handles(pid, signal.SIGTERM) for pid in pids) and time.monotonic() < deadline:
                time.sleep(0.05)
            assert not any(_handles(pid, signal.SIGTERM) for pid in pids)
        finally:
            runner.close()
    finally:
        signal.signal(signal.SIGTERM, previous)


def test_free_parameters_come_from_the_schema() -> None:
    config = load_case(1)
    chosen = free_parameters(["damping_ratio", "shear_modulus", "activation_exponent"], config)
    assert [p.unit for p in chosen] == ["1", "Pa", "1"]
    assert [p.logarithmic for p in chosen] == [False, True, False]
    assert chosen[1].theta_bounds() == pytest.approx((math.log(1e3), math.log(1e11)))
    assert "contact_area" in fittable_names(config) and "normal_force" in fittable_names(config)
    with pytest.raises(InputError, match=r"--free 'zeta' is not a parameter.*valid: mass, natural_frequency"):
        free_parameters(["zeta"], config)
    with pytest.raises(InputError, match="given twice"):
        free_parameters(["mass", "mass"], config)


def test_csv_with_unit_suffixed_columns(tmp_path: Path) -> None:
    path = tmp_path / "timeseries.csv"
    time = np.arange(50) / 1000.0
    rows = ["time_s,band_velocity_m_s,displacement_m"] + [
        f"{t:.6f},1e-7,{1e-8 + t * 1e-9:.12e}" for t in time
    ]
    path.write_text("\n".join(rows) + "\n")
    data = load_csv(path)
    assert data.sample_rate == pytest.approx(1000.0)
    assert data.friction_coefficient is None and data.displacement is not None
    assert len(data.fingerprint()) == 64


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("time,displacement\n0,1\n", "no band_velocity column"),
        ("time,band_velocity\n" + "".join(f"{k / 1000},1e-7\n" for k in range(30)), "no measured stream"),
        ("time,band_velocity,displacement\n0,1e-7,x\n", "row 2: displacement 'x' is not a number"),
        (
            "time,band_velocity,displacement\n" + "".join(f"{k * k / 1000},1e-7,0\n" for k in range(30)),
            "time step",
        ),
        (
            "time,band_velocity,displacement\n" + "".join(f"{k / 1000},nan,0\n" for k in range(30)),
            "not finite",
        ),
    ],
)
def test_bad_csv_is_named(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(InputError, match=message):
        load_csv(path)
