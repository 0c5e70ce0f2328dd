"""Compiled (numba) kernels: the Radau IIA rig stepper and the one adapter to friction-law kernels.

Friction laws reach the compiled code through one adapter (this module):

* a law's scalar kernel ``(v, p) -> (μ, dμ/dv)`` is decorated with :func:`law_kernel`, which
  compiles it for :data:`LAW_SIGNATURE` (v float64, p a contiguous float64 array) with its own
  on-disk cache;
* the stepper (:func:`advance`) and the vectorized evaluation (:func:`evaluate_law`) are compiled
  ONCE for a first-class function argument of type :data:`LAW_KERNEL` and call the law through its
  address. There is one compiled stepper for every law.

Why this design (measured, see docs/extending.md): numba offers three ways to hand a function to
a compiled one. (1) Passing the dispatcher itself (argument typed ``Dispatcher``) specializes the
callee per law and inlines it, but such a signature never hits numba's cache: every process
recompiled the stepper (≈ 4–6 s) and each run added a new cache file. (2) A factory building a
stepper per law (closure) is cached by the factory's file, so a change in the law's file would
keep running a stale compiled copy (the bug that once had every kernel in this one file). (3) A
first-class function type (what this module does): the stepper is compiled and cached once; the
law's kernel is compiled and cached by its own file, and the stepper only holds its address at
call time. A change to a law's file therefore recompiles that law's kernel and nothing else, and
no compiled code of one file ever embeds code of another (test/test_friction_laws.py checks it in
fresh processes). The price is an indirect, not inlined, call to μ(v) — 3 to 4 per Newton
iteration — which costs a few per cent of integration time (figures in docs/extending.md); the
default law's results stay bit-identical (no fast-math: inlining does not change floating point).

Cache staleness inside one file still matters: helpers a kernel calls directly (numba inlines
njit callees into the caller's cached code) must live in the kernel's own file, as
core/junction.py does.

Integrator: 3-stage Radau IIA (order 5, L-stable, stiffly accurate) with adaptive substeps and the
embedded error estimate of Hairer & Wanner (as in scipy's Radau); full Newton on the three stage
velocities (displacements are linear in them) with a trust region in log|v_rel|.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit, types
from numba.core.types import FunctionType

#: Type of a law's p: a contiguous, writable float64 array.
LAW_PARAMETERS = types.Array(types.float64, 1, "C")
#: Signature every law kernel is compiled for: (v, p) -> (μ, dμ/dv).
LAW_SIGNATURE = types.UniTuple(types.float64, 2)(types.float64, LAW_PARAMETERS)
#: The first-class function type the stepper receives a law kernel as.
LAW_KERNEL = FunctionType(LAW_SIGNATURE)


def law_kernel(function: Callable[..., tuple[float, float]]) -> Any:
    """Decorator: compile a friction law's scalar kernel (v, p) -> (μ, dμ/dv) for the stepper.

    Compiled eagerly for LAW_SIGNATURE with numba's on-disk cache (keyed on the kernel's own file).
    """
    return njit(LAW_SIGNATURE, cache=True)(function)


def _evaluate_law_py(law: Any, v: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    mu = np.empty(v.size)
    dmu = np.empty(v.size)
    for i in range(v.size):
        mu[i], dmu[i] = law(v[i], p)
    return mu, dmu


@functools.cache
def _evaluator() -> Any:
    array = types.Array(types.float64, 1, "C")
    signature = types.Tuple((array, array))(LAW_KERNEL, array, LAW_PARAMETERS)
    return njit(signature, cache=True)(_evaluate_law_py)


def evaluate_law(kernel: Any, velocity: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """μ and dμ/dv of a law kernel at every velocity of a 1-D float64 array (p: law.pack(params))."""
    v = np.ascontiguousarray(velocity, dtype=np.float64).reshape(-1)
    return _evaluator()(kernel, v, np.ascontiguousarray(p, dtype=np.float64))


_S6 = math.sqrt(6.0)
_C = np.array([(4.0 - _S6) / 10.0, (4.0 + _S6) / 10.0, 1.0])
_A = np.array(
    [
        [(88.0 - 7.0 * _S6) / 360.0, (296.0 - 169.0 * _S6) / 1800.0, (-2.0 + 3.0 * _S6) / 225.0],
        [(296.0 + 169.0 * _S6) / 1800.0, (88.0 + 7.0 * _S6) / 360.0, (-2.0 - 3.0 * _S6) / 225.0],
        [(16.0 - _S6) / 36.0, (16.0 + _S6) / 36.0, 1.0 / 9.0],
    ]
)
_A2 = _A @ _A
_E = np.array([-13.0 - 7.0 * _S6, -13.0 + 7.0 * _S6, -1.0]) / 3.0
_MU_REAL = 3.0 + 3.0 ** (2.0 / 3.0) - 3.0 ** (1.0 / 3.0)
_NEWTON_MAXITER = 40
_REL_FACTOR = 4.0
_NEWTON_TOL = 0.03
_MIN_FACTOR = 0.2
_MAX_FACTOR = 8.0

# Status codes of the compiled kernel.
OK = 0
STEP_TOO_SMALL = 1


@njit(cache=True)
def _solve3(a: np.ndarray, b: np.ndarray, x: np.ndarray) -> None:
    """Solve the 3x3 system a x = b by Gaussian elimination with partial pivoting (a, b destroyed)."""
    for col in range(3):
        pivot = col
        for row in range(col + 1, 3):
            if abs(a[row, col]) > abs(a[pivot, col]):
                pivot = row
        if pivot != col:
            for j in range(3):
                a[col, j], a[pivot, j] = a[pivot, j], a[col, j]
            b[col], b[pivot] = b[pivot], b[col]
        for row in range(col + 1, 3):
            factor = a[row, col] / a[col, col]
            for j in range(col, 3):
                a[row, j] -= factor * a[col, j]
            b[row] -= factor * b[col]
    for row in range(2, -1, -1):
        acc = b[row]
        for j in range(row + 1, 3):
            acc -= a[row, j] * x[j]
        x[row] = acc / a[row, row]


@njit(cache=True)
def _radau_step(
    law: Any,
    x: float,
    w: float,
    t: float,
    h: float,
    t0: float,
    dt: float,
    vb0: float,
    vb1: float,
    rig: np.ndarray,
    fp: np.ndarray,
    rtol: float,
    atol_x: float,
    atol_w: float,
    aa: np.ndarray,
    a2: np.ndarray,
    cc: np.ndarray,
    ee: np.ndarray,
    work: np.ndarray,
    jac: np.ndarray,
) -> tuple[bool, float, float, float]:
    """One Radau IIA step of size h from t; returns (accepted, x_new, w_new, error_norm).

    work (8x3) and jac (3x3) are scratch space, allocated once per advance() call.
    """
    mass, damp, stiff, gamma, normal = rig[0], rig[1], rig[2], rig[3], rig[4]
    slope_vb = (vb1 - vb0) / dt
    vb, wst, g, gw, res, delta, zx, zw = (
        work[0], work[1], work[2], work[3], work[4], work[5], work[6], work[7]
    )
    for i in range(3):
        vb[i] = vb0 + slope_vb * (t + cc[i] * h - t0)
    # Newton on the stage velocities W (displacements X = x + h A W). Predictor: a sliding mass
    # keeps its velocity; a stuck one (|v_rel| ≪ v_band) keeps its relative velocity, i.e. moves
    # with the band. Starting a stuck mass at constant ẋ would put the stages on the unstable
    # zone-2 branch, which has the same μ and is a spurious root of the stage equations.
    vb_now = vb0 + slope_vb * (t - t0)
    rel_now = vb_now - gamma * w
    stuck = abs(rel_now) < 1e-3 * abs(vb_now)
    mu0, dmu0 = law(rel_now, fp)
    if not math.isfinite(dmu0):
        dmu0 = 1e300
    f_w = (normal * mu0 - damp * w - stiff * x) / mass
    for i in range(3):
        # sliding: explicit-Euler velocity; stuck: follow the band
        wst[i] = w + (vb[i] - vb_now) / gamma if stuck else w + cc[i] * h * f_w
    converged = False
    norm_old = math.inf
    for _ in range(_NEWTON_MAXITER):
        for j in range(3):
            xj = x + h * (aa[j, 0] * wst[0] + aa[j, 1] * wst[1] + aa[j, 2] * wst[2])
            mu, dmu = law(vb[j] - gamma * wst[j], fp)
            if not math.isfinite(dmu):
                dmu = 1e300
            g[j] = (normal * mu - damp * wst[j] - stiff * xj) / mass
            gw[j] = (-gamma * normal * dmu - damp) / mass
        for i in range(3):
            res[i] = wst[i] - w - h * (aa[i, 0] * g[0] + aa[i, 1] * g[1] + aa[i, 2] * g[2])
            for j in range(3):
                jac[i, j] = -h * aa[i, j] * gw[j] + h * h * stiff / mass * a2[i, j]
            jac[i, i] += 1.0
        for i in range(3):
            res[i] = -res[i]
        _solve3(jac, res, delta)
        clamped = False
        norm = 0.0
        for i in range(3):
            if not math.isfinite(delta[i]):
                return False, x, w, math.inf
            old_rel = vb[i] - gamma * wst[i]
            new_w = wst[i] + delta[i]
            new_rel = vb[i] - gamma * new_w
            # Trust region in log|v_rel|: an iterate may change |v_rel| by at most a factor
            # _REL_FACTOR and may not cross v_rel = 0 from far away. Without it, Newton jumps
            # between branches of equal μ (stuck zone 1 and unstable zone 2).
            if old_rel != 0.0:
                ratio = new_rel / old_rel
                if ratio < 0.0 and abs(old_rel) <= 1e-16:
                    pass
                elif ratio < 1.0 / _REL_FACTOR:
                    new_w = (vb[i] - old_rel / _REL_FACTOR) / gamma
                    clamped = True
                elif ratio > _REL_FACTOR:
                    new_w = (vb[i] - old_rel * _REL_FACTOR) / gamma
                    clamped = True
            norm = max(norm, abs(new_w - wst[i]) / (atol_w + rtol * abs(new_w)))
            wst[i] = new_w
        # Stop when the remaining error, estimated from the contraction rate θ of successive
        # increments (Hairer & Wanner IV.8), is a small fraction of the tolerance.
        if not clamped:
            theta = norm / norm_old
            remaining = norm * theta / (1.0 - theta) if theta < 1.0 else norm
            if norm <= _NEWTON_TOL or remaining <= _NEWTON_TOL:
                converged = True
                break
        norm_old = norm if not clamped else math.inf
    if not converged:
        return False, x, w, math.inf
    for i in range(3):
        zx[i] = h * (aa[i, 0] * wst[0] + aa[i, 1] * wst[1] + aa[i, 2] * wst[2])
        zw[i] = wst[i] - w
    x_new = x + zx[2]
    w_new = wst[2]
    # Embedded error estimate: (MU_REAL/h I − J)^-1 (f(y_n) + Z^T E / h).
    f_x = w
    j_wx = -stiff / mass
    j_ww = (-gamma * normal * dmu0 - damp) / mass
    r_x = f_x + (ee[0] * zx[0] + ee[1] * zx[1] + ee[2] * zx[2]) / h
    r_w = f_w + (ee[0] * zw[0] + ee[1] * zw[1] + ee[2] * zw[2]) / h
    diag = _MU_REAL / h
    # [[diag, -1], [-j_wx, diag - j_ww]] e = r
    det = diag * (diag - j_ww) - j_wx
    e_x = ((diag - j_ww) * r_x + r_w) / det
    e_w = (diag * r_w + j_wx * r_x) / det
    if j_ww > 0.0:
        # Negative effective damping (zone 2, e.g. the onset of a slip): the filter above is made
        # for decaying stiff modes and would shrink the estimate of a fast-growing one. Take the
        # unfiltered estimate h/MU_REAL (f + Z^T E / h) when it is larger.
        e_x = max(abs(e_x), abs(r_x / diag))
        e_w = max(abs(e_w), abs(r_w / diag))
    sx = atol_x + rtol * max(abs(x), abs(x_new))
    sw = atol_w + rtol * max(abs(w), abs(w_new))
    err = math.sqrt(0.5 * ((e_x / sx) ** 2 + (e_w / sw) ** 2))
    if not math.isfinite(err):
        return False, x, w, math.inf
    return err <= 1.0, x_new, w_new, err


def _advance_py(
    state: np.ndarray,
    band: np.ndarray,
    dt: float,
    rig: np.ndarray,
    law: Any,
    fp: np.ndarray,
    rtol: float,
    atol_x: float,
    atol_w: float,
    aa: np.ndarray,
    a2: np.ndarray,
    cc: np.ndarray,
    ee: np.ndarray,
    out_x: np.ndarray,
    out_w: np.ndarray,
) -> int:
    """Advance over len(band) samples; state = [t, x, ẋ, v_band, h, substeps] is updated in place.

    On failure (STEP_TOO_SMALL) the state is that of the last completed sample, so a caller can
    carry on from the sample grid.
    """
    t, x, w, vb_prev, h = state[0], state[1], state[2], state[3], state[4]
    substeps = state[5]
    work = np.empty((8, 3))
    jac = np.empty((3, 3))
    for k in range(band.size):
        t0 = t
        x0, w0 = x, w  # the last completed sample, restored if this one fails
        t_end = t0 + dt
        vb_next = band[k]
        while t < t_end:
            remaining = t_end - t
            last = h >= remaining * (1.0 - 1e-12)
            step = remaining if last else h
            accepted, x_new, w_new, err = _radau_step(
                law, x, w, t, step, t0, dt, vb_prev, vb_next, rig, fp, rtol, atol_x, atol_w, aa, a2, cc, ee,
                work, jac,
            )
            if math.isfinite(err):
                factor = 0.9 * err ** (-0.25) if err > 0.0 else _MAX_FACTOR
                factor = min(_MAX_FACTOR, max(_MIN_FACTOR, factor))
            else:
                factor = 0.5
            if accepted:
                x, w = x_new, w_new
                t = t_end if last else t + step
                substeps += 1.0
                h_new = step * factor
                if last and step < h and factor >= 1.0:
                    h_new = max(h, h_new)  # a step cut short to land on the sample says little
                h = min(h_new, dt)
            else:
                h = step * min(factor, 0.9)
                if h < 1e-15 * max(1.0, abs(t)):
                    # leave the state on the sample grid: the last completed sample
                    state[0], state[1], state[2], state[3], state[4] = t0, x0, w0, vb_prev, dt * 0.1
                    state[5] = substeps
                    return STEP_TOO_SMALL
        t = t_end
        vb_prev = vb_next
        out_x[k] = x
        out_w[k] = w
    state[0], state[1], state[2], state[3], state[4] = t, x, w, vb_prev, h
    state[5] = substeps
    return OK


@functools.cache
def _stepper() -> Any:
    """The compiled stepper (compiled, or loaded from numba's cache, on first use)."""
    f8 = types.float64
    array = types.Array(f8, 1, "C")
    matrix = types.Array(f8, 2, "C")
    signature = types.int64(
        array, array, f8, array, LAW_KERNEL, LAW_PARAMETERS, f8, f8, f8,
        matrix, matrix, array, array, array, array,
    )
    return njit(signature, cache=True)(_advance_py)


def advance(
    state: np.ndarray,
    band: np.ndarray,
    dt: float,
    rig: np.ndarray,
    kernel: Any,
    fp: np.ndarray,
    rtol: float,
    atol_x: float,
    atol_w: float,
    out_x: np.ndarray,
    out_w: np.ndarray,
) -> int:
    """Advance over len(band) samples with the law `kernel` (p = fp); status OK or STEP_TOO_SMALL.

    state = [t, x, ẋ, v_band, h, substeps] is updated in place; rig = [m, c, k, γ, N].
    """
    return int(
        _stepper()(state, band, dt, rig, kernel, fp, rtol, atol_x, atol_w, _A, _A2, _C, _E, out_x, out_w)
    )
