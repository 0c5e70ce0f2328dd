"""Multiple shooting on the compiled core: residuals and Jacobian of a fit.

Why multiple shooting: a stick-slip trajectory depends on its parameters through slip times, and
over many slips a small parameter error shifts a slip by a large share of the displacement range;
fitting one long simulation (single shooting) then meets a cost full of local minima. Here the
record is cut into segments (default 0.25 s); each starts from its own free state (x_i, ẋ_i) and is
integrated over the measured band by core.integrator.RigIntegrator (the project's Radau IIA, the
code path of `lubrig simulate` and the plant), so no segment is long enough to lose its slips. The
continuity of x and ẋ at every boundary is a residual with a weight (DEFECT_WEIGHT noise units):
at the solution the segments join into one trajectory of the fitted rig.

Residuals, all in units of each stream's noise (estimated from the record, `noise_level`):
(x_model − x_measured) / σ_x and (μ_model − μ_measured) / σ_μ at every sample of the streams
present (0 for the μ samples next to a stick–slip transition, stick.transition_samples), then the
weighted defects at the segment boundaries. The model at a boundary sample is
the end of the segment that reaches it, not the next one's free start state: while the mass
sticks, μ depends on v_rel ≈ 0 with a slope up to 1e11 s/m, so a start velocity off by 1e-13 m/s
would put μ off by 0.01 at that one sample (the integration settles it within microseconds).

The Jacobian is by forward differences with the structure used: one run of the whole record per
free parameter, plus one with every segment's x_i moved and one with every ẋ_i moved (segment i's
samples depend on its own start state only), so a Jacobian costs P + 2 runs of the record
whatever the number of segments. The runs are independent: with workers > 1 they go to a pool
of forked processes (the compiled core does not release the GIL, so threads would not help).
"""

from __future__ import annotations

import math
import multiprocessing
import signal
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.signal import savgol_filter

from ..core.friction_laws import law_for
from ..core.integrator import IntegrationError, RigIntegrator
from ..core.presets import RunConfig
from .data import MeasuredData
from .parameters import FreeParameter, with_values
from .stick import segment_starts, stuck_positions, stuck_samples, transition_samples

#: Weight of a continuity defect against one sample's residual (both in noise units).
DEFECT_WEIGHT = 10.0
#: Forward-difference step in θ and in the scaled states.
STEP = 1e-6
#: A data residual that moves by more than this (noise units) over one forward-difference step has
#: crossed a discontinuity (see jacobian_from); a slope that steep is no slope of the model.
JUMP = 0.5
#: The integrator's settings in a fit: its output should be a smooth function of the parameters,
#: since forward differences read any jump, however far below the tolerance, as a slope.
#: * max_step_samples 1, every step ends on a sample. A step spanning samples (core/stepper.py)
#:   puts them on its collocation polynomial, whose error changes by jumps when a parameter moved
#:   by STEP changes the step sequence.
#: * min_newton_iterations 2: whether a stage solve stops after one Newton iteration changes by
#:   jumps too.
#: Measured with the errors from SVDs (fit/uncertainty.py): test_fit's μ-only and x-and-μ records
#: of case 4 (seeds 1, 2) give the same estimates, errors and verdicts to 5 digits with steps of
#: up to 16 samples and one iteration, and bench_fit.py is 5–8 % faster; kept for the principle.
FIT_INTEGRATION: dict[str, int] = {"max_step_samples": 1, "min_newton_iterations": 2}
#: Residual given to a sample whose run failed (the step size collapsed): a bad step, not a crash.
FAILED = 1e3

#: The problem a forked worker computes for (set before the pool forks).
_WORKER_PROBLEM: ShootingProblem | None = None


def noise_level(values: np.ndarray) -> float:
    """White-noise σ of a stream from its second differences (robust: median absolute deviation).

    A smooth signal sampled at 1 kHz barely curves from one sample to the next, so the second
    difference y[k+1] − 2 y[k] + y[k−1] is noise alone, of variance 6 σ². Floored at 1e-9 of the
    stream's range (noise-free data would otherwise weigh infinitely).
    """
    second = values[2:] - 2.0 * values[1:-1] + values[:-2]
    mad = float(np.median(np.abs(second - np.median(second))))
    span = float(np.ptp(values)) or abs(float(values[0])) or 1.0
    return max(1.4826 * mad / math.sqrt(6.0), 1e-9 * span)


@dataclass
class Run:
    """One run of the record: model streams at every sample, end states of all but the last segment."""

    displacement: np.ndarray
    friction_coefficient: np.ndarray
    ends: np.ndarray  # (segments − 1, 2): x, ẋ at the next segment's start sample
    failed: bool = False


@dataclass
class ShootingProblem:
    """The record, the start configuration, the free parameters and the segment grid."""

    data: MeasuredData
    config: RunConfig
    parameters: list[FreeParameter]
    segment_samples: int
    defect_weight: float = DEFECT_WEIGHT
    starts: np.ndarray = field(init=False)
    stuck: np.ndarray = field(init=False)  # per sample: the measured mass sticks (stick.py)
    left_out: np.ndarray = field(init=False)  # per sample: μ next to a stick–slip transition, unfitted
    tied: np.ndarray = field(init=False)  # per segment: starts stuck, ẋ_i = v_band / γ (not free)
    sigma: dict[str, float] = field(init=False)
    state_scale: tuple[float, float] = field(init=False)
    state_steps: tuple[float, float] = field(init=False)  # forward-difference steps of x_i, ẋ_i

    def __post_init__(self) -> None:
        n = self.data.time.size
        self.sigma = {name: noise_level(values) for name, values in self.data.streams.items()}
        self.stuck = self._stuck()
        mu = self.data.friction_coefficient
        sigma_mu = self.sigma.get("friction_coefficient", 0.0)
        self.left_out = np.zeros(n, dtype=bool) if mu is None else transition_samples(mu, sigma_mu)
        self.starts = segment_starts(n, self.segment_samples, self.stuck, self.data.sample_rate)
        self.tied = self.stuck[self.starts]
        length = self._length_scale()
        self.state_scale = (length, length * self.config.rig.angular_frequency)
        self.state_steps = (STEP, min(STEP, self._stick_step() / self.state_scale[1]))

    def _stuck(self) -> np.ndarray:
        """Samples where the measured mass sticks to the band (stick.stuck_samples; none without x)."""
        x = self.data.displacement
        if x is None or self._peak_velocity() is None:
            return np.zeros(self.data.time.size, dtype=bool)
        gamma, sigma = self.config.rig.velocity_factor, self.sigma["displacement"]
        return stuck_samples(x, self.data.band_velocity, self.data.sample_rate, gamma, sigma)

    def _stick_step(self) -> float:
        """A velocity step (m/s) that keeps a stuck mass stuck: 1e-3 of the friction peak's v_rel / γ.

        While the mass sticks, |v_rel| stays below the velocity of the friction peak (4.08e-12 m/s
        for the study's law); a forward-difference step of ẋ_i beyond it would make the moved run
        slip and the Jacobian column meaningless. A law without a peak puts no bound.
        """
        peak = self._peak_velocity()
        return math.inf if peak is None else 1e-3 * peak / self.config.rig.velocity_factor

    def _peak_velocity(self) -> float | None:
        """v_rel of the start rig's friction peak (m/s), None for a law without one."""
        friction = self.config.rig.friction
        peak = law_for(friction).peak(friction)
        return None if peak is None else float(peak.velocity)

    def _length_scale(self) -> float:
        """Displacement scale: the measured range, else N μ_range / k of the start rig."""
        if self.data.displacement is not None:
            return float(np.ptp(self.data.displacement)) or abs(float(self.data.displacement[0])) or 1e-9
        mu = self.data.friction_coefficient
        assert mu is not None
        rig = self.config.rig
        return float(np.ptp(mu) or abs(mu[0]) or 1e-3) * rig.normal_force / rig.stiffness

    @property
    def slips(self) -> bool:
        """True when the segment layout holds slips between stick phases (a stick-slip record)."""
        return bool(np.any(np.diff(self.starts) > self.segment_samples))

    @property
    def segments(self) -> int:
        """Number of shooting segments."""
        return int(self.starts.size)

    @property
    def ends(self) -> np.ndarray:
        """Last sample of every segment (the next one's start; the record's last for the last)."""
        return np.append(self.starts[1:], self.data.time.size - 1)

    # -- vector z = [θ (free parameters), x_0/Lx, ẋ_0/Lv, x_1/Lx, ...] --------------------------
    @property
    def free_states(self) -> np.ndarray:
        """(segments, 2) mask of the states that are variables of the fit (all but tied ẋ_i)."""
        mask = np.ones((self.segments, 2), dtype=bool)
        mask[self.tied, 1] = False
        return mask

    def state_columns(self) -> np.ndarray:
        """(segments, 2): index in z of each free state (x_i, ẋ_i); −1 for a tied ẋ_i."""
        mask = self.free_states
        index = np.full(mask.shape, -1, dtype=np.int64)
        index[mask] = len(self.parameters) + np.arange(np.count_nonzero(mask))
        return index

    def pack(self, values: np.ndarray, states: np.ndarray) -> np.ndarray:
        """The optimizer's vector of physical values and free segment start states."""
        theta = [p.to_theta(v) for p, v in zip(self.parameters, values, strict=True)]
        return np.concatenate([theta, (states / np.array(self.state_scale))[self.free_states]])

    def unpack(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(physical values, states (segments, 2)) of an optimizer vector, tied ẋ_i filled in."""
        count = len(self.parameters)
        values = np.array([p.from_theta(t) for p, t in zip(self.parameters, z[:count], strict=True)])
        states = np.zeros((self.segments, 2))
        states[self.free_states] = z[count:]
        return values, self.tie(values, states * np.array(self.state_scale))

    def tie(self, values: np.ndarray, states: np.ndarray) -> np.ndarray:
        """`states` with every tied segment's ẋ_i set stuck: v_rel = 1e-3 of the peak's velocity.

        Not v_rel = 0: at exactly zero the friction law gives μ = 0 with an unbounded slope, and the
        compiled Radau stays there (measured: a stuck start at x = 5.9e-8 m in case 1 physical kept
        v_rel = 0 and μ = 0 over 30 samples, against μ = 0.025 from v_rel = ±1e-13 m/s). From any
        v_rel inside the first zone it settles onto the stick branch within the first step.
        """
        if not self.tied.any():
            return states
        gamma = self.config_for(values).rig.velocity_factor
        creep = 1e-3 * (self._peak_velocity() or 0.0)
        tied = states.copy()
        tied[self.tied, 1] = (self.data.band_velocity[self.starts[self.tied]] - creep) / gamma
        return tied

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of z: the physical ranges of the parameters, states free."""
        free = int(np.count_nonzero(self.free_states))
        low = [p.theta_bounds()[0] for p in self.parameters] + [-np.inf] * free
        high = [p.theta_bounds()[1] for p in self.parameters] + [np.inf] * free
        return np.array(low), np.array(high)

    def initial_states(self, values: np.ndarray) -> np.ndarray:
        """Segment start states from the data (smoothed x and its derivative), else from a run.

        A tied segment (starting stuck) takes x_i from the stick line through the data around it
        and ẋ_i stuck (tie).
        """
        x = self.data.displacement
        if x is None:
            run = self.continuous_run(values, None)
            return np.column_stack([run.displacement[self.starts], run.velocity[self.starts]])
        window = min(2 * (int(0.02 * self.data.sample_rate) // 2) + 1, 2 * ((x.size - 1) // 2) - 1)
        window = max(window, 5)
        smooth = savgol_filter(x, window, 3)
        slope = savgol_filter(x, window, 3, deriv=1, delta=1.0 / self.data.sample_rate)
        states = np.column_stack([smooth[self.starts], slope[self.starts]])
        if self.tied.any():
            band, rate = self.data.band_velocity, self.data.sample_rate
            gamma, sigma = self.config.rig.velocity_factor, self.sigma["displacement"]
            tied = self.starts[self.tied]
            states[self.tied, 0] = stuck_positions(x, band, rate, gamma, sigma, self.stuck, tied)
        return self.tie(values, states)

    # -- runs ------------------------------------------------------------------------------------
    def config_for(self, values: np.ndarray) -> RunConfig:
        """The start configuration with the free parameters set."""
        return with_values(self.config, self.parameters, values)

    def integrator(self, values: np.ndarray) -> RigIntegrator:
        """A fresh integrator of the rig with these parameter values at the record's sample rate."""
        config = self.config_for(values)
        return RigIntegrator(
            config.rig,
            float(self.data.band_velocity[0]),
            sample_rate=self.data.sample_rate,
            rtol=config.rtol,
            **FIT_INTEGRATION,
        )

    def run(self, values: np.ndarray, states: np.ndarray) -> Run:
        """Every segment from its own start state: the model at every sample and the end states."""
        n = self.data.time.size
        x = np.empty(n)
        mu = np.empty(n)
        ends = np.empty((self.segments - 1, 2))
        states = self.tie(values, states)
        try:
            integrator = self.integrator(values)
            band, time = self.data.band_velocity, self.data.time
            for i, (start, end) in enumerate(zip(self.starts, self.ends, strict=True)):
                integrator.initial_displacement, integrator.initial_velocity = states[i]
                integrator.reset(band_velocity=float(band[start]), time=float(time[start]))
                if i == 0:
                    first = integrator.current()
                    x[0], mu[0] = first.displacement[0], first.friction_coefficient[0]
                part = integrator.advance(band[start + 1 : end + 1])
                x[start + 1 : end + 1] = part.displacement
                mu[start + 1 : end + 1] = part.friction_coefficient
                if i < self.segments - 1:
                    ends[i] = part.displacement[-1], part.velocity[-1]
        except (IntegrationError, ValueError):
            return Run(np.full(n, np.nan), np.full(n, np.nan), np.full(ends.shape, np.nan), failed=True)
        return Run(x, mu, ends)

    def continuous_run(self, values: np.ndarray, state: np.ndarray | None) -> Any:
        """One run over the whole record from `state` (x, ẋ) or the configuration's initial condition."""
        integrator = self.integrator(values)
        if state is not None:
            integrator.initial_displacement, integrator.initial_velocity = float(state[0]), float(state[1])
            integrator.reset()
        first = integrator.current()
        from ..core.trajectory import concatenate

        return concatenate([first, integrator.advance(self.data.band_velocity[1:])])

    # -- residuals and Jacobian ------------------------------------------------------------------
    def residuals_of(self, run: Run, states: np.ndarray) -> np.ndarray:
        """The residual vector of a run (noise units; defects weighted)."""
        parts = []
        for name, measured in self.data.streams.items():
            model = run.displacement if name == "displacement" else run.friction_coefficient
            residual = (model - measured) / self.sigma[name]
            if name == "friction_coefficient":
                residual = np.where(self.left_out, 0.0, residual)
            parts.append(residual)
        lx, lv = self._defect_scales()
        defects = (run.ends - states[1:]) / np.array([lx, lv])
        parts.append(self.defect_weight * defects.ravel())
        residual = np.concatenate(parts)
        return np.where(np.isfinite(residual), residual, FAILED)

    def _defect_scales(self) -> tuple[float, float]:
        """σ of x in the defects (σ_x, else that of μ as a displacement) and of ẋ (ω0 σ_x)."""
        if "displacement" in self.sigma:
            lx = self.sigma["displacement"]
        else:
            rig = self.config.rig
            lx = self.sigma["friction_coefficient"] * rig.normal_force / rig.stiffness
        return lx, lx * self.config.rig.angular_frequency

    def data_rows(self) -> int:
        """Residual rows that compare the model with measured samples."""
        return self.data.time.size * len(self.data.streams)

    def fitted_rows(self) -> int:
        """Data rows the fit uses: all but the μ samples left out next to a transition."""
        left_out = int(np.count_nonzero(self.left_out)) if "friction_coefficient" in self.data.streams else 0
        return self.data_rows() - left_out

    def jacobian_tasks(
        self, z: np.ndarray, parameters: bool = True
    ) -> list[tuple[np.ndarray, np.ndarray, float]]:
        """(values, states, step) of every perturbed run a Jacobian needs: P parameters, all x_i, all ẋ_i.

        Without `parameters` only the two state runs (a fit of the states alone).
        """
        values, states = self.unpack(z)
        count = len(self.parameters)
        _, high = self.bounds()
        tasks = []
        for j in range(count if parameters else 0):
            step = STEP if z[j] + STEP <= high[j] else -STEP
            moved = z.copy()
            moved[j] += step
            moved_values = self.unpack(moved)[0]
            tasks.append((moved_values, self.tie(moved_values, states), step))
        for column in range(2):
            step = self.state_steps[column]
            moved_states = states.copy()
            moved_states[:, column] += step * self.state_scale[column]
            tasks.append((values, self.tie(values, moved_states), step))
        return tasks

    def jacobian_from(self, z: np.ndarray, base: np.ndarray, runs: list[Run]) -> np.ndarray:
        """The dense Jacobian from the base residuals and the perturbed runs of jacobian_tasks.

        With runs for the states only, the parameters' columns are left zero.
        """
        parameters = len(runs) > 2
        count = len(self.parameters)
        tasks = self.jacobian_tasks(z, parameters)
        jac = np.zeros((base.size, z.size))
        for j in range(count if parameters else 0):
            _, task_states, step = tasks[j]
            jac[:, j] = self._difference(self.residuals_of(runs[j], task_states), base) / step
        starts, ends = self.starts, self.ends
        lx, lv = self._defect_scales()
        data_rows = self.data_rows()
        n = self.data.time.size
        columns = self.state_columns()
        for column in range(2):
            offset = count if parameters else 0
            _, task_states, step = tasks[offset + column]
            delta = self._difference(self.residuals_of(runs[offset + column], task_states), base) / step
            for i in range(self.segments):
                if column == 1 and self.tied[i]:
                    continue  # a tied ẋ_i is no variable
                col = columns[i, column]
                first = 0 if i == 0 else starts[i] + 1  # a boundary sample is its earlier segment's end
                for k in range(len(self.data.streams)):
                    rows = slice(k * n + first, k * n + ends[i] + 1)
                    jac[rows, col] = delta[rows]
                if i < self.segments - 1:
                    row = data_rows + 2 * i
                    own = delta[row : row + 2]  # d(end_i)/d(state_i) minus the known −1 of state_{i+1}
                    if not (column == 1 and self.tied[i + 1]):  # a tied ẋ_{i+1} did not move
                        own[column] += self.defect_weight * self.state_scale[column] / (lx, lv)[column]
                    jac[row : row + 2, col] = own
                if i > 0:
                    row = data_rows + 2 * (i - 1) + column
                    jac[row, col] = -self.defect_weight * self.state_scale[column] / (lx, lv)[column]
        return jac

    def _difference(self, moved: np.ndarray, base: np.ndarray) -> np.ndarray:
        """The change moved − base, 0 for a data row that jumped by more than JUMP noise units.

        μ changes by 0.16 (about 58 σ_μ at 1 % noise) within microseconds at every stick–slip
        transition, and in smaller steps where a segment's start settles onto the stick branch. A
        step of 1e-6 in θ that moves such an instant across a sample time changes that sample's
        residual by the whole jump: a forward difference of 1e7 or more noise units per unit of θ,
        which no smooth dependence gives (a slip's timing moves x by about 1e4 per unit of θ). Kept,
        one such row outweighs the record in JᵀJ (measured: 99 % of f0's information from one μ
        sample, its standard error collapsed 60-fold) and steers the Gauss–Newton steps. Such an
        entry is set to 0: the sample's smooth slope either side of the jump is negligible beside
        the record's, and the jump itself is no derivative.
        """
        difference = moved - base
        rows = self.data_rows()
        jumped = np.abs(difference[:rows]) > JUMP
        difference[:rows][jumped] = 0.0
        return difference


def _worker_start() -> None:
    """A forked worker takes SIGTERM's default action (death) and leaves Ctrl-C to its parent.

    It would inherit the parent's handlers. A Python handler runs only between bytecodes, so a
    SIGTERM from Pool.terminate that lands just before the worker blocks on the pool's task lock
    is never acted on, and the pool's join waits for ever (seen beside two CPU hogs in a test
    process whose SIGTERM handler raises KeyboardInterrupt).
    """
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _worker_run(task: tuple[np.ndarray, np.ndarray, float]) -> Run:
    assert _WORKER_PROBLEM is not None
    return _WORKER_PROBLEM.run(task[0], task[1])


class Runner:
    """Runs of a problem, serially or in a pool of forked worker processes (closed by `close`)."""

    def __init__(self, problem: ShootingProblem, workers: int) -> None:
        global _WORKER_PROBLEM
        self.problem = problem
        self.pool: Any = None
        self._last: tuple[np.ndarray, np.ndarray] | None = None
        if workers > 1:
            _WORKER_PROBLEM = problem  # the forked workers inherit it
            self.pool = multiprocessing.get_context("fork").Pool(workers, initializer=_worker_start)

    def map(self, tasks: list[tuple[np.ndarray, np.ndarray, float]]) -> list[Run]:
        """The runs of the tasks, in order."""
        if self.pool is None:
            return [self.problem.run(values, states) for values, states, _ in tasks]
        runs: list[Run] = self.pool.map(_worker_run, tasks, chunksize=1)
        return runs

    def close(self) -> None:
        """End the worker processes (SIGTERM: at once, also after a Ctrl-C in the middle of a map)."""
        if self.pool is not None:
            self.pool.terminate()
            self.pool.join()
            self.pool = None

    def residuals(self, z: np.ndarray) -> np.ndarray:
        """The residual vector at z (kept for the Jacobian at the same z)."""
        values, states = self.problem.unpack(z)
        residual = self.problem.residuals_of(self.problem.run(values, states), states)
        self._last = (z.copy(), residual)
        return residual

    def jacobian(self, z: np.ndarray, parameters: bool = True) -> np.ndarray:
        """The dense Jacobian at z: the perturbed runs of jacobian_tasks, in the pool if there is one."""
        last = self._last
        base = last[1] if last is not None and np.array_equal(last[0], z) else self.residuals(z)
        runs = self.map(self.problem.jacobian_tasks(z, parameters))
        return self.problem.jacobian_from(z, base, runs)
