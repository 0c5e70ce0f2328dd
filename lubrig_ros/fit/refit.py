"""Standard errors from refits: the estimator's spread over fresh noise around the fitted model.

The linearized errors of fit/solve.py (`covariance`) describe the estimator where the residuals
are close to linear in the parameters over a few standard errors. On a stick-slip record they
are not everywhere: a slip's time moves with the parameters, and the samples of a 50 ms slip
change by far more than the noise when it moves by one sample (docs/fitting.md measures ζ's
spread over noise seeds at about 1.5 × its linearized error). A parametric bootstrap (Efron and
Tibshirani, *An Introduction to the Bootstrap*, 1993, ch. 6) measures the spread instead:

* each refit's record is the fitted model at every sample (`FitResult.model`) plus independent
  Gaussian noise at each measured stream's residual RMS (the data's own noise model: a record
  whose noise is not white and Gaussian is not described by either error);
* it is fitted by the same method (`fit`: the same free parameters, segments, and on a stick-slip
  record the same start scan), started from the fitted values;
* the refit error of a parameter is the standard deviation (ddof 1) of its refit estimates, in its
  own unit; `shift` is their mean minus the fitted value (a bias of the estimator shows there).

The noise is drawn from numpy's PCG64 seeded with `seed`: the same record, fit and seed give the
same refit errors. With `count` refits the error's own relative uncertainty is about
1 / sqrt(2 (count − 1)) (16 refits: 18 %).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..core.errors import InputError
from .data import MeasuredData
from .solve import FitResult, fit

#: Fewest refits whose spread is reported (two give a standard deviation with 100 % uncertainty).
MIN_REFITS = 4


@dataclass(frozen=True)
class Refits:
    """The refits of one fit: count, seed, errors and mean shifts (in the parameters' units)."""

    count: int
    seed: int
    errors: np.ndarray
    shift: np.ndarray
    failed: int
    wall_time: float

    def to_dict(self, names: list[str]) -> dict[str, Any]:
        """JSON-ready: per parameter the refit standard error and the mean shift."""
        return {
            "count": self.count,
            "seed": self.seed,
            "failed": self.failed,
            "standard_error": {n: float(e) for n, e in zip(names, self.errors, strict=True)},
            "mean_shift": {n: float(s) for n, s in zip(names, self.shift, strict=True)},
            "noise": "Gaussian at each stream's residual RMS, around the fitted model",
            "wall_time_s": self.wall_time,
        }


def refit_errors(data: MeasuredData, result: FitResult, count: int, seed: int = 0, **options: Any) -> Refits:
    """`count` refits of `result`'s parameters to its model plus fresh noise (module docstring).

    `options` go to each `fit` (segment_seconds, workers, max_evaluations): the same as the fit's.
    A refit that does not converge is counted in `failed` and left out of the spread.
    """
    if count < MIN_REFITS:
        raise InputError(f"--refits {count} is too few: expected 0 (none) or at least {MIN_REFITS}")
    assert result.config is not None
    started = time.perf_counter()
    rng = np.random.default_rng(seed)
    estimates, failed = [], 0
    for _ in range(count):
        streams = {
            name: result.model[name]
            + rng.normal(0.0, result.residual_rms[name], size=result.model[name].size)
            for name in data.streams
        }
        record = replace(data, **streams, source=f"{data.source} (refit)")
        refit = fit(record, result.config, result.names, **options)
        if refit.success:
            estimates.append(refit.values)
        else:
            failed += 1
    values = np.array(estimates)
    if len(estimates) < 2:
        errors = np.full(len(result.names), np.inf)
        shift = np.full(len(result.names), np.nan)
    else:
        errors = values.std(axis=0, ddof=1)
        shift = values.mean(axis=0) - result.values
    return Refits(count, seed, errors, shift, failed, time.perf_counter() - started)
