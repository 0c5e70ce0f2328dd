"""Bounded nonlinear least squares on the multiple-shooting residuals.

scipy.optimize.least_squares (trust-region reflective, bounded by the parameters' physical ranges
from core/schema.py) minimizes the residuals of fit.shooting; fit.uncertainty gives the standard
errors and names what the data cannot determine, from the Jacobian at the solution.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import csr_matrix
from threadpoolctl import threadpool_limits

from ..core.presets import RunConfig
from .data import MeasuredData
from .defaults import MAX_EVALUATIONS, SEGMENT_SECONDS
from .parameters import FreeParameter, current_value, free_parameters
from .shooting import DEFECT_WEIGHT, Runner, ShootingProblem
from .uncertainty import covariance, parameter_information, undetermined

#: Residual RMS above this multiple of a stream's noise estimate: the fitted model does not
#: explain the data (a local minimum, a model that cannot, or parameters that should be free).
MAX_MISFIT = 1.5
#: The first stage (states alone) only prepares the second: a coarse tolerance, few evaluations.
STATE_STAGE_FTOL = 1e-4
STATE_STAGE_EVALUATIONS = 10
#: Points of the stick-slip start scan (a power of two: a Sobol' sequence's balance) and its span
#: in θ either side of the start (ln 1.25 for a positive parameter; ±25 % of the scale otherwise).
SCAN_POINTS = 128
SCAN_SPAN = math.log(1.25)
SCAN_LINEAR_SPAN = 0.25
SCAN_STARTS = 3
#: Exact trust-region steps (an SVD of the dense Jacobian: time ∝ m n², memory ∝ m n for m data
#: rows and n unknowns) up to this m·n², LSMR's inexact ones on the sparse Jacobian above it.
#: Exact steps reach the minimum where LSMR's stopped above it or never converged (docs/fitting.md,
#: Method); the 20 s five-parameter benchmark is 1.1e9 (an SVD 0.5 s on one thread), a 60 s record
#: with x and μ 2.8e10 (7.4 s and 1.4 GB an SVD).
EXACT_STEP_BUDGET = 2e9
#: BLAS threads of the fit's dense linear algebra (an SVD of the Jacobian per step, the errors'):
#: on a shared machine OpenBLAS's threads spin against other processes. An SVD of 40000 × 165
#: took 0.33 s on two threads and 0.52–0.63 s on one on a quiet machine, but 2.4–14 s on two
#: and 1.1–1.2 s on one beside one CPU hog (docs/fitting.md, "Tests and speed").
BLAS_THREADS = 1


@dataclass
class FitResult:
    """What a fit found (fit.json is its to_dict)."""

    parameters: list[FreeParameter]
    start: np.ndarray
    values: np.ndarray
    errors: np.ndarray
    correlation: np.ndarray
    initial_state: np.ndarray  # x(0) m, ẋ(0) m/s
    initial_state_errors: np.ndarray
    residual_rms: dict[str, float]
    noise: dict[str, float]
    cost: float
    evaluations: int
    jacobians: int
    status: str
    success: bool
    segments: int
    segment_seconds: float
    wall_time: float
    workers: int
    steps: str  # the trust-region steps of the full stage: "exact" or "lsmr" (step_kind)
    undetermined: dict[str, str] = field(default_factory=dict)
    #: free parameters the optimizer left on a bound of their range (scipy's active constraints)
    at_bound: list[str] = field(default_factory=list)
    config: RunConfig | None = None
    states: np.ndarray | None = None
    #: the fitted model at every sample (the shooting segments), by measured stream
    model: dict[str, np.ndarray] = field(default_factory=dict)

    def misfit(self) -> dict[str, float]:
        """Streams whose residual RMS exceeds MAX_MISFIT noise estimates: stream → RMS / noise."""
        ratios = {name: rms / self.noise[name] for name, rms in self.residual_rms.items()}
        return {name: ratio for name, ratio in ratios.items() if ratio > MAX_MISFIT}

    @property
    def names(self) -> list[str]:
        """The free parameters' names."""
        return [p.name for p in self.parameters]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready estimates, errors, correlation, residuals, cost, iterations, identifiability."""
        estimates = {
            p.name: {
                "value": float(v),
                "standard_error": _json_float(e),
                "unit": p.unit,
                "start": float(s),
                "bounds": [p.spec.low, p.spec.high],
                "identifiable": p.name not in self.undetermined,
                "at_bound": p.name in self.at_bound,
            }
            for p, v, e, s in zip(self.parameters, self.values, self.errors, self.start, strict=True)
        }
        return {
            "estimates": estimates,
            "correlation": {
                "names": self.names,
                "matrix": [[_json_float(c) for c in row] for row in self.correlation],
            },
            "undetermined": self.undetermined,
            "initial_state": {
                "displacement_m": float(self.initial_state[0]),
                "displacement_standard_error_m": _json_float(self.initial_state_errors[0]),
                "velocity_m_s": float(self.initial_state[1]),
                "velocity_standard_error_m_s": _json_float(self.initial_state_errors[1]),
            },
            "residual_rms": self.residual_rms,
            "misfit": self.misfit(),
            "noise_estimate": self.noise,
            "cost": self.cost,
            "function_evaluations": self.evaluations,
            "jacobian_evaluations": self.jacobians,
            "status": self.status,
            "success": self.success,
            "method": {
                "name": "multiple shooting, scipy.optimize.least_squares (trf, bounded)",
                "segments": self.segments,
                "segment_s": self.segment_seconds,
                "defect_weight": DEFECT_WEIGHT,
                "trust_region_steps": self.steps,
                "workers": self.workers,
                "wall_time_s": self.wall_time,
            },
        }


def unconverged(document: dict[str, Any]) -> str:
    """Why a fit's estimates are not at a minimum, from its fit.json content ('' if it converged)."""
    if document["success"]:
        return ""
    return (
        f"the fit stopped after {document['function_evaluations']} evaluation(s) without converging "
        f"({document['status']}): the estimates and errors are those of where it stopped "
        "(--max-evaluations allows more)"
    )


def bound_warning(name: str, estimate: dict[str, Any]) -> str:
    """What a parameter ending on a bound of its range means for the errors (from fit.json)."""
    low, high = estimate["bounds"]
    return (
        f"{name} ended on a bound of its range [{low:g}, {high:g}] at {estimate['value']:.6g}: its standard "
        "error treats it as free, and those of the other parameters hold only if it is right there"
    )


def _json_float(value: float) -> float | None:
    """A finite float, or None (JSON has no inf/NaN) for an error the data cannot bound."""
    return float(value) if math.isfinite(value) else None


def fit(
    data: MeasuredData,
    config: RunConfig,
    names: list[str],
    segment_seconds: float = SEGMENT_SECONDS,
    workers: int = 1,
    max_evaluations: int = MAX_EVALUATIONS,
) -> FitResult:
    """Estimate the named parameters of `config` from `data`, started from `config`'s values."""
    started = time.perf_counter()
    parameters = free_parameters(names, config)
    samples = max(2, round(segment_seconds * data.sample_rate))
    problem = ShootingProblem(data, config, parameters, samples)
    start = np.array([current_value(config, p) for p in parameters])
    low, high = problem.bounds()
    theta = np.array([p.to_theta(v) for p, v in zip(parameters, start, strict=True)])
    theta = np.clip(
        theta, low[: theta.size] + 1e-9 * np.abs(low[: theta.size]) + 1e-12, high[: theta.size] - 1e-9
    )
    z0 = np.concatenate([theta, problem.pack(start, problem.initial_states(start))[len(parameters) :]])
    with threadpool_limits(limits=BLAS_THREADS, user_api="blas"):
        runner = Runner(problem, workers)
        try:
            starts = _scan(runner, z0, low, high) if problem.slips else [z0]
            solutions = [_local_fit(runner, z, low, high, max_evaluations) for z in starts]
            solution = min(solutions, key=lambda s: float(s.cost))
            jac = runner.jacobian(solution.x)
        finally:
            runner.close()
        return _result(problem, parameters, start, solution, jac, workers, time.perf_counter() - started)


def step_kind(rows: int, unknowns: int) -> str:
    """The trust-region steps of a stage with these data rows and unknowns, "exact" or "lsmr"."""
    return "exact" if rows * unknowns**2 <= EXACT_STEP_BUDGET else "lsmr"


def trust_region_steps(
    problem: ShootingProblem, unknowns: int, jacobian: Callable[[np.ndarray], np.ndarray]
) -> dict[str, Any]:
    """least_squares' arguments for the steps step_kind chooses (LSMR takes the Jacobian sparse)."""
    if step_kind(problem.data_rows(), unknowns) == "exact":
        return {"tr_solver": "exact", "jac": jacobian}
    return {"tr_solver": "lsmr", "jac": lambda z: csr_matrix(jacobian(z))}


def _local_fit(
    runner: Runner, z0: np.ndarray, low: np.ndarray, high: np.ndarray, max_evaluations: int
) -> Any:
    """The states' stage, then bounded least squares on everything from there (scipy's result)."""
    z0 = _fit_states(runner, z0, max_evaluations)
    return least_squares(
        runner.residuals,
        z0,
        bounds=(low, high),
        method="trf",
        x_scale=1.0,
        max_nfev=max_evaluations,
        **trust_region_steps(runner.problem, z0.size, runner.jacobian),
    )


def _scan(runner: Runner, z0: np.ndarray, low: np.ndarray, high: np.ndarray) -> list[np.ndarray]:
    """The SCAN_STARTS best of SCAN_POINTS parameter sets around the start (stick-slip records).

    On a stick-slip record the local fit cannot carry a slip far: a slip's time moves with the
    threshold x = N μ_peak / k, the cost grows with the distance between the model's slip and the
    data's, and its Gauss-Newton model does not see past the slip's edge (measured on case 1
    physical, 10 s: from ζ −10 %, f0 −5 %, G +10 %, a threshold 21 % high, the local fit ends with
    f0 −8.5 %, G −24 % and ζ near 0). So the free parameters are first scanned over θ ± SCAN_SPAN
    (a ratio of 1.25 for a positive parameter, ±25 % of its scale for a linear one), on an
    unscrambled Sobol' sequence of SCAN_POINTS points (deterministic), each one run of the record
    from the data's states; the SCAN_STARTS of lowest cost (the start among the candidates) each
    start a local fit, and the fit keeps the lowest final cost: the cost of a stick-slip record
    also has nearby local minima in the weakly seen ζ (measured: from one start, seed 4 of the
    test's record ended at ζ −16 % with the residual RMS 1.075 × the noise, 1.03 × at the truth).
    """
    from scipy.stats import qmc  # scipy.stats is slow to import and only stick-slip needs it

    problem = runner.problem
    count = len(problem.parameters)
    spans = np.array([SCAN_SPAN if p.logarithmic else SCAN_LINEAR_SPAN for p in problem.parameters])
    unit = qmc.Sobol(count, scramble=False).random(SCAN_POINTS)
    points = np.clip(z0[:count] + (2.0 * unit - 1.0) * spans, low[:count], high[:count])
    points = np.vstack([z0[:count], points])
    tasks = []
    for theta in points:
        values = problem.unpack(np.concatenate([theta, z0[count:]]))[0]
        tasks.append((values, problem.initial_states(values), 0.0))
    costs = [
        float(np.sum(problem.residuals_of(run, states) ** 2))
        for run, (_, states, _) in zip(runner.map(tasks), tasks, strict=True)
    ]
    best = np.argsort(costs)[:SCAN_STARTS]
    return [problem.pack(tasks[k][0], tasks[k][1]) for k in best]


def _fit_states(runner: Runner, z0: np.ndarray, max_evaluations: int) -> np.ndarray:
    """z0 with the segment states fitted to the data at the start parameters (the first stage).

    States taken from the smoothed data are off where the mass slips (a fast velocity the
    smoothing flattens) and noisy where it sticks; fitted first with the parameters held, the
    segments start close to a trajectory of the start rig, and the full fit then moves the
    parameters from there instead of chasing slips with them.

    The x_i of a segment that starts stuck (ShootingProblem.tied) is held: it comes from the stick
    line through the data, precise already, and fitted at start parameters a few per cent off it
    would move: the state would put the model's slip at the data's slip time, absorbing the
    threshold's error, and the full fit would start from that compromise (measured on case 1
    physical, 10 s, from ζ −10 %, f0 +5 %, G −10 %: ends 6–26 % off with those states fitted here,
    within 1 standard error with them held).
    """
    problem = runner.problem
    moving = np.sort(problem.state_columns()[~problem.tied].ravel())
    if moving.size == 0:
        return z0

    def with_states(states: np.ndarray) -> np.ndarray:
        z = z0.copy()
        z[moving] = states
        return z

    def fun(states: np.ndarray) -> np.ndarray:
        return runner.residuals(with_states(states))

    def jac(states: np.ndarray) -> np.ndarray:
        return runner.jacobian(with_states(states), parameters=False)[:, moving]

    solution = least_squares(
        fun,
        z0[moving],
        method="trf",
        ftol=STATE_STAGE_FTOL,
        max_nfev=min(max_evaluations, STATE_STAGE_EVALUATIONS),
        **trust_region_steps(problem, moving.size, jac),
    )
    return with_states(solution.x)


def _result(
    problem: ShootingProblem,
    parameters: list[FreeParameter],
    start: np.ndarray,
    solution: Any,
    jac: np.ndarray,
    workers: int,
    wall: float,
) -> FitResult:
    values, states = problem.unpack(solution.x)
    cov = covariance(problem, jac, solution.fun)
    count = len(parameters)
    theta_errors = np.sqrt(np.clip(np.diag(cov)[:count], 0.0, None))
    errors = np.array(
        [p.physical_error(v, e) for p, v, e in zip(parameters, values, theta_errors, strict=True)]
    )
    block = cov[:count, :count]
    scale = np.where(theta_errors > 0, theta_errors, 1.0)
    correlation = block / np.outer(scale, scale)
    first = problem.state_columns()[0]  # a tied ẋ(0) (the record starts stuck) has no error of its own
    variances = np.array([cov[j, j] if j >= 0 else 0.0 for j in first])
    initial_errors = np.sqrt(np.clip(variances, 0.0, None)) * np.array(problem.state_scale)
    run = problem.run(values, states)  # the model also where μ samples are left out of the fit
    rms = {}
    model = {}
    for name, measured in problem.data.streams.items():
        model[name] = run.displacement if name == "displacement" else run.friction_coefficient
        fitted = ~problem.left_out if name == "friction_coefficient" else slice(None)
        rms[name] = float(np.sqrt(np.mean((model[name] - measured)[fitted] ** 2)))
    result = FitResult(
        parameters=parameters,
        start=start,
        values=values,
        errors=errors,
        correlation=correlation,
        initial_state=states[0],
        initial_state_errors=initial_errors,
        residual_rms=rms,
        noise=dict(problem.sigma),
        cost=float(solution.cost),
        evaluations=int(solution.nfev),
        jacobians=int(solution.njev or 0),
        status=str(solution.message),
        success=bool(solution.success),
        segments=problem.segments,
        segment_seconds=problem.segment_samples / problem.data.sample_rate,
        wall_time=wall,
        workers=workers,
        steps=step_kind(problem.data_rows(), solution.x.size),
        config=problem.config_for(values),
        states=states,
        model=model,
    )
    info, retained = parameter_information(problem, jac)
    active = solution.active_mask[:count]
    result.at_bound = [p.name for p, bound in zip(parameters, active, strict=True) if bound]
    result.undetermined = undetermined(parameters, values, errors, correlation, info, retained)
    return result
