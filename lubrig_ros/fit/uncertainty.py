"""A fit's standard errors and what its data cannot determine, from the Jacobian at the solution.

* covariance: that of the estimator computed, the sandwich s² A⁺ J_dᵀJ_d A⁺ with A = JᵀJ at the
  fit's continuity weight (DEFECT_WEIGHT: the segments are joined by a penalty, not exactly, so
  the states are some extra freedom) and J_d the data rows (only they carry noise); s² is the data
  residuals' mean square per degree of freedom (the noise estimate corrected by what the model
  leaves).
* identifiability: a parameter is named as not determined by the data when its relative standard
  error exceeds MAX_RELATIVE_ERROR, when its correlation with another free parameter exceeds
  MAX_CORRELATION in magnitude (both from the covariance above), when the segments' start states
  absorb it (its information with them eliminated below MIN_RETAINED of its information from the
  data rows alone), or when it takes part in a near-null direction of the parameters' information
  with the continuity rows weighted COVARIANCE_WEIGHT, the penalty's limit (eigenvalue of the
  correlation-scaled information below MIN_EIGENVALUE: a combination the data cannot see, such as
  A·G and A·η_ref, which are all μ depends on).

Both come from singular value decompositions of the Jacobian, never from JᵀJ: the parameters'
information with the states eliminated is the small difference of large terms when the continuity
rows (weighted 1000) carry most of a parameter's column, and formed from JᵀJ (its Schur complement)
that difference was lost to rounding (measured on μ alone of study case 4: f0's information 1290
(in ln f0) by projection, −4973, +32050 and −3588 by the Schur complement at three stops of the same
fit, so the verdict on f0 flipped with where the fit stopped). The Jacobian's columns are
projected off the span of the state columns instead, which loses nothing to cancellation.
"""

from __future__ import annotations

import math

import numpy as np

from .parameters import FreeParameter
from .shooting import ShootingProblem

#: Weight of the continuity rows in the information asked about identifiability (the penalty's limit).
COVARIANCE_WEIGHT = 1e3
#: A correlation above this (in magnitude) names both parameters.
MAX_CORRELATION = 0.99
#: A relative standard error above this names the parameter: ±2 standard errors span the value
#: itself (for ζ, the data cannot tell it from zero).
MAX_RELATIVE_ERROR = 0.5
#: Eigenvalue of the correlation-scaled information below which a direction counts as unseen.
MIN_EIGENVALUE = 1e-8
#: A parameter's information with the states eliminated (continuity rows included, so the ratio
#: can exceed 1), over its information from the data rows alone, below which the segments' start
#: states absorb it. Measured on case 4's 3 s records: 0.14–5.6 for ζ, f0 and G; what forward
#: differences leave of an absorbed column, at most 3.1e-8 (the projected difference between
#: Jacobians with steps 1e-6 and 1e-7, over the same yardstick), hence 1e-6.
MIN_RETAINED = 1e-6


def _svd(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Thin SVD (U, s, Vᵀ) truncated to the numerical rank (numpy's matrix_rank tolerance)."""
    u, s, vt = np.linalg.svd(matrix, full_matrices=False)
    keep = s > s.max(initial=0.0) * max(matrix.shape) * np.finfo(float).eps
    return u[:, keep], s[keep], vt[keep]


def covariance(problem: ShootingProblem, jac: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """Covariance of z as computed (the fit's weights): s² A⁺ J_dᵀJ_d A⁺, A = JᵀJ.

    With J = U S Vᵀ and U_d the data rows of U this is s² V S⁻¹ U_dᵀU_d S⁻¹ Vᵀ; s² is the data
    residuals' mean square per degree of freedom.
    """
    rows = problem.data_rows()
    u, s, vt = _svd(np.asarray(jac))
    data = u[:rows] / s
    dof = max(problem.fitted_rows() - jac.shape[1], 1)
    s2 = float(residual[:rows] @ residual[:rows]) / dof
    return np.asarray(s2 * (vt.T @ (data.T @ data) @ vt))


def _identifiability_rows(problem: ShootingProblem, jac: np.ndarray) -> np.ndarray:
    """The Jacobian with the continuity rows weighted COVARIANCE_WEIGHT instead of the fit's weight."""
    weighted = np.array(jac, dtype=float)
    weighted[problem.data_rows() :] *= COVARIANCE_WEIGHT / problem.defect_weight
    return weighted


def parameter_information(problem: ShootingProblem, jac: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(the parameters' information with the states eliminated, in θ; its ratio to their own).

    Their own: each parameter's information from the data rows alone (MIN_RETAINED). The
    continuity rows are weighted COVARIANCE_WEIGHT. The parameter columns are projected off the
    span of the state columns (an orthonormal basis from their SVD): what remains is what the data
    say of the parameters whatever the states.
    """
    count = len(problem.parameters)
    weighted = _identifiability_rows(problem, jac)
    columns = weighted[:, :count]
    states = weighted[:, count:]
    if states.shape[1]:
        basis = _svd(states)[0]
        columns = columns - basis @ (basis.T @ columns)
    info = np.asarray(columns.T @ columns)
    data = weighted[: problem.data_rows(), :count]
    bare = np.einsum("ij,ij->j", data, data)
    retained = np.divide(np.diag(info), bare, out=np.zeros(count), where=bare > 0.0)
    return info, retained


def undetermined(
    parameters: list[FreeParameter],
    values: np.ndarray,
    errors: np.ndarray,
    correlation: np.ndarray,
    info: np.ndarray,
    retained: np.ndarray,
) -> dict[str, str]:
    """Each parameter the data cannot determine, with why (see the module's docstring)."""
    names = [p.name for p in parameters]
    found: dict[str, list[str]] = {}
    for j, p in enumerate(parameters):
        reference = abs(values[j]) or (p.spec.high - p.spec.low)
        if not math.isfinite(errors[j]) or errors[j] > MAX_RELATIVE_ERROR * reference:
            found.setdefault(p.name, []).append(
                f"standard error {errors[j]:.3g}{p.spec.unit_text} exceeds "
                f"{MAX_RELATIVE_ERROR:.0%} of the value (±2 standard errors span the value itself)"
            )
        for k in range(len(parameters)):
            if k != j and abs(correlation[j, k]) > MAX_CORRELATION:
                found.setdefault(p.name, []).append(f"correlation {correlation[j, k]:+.4f} with {names[k]}")
        if retained[j] < MIN_RETAINED:
            found.setdefault(p.name, []).append(
                f"no information left once the segments' start states are fitted (they absorb "
                f"it: {retained[j]:.1e} of its information from the data alone is left)"
            )
    diagonal = np.sqrt(np.clip(np.diag(info), 0.0, None))
    scale = np.where(diagonal > 0.0, diagonal, 1.0)
    eigenvalues, vectors = np.linalg.eigh(info / np.outer(scale, scale))
    top = max(float(eigenvalues.max()), 1e-300)
    for value, vector in zip(eigenvalues, vectors.T, strict=True):
        if value < MIN_EIGENVALUE * top:
            weight = np.abs(vector)
            members = [names[j] for j in range(len(names)) if weight[j] >= 0.25 * weight.max()]
            combination = " + ".join(f"{vector[names.index(m)]:+.2f}·{m}" for m in members)
            for member in members:
                found.setdefault(member, []).append(
                    f"near-singular Jacobian: the data do not see the combination {combination} (in θ)"
                )
    return {name: "; ".join(dict.fromkeys(reasons)) for name, reasons in found.items()}
