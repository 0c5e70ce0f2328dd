"""Criteria that state their choice and how the verdict moves across its reasonable range
(C2a's tolerance on 'identical', C9b/C10b's reference level), and the μ statements judged on
the extremes between samples (core/dense.py) when the metrics carry them."""

from __future__ import annotations

from typing import Any

from lubrig_ros.core.params import RigParameters
from lubrig_ros.study import checks as check
from lubrig_ros.study.runs import GONE_FRACTIONS

RIG = RigParameters()


def _pp(ratio: float) -> dict[int, dict[str, Any]]:
    return {1: {"x_peak_to_peak": 1.0}, 2: {"x_peak_to_peak": ratio}}


def test_c2a_states_its_margin() -> None:
    agree, text = check.case2_same_amplitude(_pp(1.2496), RIG)
    assert agree and "1.2496" in text and "marginal" in text and "24.96%" in text
    agree, text = check.case2_same_amplitude(_pp(1.2588), RIG)
    assert not agree and "marginal" in text
    agree, text = check.case2_same_amplitude(_pp(1 / 1.1), RIG)
    assert agree and "holds over the whole reasonable range" in text
    agree, text = check.case2_same_amplitude(_pp(1.4), RIG)
    assert not agree and "differs over the whole reasonable range" in text


def test_gone_shows_each_reference_level() -> None:
    assert GONE_FRACTIONS[0] < 0.1 < GONE_FRACTIONS[-1]
    times = [6.25, 5.5, 4.25, 3.25, 2.5]  # paper case 9 as measured
    metrics = {9: {"f0_gone_time": 4.25, "f0_gone_times": times}}
    agree, text = check.gone(9)(metrics, RIG)
    assert not agree and "holds at 0.03, 0.05 only" in text
    metrics = {9: {"f0_gone_time": 8.0, "f0_gone_times": [12.0, 10.0, 8.0, 6.0, float("inf")]}}
    agree, text = check.gone(9)(metrics, RIG)
    assert agree and "holds at 0.03, 0.05, 0.1, 0.2 only" in text
    agree, text = check.gone(9)({9: {"f0_gone_time": 8.0}}, RIG)  # an old scan table
    assert agree and "per reference level" not in text


def test_case8_mu_uses_the_extremes_between_samples() -> None:
    sampled = {"mu_min": 0.0065, "mu_max": 0.023}
    assert not check.case8_mu({8: sampled}, RIG)[0]
    dense = dict(sampled, mu_min_dense=0.0065, mu_max_dense=0.161)
    agree, text = check.case8_mu({8: dense}, RIG)
    assert agree and "between samples" in text and "0.023" in text
    stuck = dict(sampled, mu_min_dense=0.0025, mu_max_dense=0.161)
    assert not check.case8_mu({8: stuck}, RIG)[0]
