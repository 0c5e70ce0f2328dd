"""`lubrig paper`: offline reproduction, the scorecard per reading and the page (short run length)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

from lubrig_ros.cli.main import main
from lubrig_ros.cli.paper import committed_scan
from lubrig_ros.core.params import CONVENTIONS
from lubrig_ros.study.statements import STATEMENTS


@pytest.mark.slow
def test_paper_writes_scorecard_and_embeds_every_figure(tmp_path: Path) -> None:
    out = tmp_path / "paper"
    docs = tmp_path / "docs"
    assert main(["paper", "--out", str(out), "--duration", "6", "--docs", str(docs)]) == 0
    text = (out / "comparison.md").read_text()
    scorecard = text.split("## Scorecard per reading")[1].split("\n## ")[0]
    rows = [line for line in scorecard.splitlines() if line.startswith("| ") and "criterion" not in line]
    assert [r.split(" | ")[0][2:] for r in rows] == [s.key for s in STATEMENTS]
    for row in rows:
        marks = row.rstrip(" |").split(" | ")[-len(CONVENTIONS) :]
        assert all(m in ("✓", "✗") for m in marks), row
    landmarks = [r for r in rows if r.startswith("| F")]
    assert len(landmarks) == 3 and all(r.endswith("| ✓ | ✓ | ✓ |") for r in landmarks)
    for name in CONVENTIONS:
        assert re.search(rf"\| \**{name}\** \| [0-9.e-]+ \| [0-9.e-]+ \| \**\d+ of {len(STATEMENTS)}", text)
    # every image is embedded with a link relative to the page, and each target exists in DIR and docs/
    images = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    assert len(images) >= 30 + 3 + 4
    assert not [i for i in images if i.startswith(("/", "DIR"))]
    for image in images:
        for root in (out, docs):
            picture = imread(root / image)
            assert float(np.std(picture[..., :3])) > 0.02, image
    assert (docs / "study.md").read_text() == text
    links = re.findall(r"(?<!!)\[[^\]]*\]\(([^)]+)\)", text)
    assert not [link for link in links if not link.startswith("http")]  # no links into DIR/runs
    assert committed_scan().is_file() and (out / "coupling_scan.csv").is_file()
    for name in CONVENTIONS:
        assert (out / "runs" / name / "case08" / "summary.json").is_file()


def test_paper_bad_duration_one_line() -> None:
    res = subprocess.run(
        [sys.executable, "-m", "lubrig_ros.cli.main", "paper", "--out", "/tmp/x", "--duration", "1"],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert res.returncode == 2
    assert len(res.stderr.strip().splitlines()) == 1 and "--duration" in res.stderr
