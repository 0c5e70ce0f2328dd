"""The sample loop around the Radau IIA step (compiled with numba, one copy per friction law).

The band velocity is known at the output samples only and is taken as linear between them. Where
the band is a straight line over several samples (a constant band, a plateau, a ramp), a step may
span them: it is computed on the line through the last two samples extended ahead (a
*speculative* step), and the samples it covers get their output from the step's collocation
polynomial (Radau IIA's continuous extension, the one scipy's Radau uses). Each later sample is
checked against the line when it arrives:

* on the line (within LINE_TOLERANCE of its magnitude): the step still holds; its output is read
  off the polynomial, or the step is committed once a sample lies past its end;
* off the line (a kink: a corner of the band's profile, a measured band's noise): the step is
  valid up to the previous sample only. It is integrated again from its start to that sample
  (substeps landing on it, on the same line) and stepping carries on from there.

A step speculates only when the last three samples are collinear, so a band with a kink at every
sample (a measured one) is stepped as before, every step ending on a sample, with no step wasted.

Every decision depends on the samples received so far, never on how they were grouped into calls:
a run is bit-identical whether advanced in one call, in blocks of any length, or sample by sample
(also with a step budget, see BUDGET_SPENT). With max_span = 1 no step spans a sample.

The state array (STATE_SIZE float64, layout below) holds everything between calls.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

# Status codes of the compiled loop.
OK = 0
STEP_TOO_SMALL = 1
#: The call's step budget (state[BUDGET]) ran out inside a sample; the next call resumes it.
BUDGET_SPENT = 2

#: Layout of the state. T, X, W, BAND: the last output sample (time, x, ẋ, v_band); H: the next
#: step size proposed; SUBSTEPS: accepted steps so far.
T, X, W, BAND, H, SUBSTEPS = 0, 1, 2, 3, 4, 5
BUDGET = 6  # step attempts allowed in one call, accepted or rejected (0: unlimited)
PARTIAL_T0 = 7  # NaN, or T while a sample is in progress (its budget ran out)
COMPLETED = 8  # samples the last call completed
PREV_BAND = 9  # v_band one sample before T (NaN: not known)
STEP_T, STEP_X, STEP_W = 10, 11, 12  # where the integration stands: a step boundary
PENDING = 13  # length of a speculative step from STEP_T past T (0: none)
END_X, END_W = 14, 15  # its end
STAGES = 16  # its stage increments: x at 16..18, ẋ at 19..21
LINE_T0, LINE_V0, LINE_V1 = 22, 23, 24  # its band line: through (t0, v0) and (t0 + dt, v1)
REDO = 25  # NaN, or the time a step found invalid is being integrated again to
RETRY = 26  # 1 when the last step attempt was rejected (the next one may refine its error estimate)
#: The last stage solve's contraction estimate θ/(1 − θ) (Hairer & Wanner's FACCON; 1 at the start):
#: the next solve accepts its first Newton iterate when this times the iterate's increment is below
#: 3 % of the tolerance (kernels._radau_step_py).
NEWTON_RATE = 27
#: The last accepted step's length (0: none to extrapolate, after a restart) and its ẋ stage
#: increments (28..30): the next step's stages are predicted from its collocation polynomial.
LAST_H, LAST_STAGES = 28, 29
STATE_SIZE = 32

#: A sample is on the band's line when it is within this fraction of the larger of its own and
#: the line's magnitudes (a profile's ramp computed in floating point is straight to a few ulp).
LINE_TOLERANCE = 1e-12
_MIN_FACTOR = 0.2
_MAX_FACTOR = 8.0
_S6 = math.sqrt(6.0)
#: Radau IIA's collocation polynomial: y(t + θh) = y + Σ_i Z_i (P[i,0] θ + P[i,1] θ² + P[i,2] θ³).
_P = np.array(
    [
        [13.0 / 3.0 + 7.0 * _S6 / 3.0, -23.0 / 3.0 - 22.0 * _S6 / 3.0, 10.0 / 3.0 + 5.0 * _S6],
        [13.0 / 3.0 - 7.0 * _S6 / 3.0, -23.0 / 3.0 + 22.0 * _S6 / 3.0, 10.0 / 3.0 - 5.0 * _S6],
        [1.0 / 3.0, -8.0 / 3.0, 10.0 / 3.0],
    ]
)

# Placeholders: each law's specialized copies bind them to the law's Radau step and to its own
# _land_py (kernels.specialize).
_STEP: Any = None
_LAND: Any = None


@njit(cache=True)
def _factor(err: float) -> float:
    """Step size factor from an error norm (order 5: the 1/4 power, as scipy's Radau)."""
    if not math.isfinite(err):
        return 0.5
    factor = 0.9 / math.sqrt(math.sqrt(err)) if err > 0.0 else _MAX_FACTOR
    return min(_MAX_FACTOR, max(_MIN_FACTOR, factor))


@njit(cache=True)
def _on_line(v: float, t: float, t0: float, v0: float, v1: float, dt: float) -> bool:
    """Whether v at t lies on the line through (t0, v0) and (t0 + dt, v1)."""
    if math.isnan(v0):
        return False
    expected = v0 + (v1 - v0) * ((t - t0) / dt)
    return abs(v - expected) <= LINE_TOLERANCE * max(abs(v), abs(expected), abs(v0), abs(v1))


@njit(cache=True)
def _emit(
    state: np.ndarray, v: float, x: float, w: float, out_x: np.ndarray, out_w: np.ndarray, k: int
) -> None:
    """Sample k is done: x, ẋ at T + dt."""
    state[PREV_BAND] = state[BAND]
    state[BAND] = v
    state[X], state[W] = x, w
    out_x[k], out_w[k] = x, w


@njit(cache=True)
def _read_pending(state: np.ndarray, theta: float) -> tuple[float, float]:
    """x, ẋ of the pending step at fraction theta of it (its collocation polynomial)."""
    p1 = theta
    p2 = theta * theta
    p3 = p2 * theta
    x, w = state[STEP_X], state[STEP_W]
    for i in range(3):
        c = _P[i, 0] * p1 + _P[i, 1] * p2 + _P[i, 2] * p3
        x += state[STAGES + i] * c
        w += state[STAGES + 3 + i] * c
    return x, w


def _land_py(
    state: np.ndarray,
    target: float,
    line: tuple[float, float, float, float, bool],
    speculate: bool,
    run: tuple[
        np.ndarray,
        np.ndarray,
        np.ndarray,
        tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
        float,
        float,
    ],
    scratch: tuple[np.ndarray, np.ndarray],
    attempts: float,
) -> tuple[int, float, bool]:
    """Step from STEP_T until `target` is reached (landing on it) or, when `speculate`, passed.

    line: (t0, v0, v1, dt, corner), the band through (t0, v0) and (t0 + dt, v1), and whether its
    slope changes at t0 (a step from there, rejected, refines its error estimate); run: (rig, fp, tol,
    tableau, max_h, min_newton), what every step of the call shares; scratch: (work, jac). Returns (status,
    attempts, passed): passed means a speculative step now pends (PENDING, END_*, STAGES set;
    STEP_* its start).
    """
    t0, v0, v1, dt, corner = line
    rig, fp, tol, tableau, max_h, min_newton = run
    work, jac = scratch
    aa, a2, cc, ee = tableau
    budget = state[BUDGET]
    ts, x, w, h = state[STEP_T], state[STEP_X], state[STEP_W], min(state[H], max_h)
    while ts < target:
        if budget > 0.0 and attempts >= budget:
            state[STEP_T], state[STEP_X], state[STEP_W], state[H] = ts, x, w, h
            return BUDGET_SPENT, attempts, False
        attempts += 1.0
        remaining = target - ts
        last = h >= remaining * (1.0 - 1e-12)
        ahead = last and speculate and h > remaining * (1.0 + 1e-9)
        step = h if (ahead or not last) else remaining
        refine = corner and ts == t0 and state[RETRY] != 0.0
        newton = (min_newton, state[NEWTON_RATE])
        last_step = (state[LAST_H], state[LAST_STAGES], state[LAST_STAGES + 1], state[LAST_STAGES + 2])
        accepted, x_new, w_new, err, state[NEWTON_RATE] = _STEP(
            x, w, ts, step, t0, dt, v0, v1, rig, fp, tol, aa, a2, cc, ee, work, jac, refine, newton, last_step
        )
        factor = _factor(err)
        state[RETRY] = 0.0 if accepted else 1.0
        if not accepted:
            h = step * min(factor, 0.9)
            if h < 1e-15 * max(1.0, abs(ts)):
                return STEP_TOO_SMALL, attempts, False
            continue
        state[SUBSTEPS] += 1.0
        state[LAST_H] = step
        for i in range(3):
            state[LAST_STAGES + i] = work[7, i]
        h_new = step * factor
        if last and not ahead and step < h and factor >= 1.0:
            h_new = max(h, h_new)  # a step cut short to land on the target says little
        h = min(h_new, max_h)
        if ahead:
            state[STEP_T], state[STEP_X], state[STEP_W], state[H] = ts, x, w, h
            state[PENDING], state[END_X], state[END_W] = step, x_new, w_new
            for i in range(3):
                state[STAGES + i] = work[6, i]
                state[STAGES + 3 + i] = work[7, i]
            state[LINE_T0], state[LINE_V0], state[LINE_V1] = t0, v0, v1
            return OK, attempts, True
        x, w = x_new, w_new
        ts = target if last else ts + step
    state[STEP_T], state[STEP_X], state[STEP_W], state[H] = target, x, w, h
    return OK, attempts, False


def _advance_py(
    state: np.ndarray,
    band: np.ndarray,
    dt: float,
    rig: np.ndarray,
    fp: np.ndarray,
    rtol: float,
    atol_x: float,
    atol_w: float,
    aa: np.ndarray,
    a2: np.ndarray,
    cc: np.ndarray,
    ee: np.ndarray,
    max_span: float,
    min_newton: float,
    out_x: np.ndarray,
    out_w: np.ndarray,
) -> int:
    """Advance over len(band) samples (band[k] at T + (k+1)·dt); state is updated in place.

    Steps are at most max_span samples long; every stage solve takes at least min_newton (1 or 2)
    Newton iterations (kernels._radau_step_py). On failure (STEP_TOO_SMALL) the state is that of the
    last completed sample, so a caller can carry on from the sample grid. With a budget
    (state[BUDGET] > 0 step attempts) a call that spends it inside a sample returns BUDGET_SPENT:
    the next call with the same band value finishes that sample first (a resumed sample gives the
    same result as one integrated in one call). state[COMPLETED] counts the samples this call wrote
    to out_x/out_w.
    """
    run = (rig, fp, np.array([rtol, atol_x, atol_w]), (aa, a2, cc, ee), max_span * dt, min_newton)
    scratch = (np.empty((8, 3)), np.empty((3, 3)))
    attempts = 0.0
    for k in range(band.size):
        v = band[k]
        t_prev = state[T]
        t_k = t_prev + dt
        state[COMPLETED] = k
        if state[PENDING] > 0.0:  # a speculative step covers T: does v keep its line?
            t_end = state[STEP_T] + state[PENDING]
            if _on_line(v, t_k, state[LINE_T0], state[LINE_V0], state[LINE_V1], dt):
                if t_k < t_end - 1e-9 * dt:
                    x, w = _read_pending(state, (t_k - state[STEP_T]) / state[PENDING])
                    state[T] = t_k
                    _emit(state, v, x, w, out_x, out_w, k)
                    continue
                state[STEP_T], state[STEP_X], state[STEP_W] = t_end, state[END_X], state[END_W]
                state[PENDING] = 0.0
                if t_k <= t_end + 1e-9 * dt:  # its end is this sample
                    state[STEP_T] = t_k
                    state[T] = t_k
                    _emit(state, v, state[END_X], state[END_W], out_x, out_w, k)
                    continue
            else:
                state[PENDING] = 0.0
                state[REDO] = t_prev  # valid up to the previous sample only
                state[LAST_H] = 0.0  # integrated again from its start: no step ends there
        if not math.isnan(state[REDO]):
            line = (state[LINE_T0], state[LINE_V0], state[LINE_V1], dt, False)
            status, attempts, _ = _LAND(state, state[REDO], line, False, run, scratch, attempts)
            if status != OK:
                return _stop(state, status, dt)
            state[REDO] = math.nan
        corner = not _on_line(v, t_k, t_prev - dt, state[PREV_BAND], state[BAND], dt)
        speculate = max_span > 1.0 and not corner
        line = (t_prev, state[BAND], v, dt, corner)
        status, attempts, ahead = _LAND(state, t_k, line, speculate, run, scratch, attempts)
        if status != OK:
            return _stop(state, status, dt)
        state[PARTIAL_T0] = math.nan
        state[T] = t_k
        if ahead:
            x, w = _read_pending(state, (t_k - state[STEP_T]) / state[PENDING])
            _emit(state, v, x, w, out_x, out_w, k)
        else:
            _emit(state, v, state[STEP_X], state[STEP_W], out_x, out_w, k)
    state[COMPLETED] = band.size
    return OK


@njit(cache=True)
def _stop(state: np.ndarray, status: int, dt: float) -> int:
    """The call ends inside a sample: resumable (BUDGET_SPENT), or back on the last sample."""
    if status == BUDGET_SPENT:
        state[PARTIAL_T0] = state[T]
        return status
    # the step size collapsed: leave the state on the sample grid, at the last completed sample
    state[STEP_T], state[STEP_X], state[STEP_W] = state[T], state[X], state[W]
    state[PENDING] = 0.0
    state[REDO] = math.nan
    state[PARTIAL_T0] = math.nan
    state[RETRY] = 0.0
    state[LAST_H] = 0.0
    state[H] = 0.1 * dt
    return status


def initial_state(time: float, x: float, w: float, band_velocity: float, dt: float) -> np.ndarray:
    """The state at rest at `time`: (x, ẋ), the band at band_velocity, no band before it known."""
    state = np.zeros(STATE_SIZE)
    state[T], state[X], state[W], state[BAND], state[H] = time, x, w, band_velocity, 0.1 * dt
    state[PARTIAL_T0] = math.nan
    state[PREV_BAND] = math.nan
    state[STEP_T], state[STEP_X], state[STEP_W] = time, x, w
    state[REDO] = math.nan
    state[NEWTON_RATE] = 1.0
    return state
