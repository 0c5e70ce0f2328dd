"""`lubrig paper`: offline reproduction and comparison.md content (short run length)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

from lubrig_ros.cli.main import main


@pytest.mark.slow
def test_paper_writes_comparison_with_verdicts(tmp_path: Path) -> None:
    out = tmp_path / "paper"
    assert main(["paper", "--out", str(out), "--duration", "6"]) == 0
    text = (out / "comparison.md").read_text()
    table = text.split("## All ten cases")[0]
    rows = [line for line in table.splitlines() if line.startswith("| ") and "verdict" not in line]
    assert len(rows) == 19
    for row in rows:
        verdict = row.rstrip(" |").split(" | ")[-1]
        assert verdict == "agree" or verdict.startswith("differs"), row
    landmarks = [r for r in rows if r.startswith("| 3 landmarks")]
    assert len(landmarks) == 4 and all(r.endswith("| agree |") for r in landmarks)
    assert any(r.startswith("| 6 case 9") for r in rows)
    assert sum(r.startswith("| 5/6 physical") for r in rows) == 4
    for number in range(1, 11):
        assert (out / "cases" / f"case{number:02d}" / "wavelet.png").is_file()
        assert (out / "cases" / f"case{number:02d}_physical" / "summary.json").is_file()
        assert f"| case{number:02d} | paper |" in text and f"| case{number:02d} | physical |" in text
    for name in ("friction_curve.png", "stability_map.png", "stickslip/time_history.png"):
        image = imread(out / name)
        assert float(np.std(image[..., :3])) > 0.02, name


def test_paper_bad_duration_one_line() -> None:
    res = subprocess.run(
        [sys.executable, "-m", "lubrig_ros.cli.main", "paper", "--out", "/tmp/x", "--duration", "1"],
        capture_output=True, text=True, timeout=60, check=False,
    )
    assert res.returncode == 2
    assert len(res.stderr.strip().splitlines()) == 1 and "--duration" in res.stderr
