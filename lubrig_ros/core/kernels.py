"""Compiled (numba) kernels: the Radau IIA rig stepper and the one adapter to friction-law kernels.

Friction laws reach the compiled code through one adapter (this module):

* a law's scalar kernel ``(v, p) -> (μ, dμ/dv)`` is decorated with core.friction_laws.law_kernel
  (compiled for :data:`LAW_SIGNATURE` when first used: v float64, p a contiguous float64 array);
* :func:`advance` (the stepper) and :func:`evaluate_law` (vectorized μ, dμ/dv) take the kernel as
  an argument and run a copy of the stepper specialized for it (:func:`specialize`): the same
  source, with the global ``_LAW`` bound to the law's function compiled with
  ``inline="always"``, so numba inlines the law into the step (no call, and no reference count of
  p, per evaluation: 4 % of a sliding run). Compiled once per law and cached on disk.

Staleness: numba keys a cached function on its own source file only, and a specialized stepper
embeds its law's code. Its cache is therefore located by :class:`_LawLocator`, whose source stamp
is the content hash of this file AND of the law kernel's file: editing either recompiles that
law's stepper, and nothing else (test/test_friction_laws.py edits a law module between fresh
processes). Helpers a kernel calls must live in the kernel's own file (they are inlined too and
only that file is in the stamp), as core/junction.py does.

Why this design (numba 0.68.1, measured; figures in docs/extending.md). (1) Passing the dispatcher
as an argument (type ``Dispatcher``) inlines the law, but that signature never hits numba's cache
(the type is the dispatcher object): every process recompiled the stepper and each run added a
cache file. (2) A first-class function type (``FunctionType``, the law called through its address)
caches well and can never be stale, but the indirect, non-inlined calls cost 6–15 % CPU time on
the study cases, and each call from Python resolves the dispatcher's address (≈ 290 µs instead of
30 µs per single-sample advance, the plant node's pattern). (3) A closure per law would be cached
under the factory's file only (numba's keying; not built): stale after an edit of the law's file.
(4) Chosen: a specialized copy per law, inlined, with a cache keyed on both files: the same speed
and cache behaviour as before laws were pluggable, and the default law's runs stay bit-identical.

Integrator: 3-stage Radau IIA (order 5, L-stable, stiffly accurate) with the embedded error
estimate of Hairer & Wanner (as in scipy's Radau); full Newton on the three stage velocities
(displacements are linear in them) with a trust region in log|v_rel|. This file holds one step;
core/stepper.py the sample loop around it (step size control, steps spanning samples).
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import math
import os
import re
import types as pytypes
from typing import Any

import numpy as np
from numba import njit, types
from numba.core import caching as _caching

from . import stepper as stepper_module

#: Type of a law's p: a contiguous, writable float64 array.
LAW_PARAMETERS = types.Array(types.float64, 1, "C")
#: Signature every law kernel is compiled for: (v, p) -> (μ, dμ/dv).
LAW_SIGNATURE = types.UniTuple(types.float64, 2)(types.float64, LAW_PARAMETERS)


# Placeholder: each law's specialized copy of the functions below binds it to the law's kernel
# (see specialize).
_LAW: Any = None


def _evaluate_law_py(v: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    mu = np.empty(v.size)
    dmu = np.empty(v.size)
    for i in range(v.size):
        mu[i], dmu[i] = _LAW(v[i], p)
    return mu, dmu


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
#: The collocation polynomial's coefficients (core/stepper.py _P) as scalars, for the predictor.
(_P00, _P01, _P02), (_P10, _P11, _P12), (_P20, _P21, _P22) = stepper_module._P.tolist()
_MU_REAL = 3.0 + 3.0 ** (2.0 / 3.0) - 3.0 ** (1.0 / 3.0)
#: Newton iterations before a stage solve counts as failed (the step is then halved). Converged
#: solves took at most 14 (the trust region below allows a factor 4 in |v_rel| per iteration) on
#: the benchmark's cases at rtol 1e-9 … 1e-12, none from 15 to 40; a failed one cost 40, a third of
#: all iterations on physical case 1 at rtol 1e-9.
_NEWTON_MAXITER = 20
_REL_FACTOR = 4.0
_NEWTON_TOL = 0.03
#: h·|∂ẍ/∂ẋ| above which a step's mode counts as stiff (its error estimate may be refined)
_STIFF = 10.0

#: Layout of the rig array the stepper reads (float64 array of RIG_SIZE, SI units): the index of
#: each RigParameters attribute of RIG_LAYOUT (the integrator builds the array in this order).
RIG_MASS, RIG_DAMPING, RIG_STIFFNESS, RIG_VELOCITY_FACTOR, RIG_NORMAL_FORCE = 0, 1, 2, 3, 4
RIG_LAYOUT = ("mass", "damping", "stiffness", "velocity_factor", "normal_force")
RIG_SIZE = len(RIG_LAYOUT)


@njit(cache=True, inline="always")
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


# One Radau IIA step with its Newton iteration, written as numba compiles it (one function, no
# calls in the inner loop): splitting it would add calls to the hottest path of every run.
def _radau_step_py(  # noqa: C901
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
    tol: np.ndarray,
    aa: np.ndarray,
    a2: np.ndarray,
    cc: np.ndarray,
    ee: np.ndarray,
    work: np.ndarray,
    jac: np.ndarray,
    refine: bool,
    newton: tuple[float, float],
    last_step: tuple[float, float, float, float],
) -> tuple[bool, float, float, float, float]:
    """One Radau IIA step of size h from t; returns (accepted, x_new, w_new, error_norm, rate).

    tol: (rtol, atol_x, atol_w). work (8x3) and jac (3x3) are scratch space, allocated once per
    advance() call. refine: the attempt follows a rejected one from a corner of the band (its
    error estimate may then be refined, see below). newton: (min_newton, rate): 1, or 2 to never
    accept the first Newton iterate (the result is then a smooth function of the parameters, see
    below), and the last stage solve's contraction estimate (state NEWTON_RATE), returned
    updated. last_step: the last accepted step's length (0: none) and ẋ stage increments, whose
    collocation polynomial predicts this step's stages.
    """
    rtol, atol_x, atol_w = tol[0], tol[1], tol[2]
    min_newton, rate = newton
    last_h, last0, last1, last2 = last_step
    mass, damp, stiff = rig[RIG_MASS], rig[RIG_DAMPING], rig[RIG_STIFFNESS]
    gamma, normal = rig[RIG_VELOCITY_FACTOR], rig[RIG_NORMAL_FORCE]
    slope_vb = (vb1 - vb0) / dt
    vb, wst, g, gw, res, delta, zx, zw = (
        work[0],
        work[1],
        work[2],
        work[3],
        work[4],
        work[5],
        work[6],
        work[7],
    )
    for i in range(3):
        vb[i] = vb0 + slope_vb * (t + cc[i] * h - t0)
    # Newton on the stage velocities W (displacements X = x + h A W). Predictor: a sliding mass
    # follows the last step's collocation polynomial extrapolated (Hairer & Wanner IV.8, as
    # radau5), or, without a last step, its explicit-Euler velocity; a stuck one (|v_rel| ≪
    # v_band) keeps its relative velocity, i.e. moves with the band. Starting a stuck mass at
    # constant ẋ would put the stages on the unstable zone-2 branch, which has the same μ and is a
    # spurious root of the stage equations.
    vb_now = vb0 + slope_vb * (t - t0)
    rel_now = vb_now - gamma * w
    stuck = abs(rel_now) < 1e-3 * abs(vb_now)
    mu0, dmu0 = _LAW(rel_now, fp)
    if not math.isfinite(dmu0):
        dmu0 = 1e300
    f_w = (normal * mu0 - damp * w - stiff * x) / mass
    for i in range(3):
        if stuck:
            wst[i] = w + (vb[i] - vb_now) / gamma
        elif last_h > 0.0:  # y(t + c_i h) on the last step's polynomial: θ = 1 + c_i h / last_h
            th = 1.0 + cc[i] * h / last_h
            th2 = th * th
            th3 = th2 * th
            wst[i] = (
                w
                - last2
                + last0 * (_P00 * th + _P01 * th2 + _P02 * th3)
                + last1 * (_P10 * th + _P11 * th2 + _P12 * th3)
                + last2 * (_P20 * th + _P21 * th2 + _P22 * th3)
            )
        else:
            wst[i] = w + cc[i] * h * f_w
    converged = False
    norm_old = -1.0  # no unclamped increment on this step yet: no contraction rate
    # the last solve's rate, raised to 3/4 (radau5 raises it to 0.8: a little above the last rate;
    # two square roots instead of a power)
    faccon = math.sqrt(max(rate, 2.2e-16))
    faccon *= math.sqrt(faccon)
    for iteration in range(_NEWTON_MAXITER):
        for j in range(3):
            xj = x + h * (aa[j, 0] * wst[0] + aa[j, 1] * wst[1] + aa[j, 2] * wst[2])
            mu, dmu = _LAW(vb[j] - gamma * wst[j], fp)
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
                return False, x, w, math.inf, faccon
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
        # Stop when the remaining error, estimated from the contraction rate θ = ‖Δ_k‖ / ‖Δ_k−1‖ of
        # two successive unclamped increments (Hairer & Wanner IV.8), is a small fraction of the
        # tolerance. On the first iterate, θ is the last solve's (as radau5 does): a sliding mass,
        # predicted from the last step, then takes one iteration instead of two. Not a stuck mass:
        # its band-following guess is not what the last rate was measured from (at a corner of
        # case 8, a first increment of 3 error scales passed with a rate of 4e-4, its solve then
        # not contracting at all). Never the first after a clamped one, and with min_newton 2
        # never the first: whether one iteration suffices changes by jumps with the parameters,
        # and the fit's forward differences (fit/shooting.py) would read those jumps, below the
        # tolerance, as information.
        if clamped:
            norm_old = -1.0
            continue
        if norm == 0.0:
            converged = True
            break
        if iteration == 0 and not stuck and min_newton < 2.0 and faccon * norm <= _NEWTON_TOL:
            converged = True
            break
        if norm_old > 0.0:
            theta = norm / norm_old
            faccon = theta / (1.0 - theta) if theta < 0.99 else 99.0
            if theta < 1.0 and norm * theta / (1.0 - theta) <= _NEWTON_TOL:
                converged = True
                break
            if theta >= 1.0 and norm <= _NEWTON_TOL:
                # two increments below the tolerance that no longer contract: rounding noise
                converged = True
                break
        norm_old = norm
    if not converged:
        return False, x, w, math.inf, faccon
    for i in range(3):
        zx[i] = h * (aa[i, 0] * wst[0] + aa[i, 1] * wst[1] + aa[i, 2] * wst[2])
        zw[i] = wst[i] - w
    x_new = x + zx[2]
    w_new = wst[2]
    # Embedded error estimate: (MU_REAL/h I − J)^-1 (f(y_n) + Z^T E / h), J at the step's start
    # (Hairer & Wanner) unless its mode is stiff there: then J's ∂ẍ/∂ẋ is the least damped of the
    # start and the stages (theirs from the last Newton pass). A stuck mass nearing the fold (its
    # friction peak) loses its stiffness within the step, and the start's J filtered away a real
    # error: 436 × the tolerance in ẋ against an estimate of 0.81 (case 1), which moved the slip by
    # tens of µs. Only there: elsewhere the estimate stays a smooth function of the parameters,
    # which the fit's forward differences need (test_fit's μ-only record of case 4).
    j_wx = -stiff / mass
    j_ww = (-gamma * normal * dmu0 - damp) / mass
    if j_ww * h < -_STIFF:
        j_ww = max(j_ww, gw[0], gw[1], gw[2])
    ze_x = (ee[0] * zx[0] + ee[1] * zx[1] + ee[2] * zx[2]) / h
    ze_w = (ee[0] * zw[0] + ee[1] * zw[1] + ee[2] * zw[2]) / h
    diag = _MU_REAL / h
    det = diag * (diag - j_ww) - j_wx  # of [[diag, -1], [-j_wx, diag - j_ww]]
    sx = atol_x + rtol * max(abs(x), abs(x_new))
    sw = atol_w + rtol * max(abs(w), abs(w_new))
    # the mode decays fast on the step's scale at its start and at every stage (a stuck mass)
    stiff_step = j_ww * h < -_STIFF
    f_x = w
    err = math.inf
    e_x = e_w = 0.0
    for refinement in range(2):
        if refinement == 1:
            if not (refine and err > 1.0 and stiff_step):
                break
            # Hairer & Wanner IV.8 (8.20), as radau5 and scipy's Radau do after a rejection: in
            # a stiff mode the first estimate is the mode's own fast transient, the same for
            # every h ≫ its time constant. A stuck mass at a corner of the band has one (its
            # velocity turns to the band's new slope in about a nanosecond): 19 × the tolerance
            # from h = 1 ms down to 2 ns, twenty rejections in a row. Once more through the
            # filter, from f at y + e, the transient is damped. Only there (a corner, a stuck
            # mass): near a slip onset the refined estimate let steps through that moved the
            # onset (docs/integrator.md, "A stuck mass at a corner of the band").
            mu_e, _ = _LAW(vb_now - gamma * (w + e_w), fp)
            f_x = w + e_w
            f_w = (normal * mu_e - damp * (w + e_w) - stiff * (x + e_x)) / mass
        r_x = f_x + ze_x
        r_w = f_w + ze_w
        e_x = ((diag - j_ww) * r_x + r_w) / det
        e_w = (diag * r_w + j_wx * r_x) / det
        size_x, size_w = abs(e_x), abs(e_w)
        if j_ww > 0.0:
            # Negative effective damping (zone 2, e.g. the onset of a slip): the filter is made
            # for decaying stiff modes and would shrink the estimate of a fast-growing one. Take
            # the unfiltered estimate h/MU_REAL (f + Z^T E / h) when it is larger.
            size_x = max(size_x, abs(r_x / diag))
            size_w = max(size_w, abs(r_w / diag))
        err = math.sqrt(0.5 * ((size_x / sx) ** 2 + (size_w / sw) ** 2))
    if not math.isfinite(err):
        return False, x, w, math.inf, faccon
    return err <= 1.0, x_new, w_new, err, faccon


class _LawLocator(_caching._CacheLocator):
    """Cache locator of a law's specialized kernels: the normal place, keyed on both source files.

    numba keys a cached function on its own file only; a law's stepper is compiled from this file
    with the law's kernel inlined, so its stamp is the content hash of this file AND of the file
    holding the law's kernel. Other functions are not this locator's (from_function returns None).
    """

    def __init__(self, base: Any, files: tuple[str, ...]) -> None:
        self._base = base
        self._files = files
        self._py_file = base._py_file
        self._lineno = base._lineno

    def ensure_cache_path(self) -> None:
        self._base.ensure_cache_path()

    def get_cache_path(self) -> str:
        return str(self._base.get_cache_path())

    def get_disambiguator(self) -> str:
        return str(self._base.get_disambiguator())

    def get_source_stamp(self) -> Any:
        stamps = [self._base.get_source_stamp()]
        for path in self._files:
            with open(path, "rb") as handle:
                stamps.append(hashlib.sha256(handle.read()).digest())
        return tuple(stamps)

    @classmethod
    def from_function(cls, py_func: Any, py_file: str) -> Any:
        files = getattr(py_func, "_law_source_files", None)
        if files is None:
            return None
        for base_class in _BASE_LOCATORS:
            base = base_class.from_function(py_func, py_file)
            if base is not None:
                return cls(base, files)
        return None


_BASE_LOCATORS: list[Any] = [c for c in _caching.CacheImpl._locator_classes if c is not _LawLocator]
if _LawLocator not in _caching.CacheImpl._locator_classes:
    _caching.CacheImpl._locator_classes.insert(0, _LawLocator)


def _clone(function: Any, tag: str, bound: dict[str, Any], files: tuple[str, ...]) -> Any:
    """A copy of a module-level function with some globals bound, named for its law."""
    namespace = dict(function.__globals__)
    namespace.update(bound)
    copy = pytypes.FunctionType(
        function.__code__, namespace, function.__name__, function.__defaults__, function.__closure__
    )
    copy.__qualname__ = f"{function.__qualname__}__{tag}"
    copy.__module__ = function.__module__
    copy._law_source_files = files  # type: ignore[attr-defined]
    return copy


@functools.cache
def specialize(kernel: Any) -> tuple[Any, Any]:
    """(stepper, evaluator) compiled for one law kernel, inlined, cached by both files.

    stepper(state, band, dt, rig, fp, rtol, atol_x, atol_w, A, A2, C, E, max_span, min_newton, out_x,
    out_w) -> status (core.stepper's sample loop around this file's Radau step); evaluator(v, p) -> (μ,
    dμ/dv) for contiguous float64 arrays. The integrator binds both once (a per-sample call then
    costs what it did with one built-in law). The loop's cache is keyed on the law's file and this
    one too: it inlines the step compiled from here.
    """
    py_func = kernel.py_func
    kernel = getattr(kernel, "dispatcher", kernel)  # a LawKernel compiles here, when first used
    files = (os.path.abspath(inspect.getfile(py_func)),)
    tag = re.sub(r"\W", "_", f"{py_func.__module__}.{py_func.__qualname__}")
    inlined = njit(inline="always")(py_func)  # numba-IR inlined into the step, compiled with it
    step = njit(cache=True)(_clone(_radau_step_py, tag, {"_LAW": inlined}, files))
    loop_files = (*files, os.path.abspath(__file__))
    land = njit(cache=True)(_clone(stepper_module._land_py, tag, {"_STEP": step}, loop_files))
    stepper = njit(cache=True)(_clone(stepper_module._advance_py, tag, {"_LAND": land}, loop_files))
    evaluator = njit(cache=True)(_clone(_evaluate_law_py, tag, {"_LAW": kernel}, files))
    return stepper, evaluator


def evaluate_law(kernel: Any, velocity: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """μ and dμ/dv of a law kernel at every velocity of a 1-D float64 array (p: law.pack(params))."""
    v = np.ascontiguousarray(velocity, dtype=np.float64).reshape(-1)
    evaluator = specialize(kernel)[1]
    result: tuple[np.ndarray, np.ndarray] = evaluator(v, np.ascontiguousarray(p, dtype=np.float64))
    return result
