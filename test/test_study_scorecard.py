"""The scorecard of the presets' reading: every statement it agrees with keeps agreeing, and no
coupling of the committed scan reproduces more statements (docs/study.md)."""

from __future__ import annotations

from functools import cache

from lubrig_ros.cli.paper import committed_scan
from lubrig_ros.core.params import RigParameters
from lubrig_ros.core.presets import load_case
from lubrig_ros.study import runs as study_runs
from lubrig_ros.study import statements as study

#: Statements the presets' reading (paper, γ = 1/ω0) agrees with, measured 2026-12 (27 of 38).
PRESET_AGREES = {
    "F1",
    "F2",
    "F3",
    "S1",
    "S2",
    "S3",
    "S4",
    "C1a",
    "C1b",
    "C1c",
    "C2a",
    "C2b",
    "C3b",
    "C4a",
    "C4b",
    "C5a",
    "C5b",
    "C6a",
    "C6c",
    "C6d",
    "C7a",
    "C7b",
    "C10a",
    "C10b",
    "M1",
    "M2",
    "M3",
}


@cache
def preset_scorecard() -> dict[str, study.Verdict]:
    rig = load_case(1).rig
    metrics = study_runs.measure(rig.coupling_name)
    return {v.key: v for v in study.scorecard(metrics, rig)}


def test_presets_use_one_named_reading() -> None:
    rigs = {load_case(n).rig for n in range(1, 11)}
    assert len(rigs) == 1 and next(iter(rigs)).coupling_name == "paper"


def test_preset_reading_keeps_agreeing() -> None:
    cards = preset_scorecard()
    assert set(cards) == {s.key for s in study.STATEMENTS}
    lost = {key: cards[key].measured for key in PRESET_AGREES if not cards[key].agree}
    assert not lost


def test_no_scanned_coupling_reproduces_more_than_the_presets() -> None:
    scan = study_runs.read_scan_csv(committed_scan())
    assert min(scan) <= 1e-3 and max(scan) >= 1.0 and len(scan) >= 40
    best = max(
        sum(v.agree for v in study.scorecard(scan[s], study_runs.rig_with_coupling(RigParameters(), s)))
        for s in scan
    )
    assert best <= sum(v.agree for v in preset_scorecard().values())
