"""The numbers the study page's mechanism texts quote.

Linear-theory thresholds, case 8's Floquet threshold, the structural decay of the 10 Hz
transient, and what the coupling scan shows.

`numbers` returns them by the names the templates of study/page.MECHANISMS use.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..core.params import RigParameters
from ..core.stability import critical_damping_ratio
from .checks import ABOUT_WINDOW, GONE_AFTER_S, SAME_TOLERANCE
from .floquet import PeriodDoubling
from .runs import GONE_FRACTION, Metrics, rig_with_coupling
from .statements import Verdict


def agreement_intervals(cards: dict[float, list[Verdict]], key: str) -> str:
    """Scanned s ranges (first … last scanned value) where a statement agrees, as text."""
    return _intervals({s: next(v.agree for v in cards[s] if v.key == key) for s in cards})


def _intervals(flag_at: dict[float, bool]) -> str:
    """Scanned s ranges (first … last scanned value) where the flag is set, as text."""
    values = sorted(flag_at)
    flags = [flag_at[s] for s in values]
    parts, start = [], None
    for i, flag in enumerate(flags):
        if flag and start is None:
            start = i
        if start is not None and (not flag or i == len(flags) - 1):
            end = i if flag else i - 1
            a, b = values[start], values[end]
            parts.append(f"{a:.3g}" if a == b else f"{a:.3g} … {b:.3g}")
            start = None
    return ", ".join(parts) or "none"


def _decay_numbers() -> dict[str, Any]:
    """The structural decay of the 10 Hz transient that C9a, C9b quote, from the default rig."""
    rig = RigParameters()
    rate = rig.damping_ratio * rig.angular_frequency  # ζ ω0, 1/s
    t_gone = math.log(1.0 / GONE_FRACTION) / rate  # s to fall to GONE_FRACTION
    return {
        "zeta_omega": rate,
        "t_gone": t_gone,
        "gone_pct": f"{GONE_FRACTION:.0%}",
        "c9b_slower": GONE_AFTER_S[9] / t_gone,
        "c10b_early": ABOUT_WINDOW[0] * GONE_AFTER_S[10],
        "same_tolerance": SAME_TOLERANCE,
    }


def _first(values: list[float], flags: list[bool]) -> float:
    return next((s for s, flag in zip(values, flags, strict=True) if flag), math.nan)


def numbers(
    scan: dict[float, Metrics] | None,
    scan_cards: dict[float, list[Verdict]] | None = None,
    doubling: PeriodDoubling | None = None,
) -> dict[str, Any]:
    """Thresholds quoted by the mechanisms (linear theory, case 8's Floquet threshold, the scan)."""
    unit = rig_with_coupling(RigParameters(), 1.0)
    zc_v1 = float(critical_damping_ratio(1e-7, unit))  # ζ_crit at s = 1 (∝ s)
    zc_edge = float(critical_damping_ratio(3e-8, unit))
    v = np.logspace(np.log10(3.05e-8), np.log10(1.34e-7), 200)
    nan = math.nan
    out: dict[str, Any] = {
        "zc_v1": zc_v1,
        "s_v1": 0.01 / zc_v1,
        "s_edge": 0.1 / zc_edge,
        "s_stab": 0.12 / float(np.max(critical_damping_ratio(v, unit))),
        "s_pd": doubling.threshold if doubling is not None else nan,
        "s_pd_scan": nan,
        "s_c8a": nan,
        "c8b_range": "none",
        "c8_missed": "none",
        **dict.fromkeys(("c8_peak", "c8_s_peak", "c8_sampled", "c8_min_lo", "c8_min_hi"), nan),
        **dict.fromkeys(("c8_s_rev", "c8_slide_max"), nan),
        **_decay_numbers(),
        "c10b_fast": "none",
        "c2a_range": "none",
        "c2a_ratio": "n/a",
    }
    if scan:
        values = sorted(scan)
        m8 = [scan[s][8] for s in values]
        out["s_pd_scan"] = _first(
            values,
            [
                m["f0_growth_rate"] is not None and m["f0_growth_rate"] > 0 and m["f0_amplitude_late"] > 1e-10
                for m in m8
            ],
        )
        early = ABOUT_WINDOW[0] * GONE_AFTER_S[10]
        fast = {s: scan[s][10]["f0_gone_time"] for s in values}
        out["c10b_fast"] = _intervals(
            {s: t is not None and math.isfinite(t) and t < early for s, t in fast.items()}
        )
        if scan_cards:
            out["s_c8a"] = _first(values, [_agrees(scan_cards[s], "C8a") for s in values])
            out["c8b_range"] = agreement_intervals(scan_cards, "C8b")
            c2a_sliding = [  # C2a differs while case 2 slides throughout
                s for s in values if not _agrees(scan_cards[s], "C2a") and scan[s][2]["stick_fraction"] == 0
            ]
            ratios = [scan[s][2]["x_peak_to_peak"] / scan[s][1]["x_peak_to_peak"] for s in c2a_sliding]
            if ratios:
                out["c2a_range"] = _intervals({s: s in c2a_sliding for s in values})
                out["c2a_ratio"] = f"{min(ratios):.3g} … {max(ratios):.3g}"
        if all(m.get("mu_max_dense") is not None for m in m8):
            high = [float(m["mu_max_dense"]) for m in m8]
            low = [float(m["mu_min_dense"]) for m in m8]
            at_peak = [h >= 0.1 for h in high]
            out["c8_s_peak"] = _first(values, at_peak)
            peaked = [i for i, flag in enumerate(at_peak) if flag]
            sliding = [i for i, flag in enumerate(at_peak) if not flag and values[i] < out["c8_s_peak"]]
            if peaked:
                out["c8_peak"] = max(high[i] for i in peaked)
                missed = [i for i in peaked if float(m8[i]["mu_max"]) < 0.1]
                if missed:
                    out["c8_sampled"] = max(float(m8[i]["mu_max"]) for i in missed)
                    out["c8_missed"] = f"{values[missed[0]]:.3g} … {values[missed[-1]]:.3g}"
                positive = [low[i] for i in peaked if low[i] >= 0]
                out["c8_min_lo"] = min(positive) if positive else nan
                out["c8_min_hi"] = max(low[i] for i in peaked)
            if sliding:
                out["c8_slide_max"] = max(high[i] for i in sliding)
            out["c8_s_rev"] = _first(values, [lo < 0 for lo in low])
    return out


def _agrees(verdicts: list[Verdict], key: str) -> bool:
    return next(v.agree for v in verdicts if v.key == key)
