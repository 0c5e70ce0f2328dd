"""Compiled (numba) kernels: the friction law μ(v), dμ/dv and the Radau IIA rig stepper.

They live in one module on purpose: numba's on-disk cache is keyed on the source file of each
compiled function only, so a kernel that calls a kernel of another file would keep running a stale
copy of it after that file changed. With both here, any change invalidates the whole cache.

Friction: the closed forms of the junction-kinetics law cancel catastrophically for small
u = v0/v and are replaced by series there; large u only underflows exp(−u) to zero.

Integrator: 3-stage Radau IIA (order 5, L-stable, stiffly accurate) with adaptive substeps and the
embedded error estimate of Hairer & Wanner (as in scipy's Radau); full Newton on the three stage
velocities (displacements are linear in them) with a trust region in log|v_rel|.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# Below this u = v0/v the closed forms cancel catastrophically: use series instead.
_SERIES_U = 0.1


@njit(cache=True)
def _bernoulli_ratio(u: float) -> float:
    """B(u) = u / (e^u − 1), B(0) = 1."""
    if u < _SERIES_U:
        u2 = u * u
        return 1.0 - 0.5 * u + u2 / 12.0 - u2 * u2 / 720.0 + u2 * u2 * u2 / 30240.0
    e = math.exp(-u)
    return u * e / (-math.expm1(-u))


@njit(cache=True)
def _stretch_ratio(u: float) -> float:
    """r(u) = [1 − (1+u)e^−u] / (1 − e^−u) = 1 − B(u); s = v τ0 r(u)."""
    if u < _SERIES_U:
        u2 = u * u
        return u / 2.0 - u2 / 12.0 + u2 * u2 / 720.0 - u2 * u2 * u2 / 30240.0
    return 1.0 - _bernoulli_ratio(u)


@njit(cache=True)
def _stretch_slope_ratio(u: float) -> float:
    """q(u) = ds/dv / τ0 = 1 − u² e^−u / (1 − e^−u)²."""
    if u < _SERIES_U:
        u2 = u * u
        u4 = u2 * u2
        return u2 / 12.0 - u4 / 240.0 + u4 * u2 / 6048.0 - u4 * u4 / 172800.0
    e = math.exp(-u)
    m = -math.expm1(-u)
    return 1.0 - u * u * e / (m * m)


@njit(cache=True)
def mu_and_slope(v: float, p: np.ndarray) -> tuple[float, float]:
    """μ(v) and dμ/dv for one velocity; p is FrictionParameters.as_array() as float64 array.

    μ is odd and dμ/dv even; at v = 0 the slope is +inf (μ ∝ |v|^(1+k2) there).
    """
    if v == 0.0:
        return 0.0, math.inf
    sign = 1.0
    if v < 0.0:
        sign = -1.0
        v = -v
    g_mod, thick, d_pen, l_star, tau0 = p[0], p[1], p[2], p[3], p[4]
    tau_ref, v_ref, k1, eta_ref, k2 = p[5], p[6], p[7], p[8], p[9]
    area, normal = p[10], p[11]
    u = (l_star / tau0) / v
    lifetime = tau0 * (-math.expm1(-u))  # <t_b>
    stretch = v * tau0 * _stretch_ratio(u)  # s(v)
    log_ratio = math.log(v / v_ref)  # one log, two exp: cheaper than two powers
    tau = tau_ref * math.exp(k1 * log_ratio)  # τ(v)
    phi = lifetime / (lifetime + tau)  # bonded fraction
    eta = eta_ref * math.exp(k2 * log_ratio)
    scale = area / normal
    elastic = g_mod / thick
    mu = scale * (elastic * phi * stretch + (1.0 - phi) * eta * v / d_pen)
    dphi = phi * (1.0 - phi) * (-_bernoulli_ratio(u) - k1) / v
    dstretch = tau0 * _stretch_slope_ratio(u)
    dmu = scale * (
        elastic * (dphi * stretch + phi * dstretch)
        + (1.0 + k2) * (1.0 - phi) * eta / d_pen
        - dphi * eta * v / d_pen
    )
    return sign * mu, dmu


@njit(cache=True)
def _mu_and_slope_array(v: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    mu = np.empty(v.size)
    dmu = np.empty(v.size)
    flat = v.ravel()
    for i in range(flat.size):
        mu[i], dmu[i] = mu_and_slope(flat[i], p)
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
    mass, damp, stiff, gamma = rig[0], rig[1], rig[2], rig[3]
    normal = fp[11]
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
    mu0, dmu0 = mu_and_slope(rel_now, fp)
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
            mu, dmu = mu_and_slope(vb[j] - gamma * wst[j], fp)
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


@njit(cache=True)
def _advance(
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
                x, w, t, step, t0, dt, vb_prev, vb_next, rig, fp, rtol, atol_x, atol_w, aa, a2, cc, ee,
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
