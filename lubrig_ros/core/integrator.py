"""Stiff integration of the rig  m ẍ + c ẋ + k x = N μ(v_band − γ ẋ)  sample by sample.

Method: 3-stage Radau IIA (order 5, L-stable, stiffly accurate) with adaptive substeps and the
embedded error estimate of Hairer & Wanner (as in scipy's Radau). The stage equations are solved
by full Newton on the three stage velocities only (displacements are linear in them), with a
safeguard that stops an iterate from jumping across v_rel = 0 in one go: there μ ∝ |v|^0.38 has an
unbounded slope and plain Newton oscillates. This keeps the solver accurate through sticking
(v_rel ≈ 0), where the slope of μ reaches 1e11 s/m and explicit methods fail.

Band velocity is known at the output samples only (as for a node receiving messages) and is taken
as linear between consecutive samples. Substeps end exactly on every sample, so a run integrated
in one call and one advanced sample by sample give bit-identical results.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from .friction import mu_and_slope
from .params import RigParameters

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
    """Advance over len(band) samples; state = [t, x, ẋ, v_band, h, substeps] is updated in place."""
    t, x, w, vb_prev, h = state[0], state[1], state[2], state[3], state[4]
    substeps = state[5]
    work = np.empty((8, 3))
    jac = np.empty((3, 3))
    for k in range(band.size):
        t0 = t
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
                    state[0], state[1], state[2], state[3], state[4] = t, x, w, vb_prev, h
                    state[5] = substeps
                    return STEP_TOO_SMALL
        t = t_end
        vb_prev = vb_next
        out_x[k] = x
        out_w[k] = w
    state[0], state[1], state[2], state[3], state[4] = t, x, w, vb_prev, h
    state[5] = substeps
    return OK


class IntegrationError(RuntimeError):
    """The integrator could not meet its tolerance (step size collapsed)."""


@dataclass
class Trajectory:
    """Uniformly sampled rig response (SI units; relative velocity per the run's convention)."""

    time: np.ndarray  # s
    displacement: np.ndarray  # x, m
    velocity: np.ndarray  # ẋ, m/s
    friction_coefficient: np.ndarray  # μ(v_rel)
    band_velocity: np.ndarray  # m/s
    relative_velocity: np.ndarray  # v_band − γ ẋ, m/s

    COLUMNS = (
        ("time", "time_s"),
        ("displacement", "displacement_m"),
        ("velocity", "velocity_m_s"),
        ("friction_coefficient", "friction_coefficient"),
        ("band_velocity", "band_velocity_m_s"),
        ("relative_velocity", "relative_velocity_m_s"),
    )

    def __len__(self) -> int:
        return int(self.time.size)

    def as_columns(self) -> dict[str, np.ndarray]:
        """Arrays keyed by their CSV column names (with units)."""
        return {column: getattr(self, name) for name, column in self.COLUMNS}


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
    _state: np.ndarray = field(init=False, repr=False)
    _rig_array: np.ndarray = field(init=False, repr=False)
    _fp: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        for name in ("initial_band_velocity", "sample_rate", "rtol", "initial_perturbation"):
            value = float(getattr(self, name))
            if not math.isfinite(value):
                raise ValueError(f"{name}={value!r} must be finite")
            setattr(self, name, value)
        if self.sample_rate <= 0.0:
            raise ValueError(f"sample_rate={self.sample_rate!r} must be > 0 Hz")
        if not 1e-13 <= self.rtol <= 1e-2:
            raise ValueError(f"rtol={self.rtol!r} is outside the valid range [1e-13, 1e-2]")
        self._rig_array = np.array(
            [self.rig.mass, self.rig.damping, self.rig.stiffness, self.rig.velocity_factor]
        )
        self._fp = np.asarray(self.rig.friction.as_array(), dtype=np.float64)
        self.reset()

    @property
    def dt(self) -> float:
        """Sample period in s."""
        return 1.0 / self.sample_rate

    @property
    def equilibrium_displacement(self) -> float:
        """x0 for the initial band velocity, m."""
        mu = mu_and_slope(self.initial_band_velocity, self._fp)[0]
        return mu * self.rig.friction.normal_force / self.rig.stiffness

    def reset(self, band_velocity: float | None = None) -> None:
        """Back to t = 0 and the initial condition (optionally for a new initial band velocity)."""
        if band_velocity is not None:
            self.initial_band_velocity = float(band_velocity)
        if self.initial_displacement is not None:
            x_start = float(self.initial_displacement)
        else:
            x_start = (1.0 + self.initial_perturbation) * self.equilibrium_displacement
        self._state = np.array(
            [0.0, x_start, self.initial_velocity, self.initial_band_velocity, 0.1 * self.dt, 0.0]
        )

    @property
    def _scales(self) -> tuple[float, float]:
        length = self.rtol * 1e-2 * self.rig.friction.normal_force / self.rig.stiffness
        return length, length * self.rig.angular_frequency

    @property
    def time(self) -> float:
        """Current rig time in s."""
        return float(self._state[0])

    @property
    def substeps(self) -> int:
        """Accepted Radau steps so far (work measure)."""
        return int(self._state[5])

    def current(self) -> Trajectory:
        """The present state as a one-sample trajectory."""
        t, x, w, vb = self._state[:4]
        return self._sampled(np.array([t]), np.array([x]), np.array([w]), np.array([vb]))

    def advance(self, band_velocities: np.typing.ArrayLike) -> Trajectory:
        """Integrate over the next len(band_velocities) samples; sample k holds v_band at t + (k+1)·dt."""
        band = np.ascontiguousarray(band_velocities, dtype=np.float64).reshape(-1)
        if not np.isfinite(band).all():
            bad = band[~np.isfinite(band)][0]
            raise ValueError(f"band velocity {bad!r} is not finite; expected finite m/s values")
        out_x = np.empty(band.size)
        out_w = np.empty(band.size)
        t_start = self._state[0]
        atol_x, atol_w = self._scales
        status = _advance(
            self._state, band, self.dt, self._rig_array, self._fp, self.rtol, atol_x, atol_w,
            _A, _A2, _C, _E, out_x, out_w,
        )
        if status != OK:
            raise IntegrationError(
                f"step size collapsed at t={self._state[0]:.6g} s (rtol={self.rtol}); "
                "the band velocity or rig parameters may be outside the model's range"
            )
        time = t_start + self.dt * np.arange(1, band.size + 1)
        return self._sampled(time, out_x, out_w, band)

    def _sampled(
        self, time: np.ndarray, x: np.ndarray, w: np.ndarray, band: np.ndarray
    ) -> Trajectory:
        from .friction import friction_coefficient

        relative = band - self.rig.velocity_factor * w
        return Trajectory(
            time=time,
            displacement=x,
            velocity=w,
            friction_coefficient=friction_coefficient(relative, self.rig.friction),
            band_velocity=band,
            relative_velocity=relative,
        )


def concatenate(parts: list[Trajectory]) -> Trajectory:
    """Join consecutive trajectories."""
    return Trajectory(
        **{name: np.concatenate([getattr(p, name) for p in parts]) for name, _ in Trajectory.COLUMNS}
    )
