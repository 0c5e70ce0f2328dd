"""Defaults of a fit that `lubrig fit` shows in its help (here, so the CLI needs no scipy to show them)."""

from __future__ import annotations

#: Default length of a shooting segment, s.
SEGMENT_SECONDS = 0.25
#: Residual evaluations per least-squares stage at most. All 40 fits of the stick-slip record of
#: test/test_fit_stickslip.py (noise seeds 1–40) converge within 9–52; of 12 μ-only fits of
#: study case 4, where ζ is not determined, 3 stop here, named as the converged ones (a fit that
#: stops says so; docs/fitting.md).
MAX_EVALUATIONS = 60
