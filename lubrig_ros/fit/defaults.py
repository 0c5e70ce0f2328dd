"""Defaults of a fit that `lubrig fit` shows in its help (here, so the CLI needs no scipy to show them)."""

from __future__ import annotations

#: Default length of a shooting segment, s.
SEGMENT_SECONDS = 0.25
#: Residual evaluations per least-squares stage at most. On the stick-slip record of
#: test/test_fit_stickslip.py (noise seeds 1–40) 3 fits stopped here unconverged; with 150 they
#: converged to the same estimates (docs/fitting.md). Not raised: a fit that never converges (μ
#: alone on study case 4, ζ and f0 wandering in a direction the data do not see) then names f0 no
#: longer, since the near-singular test's verdict moves as ζ wanders (docs/fitting.md, open).
MAX_EVALUATIONS = 60
