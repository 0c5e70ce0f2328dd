"""The default tolerance is converged: pointwise displacement within 1e-3 of its range of a tight
(rtol 1e-13) reference over 20 s, in every named convention (model doc §6; docs/benchmarks.md).

The fast test takes the hardest cases measured per convention (stick-slip slip timing: physical
cases 5 and 6; the hertz reading's case 8; paper case 7, the largest response); the slow one runs
all ten cases of every convention.
"""

from __future__ import annotations

import numpy as np
import pytest

from lubrig_ros.core.params import CONVENTIONS
from lubrig_ros.core.presets import default_config, load_case
from lubrig_ros.core.run import simulate

REFERENCE_RTOL = 1e-13
LIMIT = 1e-3


def pointwise_error(number: int, convention: str) -> float:
    config = load_case(number).with_overrides(convention=convention, duration=20.0)
    x = simulate(config).displacement
    reference = simulate(config.with_overrides(rtol=REFERENCE_RTOL)).displacement
    return float(np.max(np.abs(x - reference)) / np.ptp(reference))


def test_cases_inherit_the_default_tolerance() -> None:
    default = default_config().rtol
    assert all(load_case(n).rtol == default for n in range(1, 11))


@pytest.mark.parametrize(
    ("number", "convention"), [(6, "physical"), (5, "physical"), (8, "hertz"), (7, "paper")]
)
def test_default_rtol_converged_on_the_hardest_cases(number: int, convention: str) -> None:
    assert pointwise_error(number, convention) < LIMIT


@pytest.mark.slow
@pytest.mark.parametrize("convention", CONVENTIONS)
@pytest.mark.parametrize("number", range(1, 11))
def test_default_rtol_converged_everywhere(number: int, convention: str) -> None:
    assert pointwise_error(number, convention) < LIMIT
