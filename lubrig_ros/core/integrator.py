"""Stiff integration of the rig  m ẍ + c ẋ + k x = N μ(v_band − γ ẋ)  sample by sample.

Method (compiled in kernels.py and stepper.py, one stepper for every friction law of
core.friction_laws): 3-stage Radau IIA (order 5, L-stable, stiffly accurate) with
adaptive steps and the embedded error estimate of Hairer & Wanner (as in scipy's Radau). The
stage equations are solved by full Newton on the three stage velocities only (displacements are
linear in them). Sticking (v_rel ≈ 0, where μ ∝ |v|^0.38 and dμ/dv reaches 1e11 s/m) needs two
safeguards, without which explicit methods fail and implicit ones chatter: a stuck mass is
predicted to move with the band, and each Newton iterate may change |v_rel| by at most a factor 4
and not jump across zero. Otherwise Newton lands on the unstable zone-2 root of equal μ.

Band velocity is known at the output samples only (as for a node receiving messages) and is taken
as linear between consecutive samples. Where it is a straight line a step may span samples
(stepper.py); every stepping decision depends on the samples received so far, so a run integrated
in one call, in blocks or sample by sample gives bit-identical results.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lubrig_ros.core.errors import InputError, LubrigError

from .friction_laws import law_for
from .kernels import _A, _A2, _C, _E, RIG_LAYOUT, specialize
from .params import RigParameters
from .stepper import (
    BUDGET,
    BUDGET_SPENT,
    COMPLETED,
    OK,
    PARTIAL_T0,
    STATE_SIZE,
    SUBSTEPS,
    initial_state,
)
from .trajectory import Trajectory, TrajectorySample


class IntegrationError(LubrigError, RuntimeError):
    """The integrator could not meet its tolerance (step size collapsed)."""


@dataclass
class RigIntegrator:
    """The rig as a steppable plant: feed band velocity samples, get sampled states back.

    Starts at rest relative to the static equilibrium x0 = μ(v_band(0)) N / k, displaced by
    `initial_perturbation` (the study's 1 %: x(0) = 1.01 x0, ẋ(0) = 0).
    """

    rig: RigParameters
    initial_band_velocity: float
    sample_rate: float = 1000.0  # Hz
    rtol: float = 1e-8
    initial_perturbation: float = 0.01
    initial_displacement: float | None = None  # m; overrides the perturbation rule
    initial_velocity: float = 0.0  # m/s
    #: longest step in sample periods: a step spans samples where the band is a line (stepper.py);
    #: a new value applies to the steps begun after it is set
    max_step_samples: int = 256
    #: Newton iterations every stage solve takes at least: 1 (the first iterate is accepted when
    #: the last solve's contraction says it is converged), or 2 (never the first: the result is
    #: then a smooth function of the parameters, which forward differences need; fit/shooting.py)
    min_newton_iterations: int = 1
    _state: np.ndarray = field(init=False, repr=False)
    _rig_array: np.ndarray = field(init=False, repr=False)
    _fp: np.ndarray = field(init=False, repr=False)
    _stepper: Any = field(init=False, repr=False)
    _evaluator: Any = field(init=False, repr=False)
    _atol: tuple[float, float] = field(init=False, repr=False)
    _coupling: float = field(init=False, repr=False)  # γ
    _one: tuple[np.ndarray, ...] = field(init=False, repr=False)  # advance_bounded's band, x, ẋ, v_rel

    def __post_init__(self) -> None:
        for name in ("initial_band_velocity", "sample_rate", "rtol", "initial_perturbation"):
            value = float(getattr(self, name))
            if not math.isfinite(value):
                raise InputError(f"{name}={value!r} must be finite")
            setattr(self, name, value)
        if self.sample_rate <= 0.0:
            raise InputError(f"sample_rate={self.sample_rate!r} must be > 0 Hz")
        self._check_settings()
        if not 1e-13 <= self.rtol <= 1e-2:
            raise InputError(f"rtol={self.rtol!r} is outside the valid range [1e-13, 1e-2]")
        self._rig_array = np.array([float(getattr(self.rig, name)) for name in RIG_LAYOUT])
        law = law_for(self.rig.friction)
        self._stepper, self._evaluator = specialize(law.kernel)  # compiled for this law, bound once
        self._fp = np.ascontiguousarray(law.pack(self.rig.friction), dtype=np.float64)
        self._atol = self._scales
        self._coupling = self.rig.velocity_factor
        self._one = tuple(np.zeros(1) for _ in range(4))
        self.reset()

    @property
    def dt(self) -> float:
        """Sample period in s."""
        return 1.0 / self.sample_rate

    @property
    def equilibrium_displacement(self) -> float:
        """x0 for the initial band velocity, m."""
        mu = float(self._evaluator(np.array([self.initial_band_velocity]), self._fp)[0][0])
        return mu * self.rig.normal_force / self.rig.stiffness

    def reset(self, band_velocity: float | None = None, time: float = 0.0) -> None:
        """Back to the initial condition at rig time `time` (s, default 0).

        With `band_velocity` the initial condition is that of this band velocity (equilibrium plus
        the perturbation); a plant recovering from a failed sample restarts there at its next
        sample time instead of going back to t = 0.
        """
        if band_velocity is not None:
            self.initial_band_velocity = float(band_velocity)
        self._check_resolved(self.initial_band_velocity)
        if not math.isfinite(time):
            raise InputError(f"time={time!r} must be finite")
        if self.initial_displacement is not None:
            x_start = float(self.initial_displacement)
        else:
            x_start = (1.0 + self.initial_perturbation) * self.equilibrium_displacement
        self._state = initial_state(
            float(time), x_start, float(self.initial_velocity), self.initial_band_velocity, self.dt
        )

    def _check_settings(self) -> None:
        """InputError for a bad max_step_samples or min_newton_iterations (settable: every call)."""
        span = self.max_step_samples
        if isinstance(span, bool) or not isinstance(span, int) or span < 1:
            raise InputError(f"max_step_samples={span!r} must be an integer >= 1")
        newton = self.min_newton_iterations
        if isinstance(newton, bool) or newton not in (1, 2):
            raise InputError(f"min_newton_iterations={newton!r} must be 1 or 2")

    def _check_resolved(self, band_velocity: float) -> None:
        """ValueError for a band at rest in all but name: 0 < |v| below the velocity tolerance.

        The error control resolves velocities down to its absolute tolerance (`_scales`); a band
        slower than that sets a relative velocity the integrator cannot see, and the stage solve
        near v_rel = 0 (where dμ/dv is unbounded) stalls instead of converging. 0 is a band at
        rest and runs (the mass stays in equilibrium). Later band values that small are integrated
        as 0 (`_step`).
        """
        resolution = self._scales[1]
        if 0.0 < abs(band_velocity) < resolution:
            raise InputError(
                f"band velocity {band_velocity!r} m/s is below the velocity the integrator resolves "
                f"at rtol {self.rtol:g} ({resolution:.2g} m/s); expected 0 (band at rest) or "
                f"|v| >= {resolution:.2g} m/s"
            )

    @property
    def _scales(self) -> tuple[float, float]:
        length = self.rtol * 1e-2 * self.rig.friction.normal_force / self.rig.stiffness
        return length, length * self.rig.angular_frequency

    @property
    def time(self) -> float:
        """Rig time of the last completed sample, s (a sample in progress has not reached its time)."""
        return float(self._state[PARTIAL_T0] if self.in_progress else self._state[0])

    @property
    def substeps(self) -> int:
        """Accepted Radau steps so far (work measure)."""
        return int(self._state[SUBSTEPS])

    @property
    def in_progress(self) -> bool:
        """True while a sample started by advance_bounded is unfinished (its budget ran out)."""
        return not math.isnan(self._state[PARTIAL_T0])

    def snapshot(self) -> np.ndarray:
        """A copy of the full stepper state (time, state, step size, counters) for `restore`."""
        return self._state.copy()

    def restore(self, snapshot: np.ndarray) -> None:
        """Back to a state taken with `snapshot` (e.g. to redo a failed block sample by sample)."""
        state = np.array(snapshot, dtype=np.float64).reshape(-1)
        if state.size != STATE_SIZE:
            raise InputError(f"a snapshot of {state.size} values; expected {STATE_SIZE} (snapshot())")
        self._state = state

    def current(self) -> Trajectory:
        """The present state as a one-sample trajectory."""
        t, x, w, vb = self._state[:4]
        return self._sampled(np.array([t]), np.array([x]), np.array([w]), np.array([vb]))

    def advance(self, band_velocities: np.typing.ArrayLike) -> Trajectory:
        """Integrate over the next len(band_velocities) samples; sample k holds v_band at t + (k+1)·dt."""
        band = self._band(band_velocities)
        t_start = self._state[0]
        out_x, out_w = self._states(band)
        time = t_start + self.dt * np.arange(1, band.size + 1)
        return self._sampled(time, out_x, out_w, band)

    def advance_states(self, band_velocities: np.typing.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """The displacement (m) and velocity (m/s) at the next samples: `advance` without μ and v_rel."""
        return self._states(self._band(band_velocities))

    def _states(self, band: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.in_progress:
            raise RuntimeError("a sample is in progress (advance_bounded ran out of budget); finish it first")
        return self._run(band, 0)

    def advance_bounded(self, band_velocity: float, max_attempts: int) -> TrajectorySample | None:
        """One sample with at most `max_attempts` step attempts; None when they ran out.

        A real-time plant cannot wait for a sample that needs thousands of substeps: it calls this
        once per tick and, on None, calls again at the next tick with the same band velocity, which
        carries on where the last call stopped. The finished sample equals advance([band_velocity])
        bit for bit, returned as floats: the real-time tick's fast path, which computes in
        preallocated one-sample buffers and makes no arrays per sample.
        """
        if max_attempts < 1:
            raise InputError(f"max_attempts={max_attempts!r} must be >= 1 step attempt")
        band, out_x, out_w, relative = self._one
        band[0] = band_velocity
        if not math.isfinite(band[0]):
            self._band(band)  # raises, naming the value
        given = band[0]
        if 0.0 < abs(given) < self._atol[1]:
            band[0] = 0.0  # integrated at rest, as in _run
        state = self._state
        t_start = state[0] if math.isnan(state[PARTIAL_T0]) else state[PARTIAL_T0]
        self._step(band, max_attempts, out_x, out_w)
        if not math.isnan(state[PARTIAL_T0]):
            return None
        relative[0] = given - self._coupling * out_w[0]  # rig.relative_velocity, on floats
        mu = self._evaluator(relative, self._fp)[0]
        return TrajectorySample(
            float(t_start + self.dt),
            float(out_x[0]),
            float(out_w[0]),
            float(mu[0]),
            float(given),
            float(relative[0]),
        )

    def _band(self, band_velocities: np.typing.ArrayLike) -> np.ndarray:
        band = np.ascontiguousarray(band_velocities, dtype=np.float64).reshape(-1)
        if not np.isfinite(band).all():
            bad = band[~np.isfinite(band)][0]
            raise InputError(f"band velocity {bad!r} is not finite; expected finite m/s values")
        return band

    def _run(self, band: np.ndarray, max_attempts: int) -> tuple[np.ndarray, np.ndarray]:
        unresolved = (band != 0.0) & (np.abs(band) < self._atol[1])
        if unresolved.any():
            # a band at rest in all but name (0 < |v| below the velocity tolerance, a subnormal):
            # integrated as at rest, which it is to the tolerance; from a mass at rest the stage
            # solve otherwise stalled (20 samples of 5e-324 m/s in 100 s). Outputs keep the value.
            band = np.where(unresolved, 0.0, band)
        out_x = np.empty(band.size)
        out_w = np.empty(band.size)
        done = self._step(band, max_attempts, out_x, out_w)
        return out_x[:done], out_w[:done]

    def _step(self, band: np.ndarray, max_attempts: int, out_x: np.ndarray, out_w: np.ndarray) -> int:
        """The compiled stepper over `band` into out_x/out_w; the samples completed."""
        self._check_settings()
        atol_x, atol_w = self._atol
        self._state[BUDGET] = float(max_attempts)
        status = self._stepper(
            self._state,
            band,
            self.dt,
            self._rig_array,
            self._fp,
            self.rtol,
            atol_x,
            atol_w,
            _A,
            _A2,
            _C,
            _E,
            float(self.max_step_samples),
            float(self.min_newton_iterations),
            out_x,
            out_w,
        )
        if status not in (OK, BUDGET_SPENT):
            raise IntegrationError(
                f"step size collapsed at t={self._state[0]:.6g} s (rtol={self.rtol}); "
                "the band velocity or rig parameters may be outside the model's range"
            )
        return int(self._state[COMPLETED])

    def _sampled(self, time: np.ndarray, x: np.ndarray, w: np.ndarray, band: np.ndarray) -> Trajectory:
        relative = self.rig.relative_velocity(band, w)
        mu = self._evaluator(np.ascontiguousarray(relative), self._fp)[0]  # params already packed
        return Trajectory(
            time=time,
            displacement=x,
            velocity=w,
            friction_coefficient=mu,
            band_velocity=band,
            relative_velocity=relative,
        )
