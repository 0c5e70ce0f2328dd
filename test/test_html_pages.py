"""HTML pages beside the Markdown reports: self-contained (every figure embedded), images decode."""

from __future__ import annotations

import base64
import io
import os
import pty
import re
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path

import pytest
from PIL import Image
from test_report import _bag

from lubrig_ros.report import write_report
from lubrig_ros.report.html import PageError, markdown_to_html
from lubrig_ros.study.page import CASE_FIGURES


class _Refs(HTMLParser):
    """Every src/href attribute and every tag of a page."""

    def __init__(self) -> None:
        super().__init__()
        self.src: list[str] = []
        self.href: list[str] = []
        self.tags: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append(tag)
        for name, value in attrs:
            if name == "src":
                self.src.append(value or "")
            if name == "href":
                self.href.append(value or "")


def _check_self_contained(page: Path, markdown: Path) -> _Refs:
    refs = _Refs()
    refs.feed(page.read_text())
    assert "link" not in refs.tags and "script" not in refs.tags
    images = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", markdown.read_text())
    assert len(refs.src) == len(images) > 0
    for src in refs.src:
        assert src.startswith("data:image/png;base64,"), src[:40]
        picture = Image.open(io.BytesIO(base64.b64decode(src.split(",", 1)[1], validate=True)))
        picture.load()
        assert picture.width > 300 and picture.height > 300
    assert not [h for h in refs.href if not h.startswith(("http://", "https://", "#"))]
    return refs


def test_report_html_embeds_every_figure(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    _bag(bag, duration=2.0)
    page = write_report(bag, tmp_path / "report")
    html = page.with_suffix(".html")
    assert html.is_file()
    _check_self_contained(html, page)
    text = html.read_text()
    assert "<h1>Run report: case 1, paper convention (γ = 0.0159)</h1>" in text
    assert "<table>" in text and "<h2>Operating point on the friction curve (μ against v_rel)</h2>" in text


def test_missing_figure_is_one_error(tmp_path: Path) -> None:
    with pytest.raises(PageError, match=r"'gone\.png' of the page is missing"):
        markdown_to_html("# t\n\n![x](gone.png)\n", tmp_path, "t")


def test_markdown_subset(tmp_path: Path) -> None:
    Image.new("RGB", (4, 4), "white").save(tmp_path / "a.png")
    text = (
        "# Title\n\nSome `code` and **bold** text.\n\n| a | b \\| c |\n|---|---|\n| 1 | 2 |\n\n"
        "- one\n- two\n\n![a](a.png)\n"
    )
    html = markdown_to_html(text, tmp_path, "T")
    assert "<h1>Title</h1>" in html and "<code>code</code>" in html and "<strong>bold</strong>" in html
    assert "<th>b | c</th>" in html and "<td>2</td>" in html and "<li>two</li>" in html
    assert html.count("data:image/png;base64,") == 1


@pytest.mark.slow
def test_paper_html_every_case_figure_and_progress_on_a_pty(tmp_path: Path) -> None:
    out = tmp_path / "paper"
    master, slave = pty.openpty()
    proc = subprocess.Popen(
        [sys.executable, "-m", "lubrig_ros.cli.main", "paper", "--out", str(out), "--duration", "6"],
        stdin=slave,
        stdout=slave,
        stderr=slave,
    )
    os.close(slave)
    output = b""
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:
            break
        if not chunk:
            break
        output += chunk
    os.close(master)
    assert proc.wait(timeout=900) == 0, output.decode()[-2000:]
    text = output.decode()
    status = [line for line in text.replace("\r\n", "\n").split("\r") if "rig time" in line]
    assert status and "lubrig paper: rig time 198.0 / 198 s" in status[-1]  # 3 readings × 11 runs × 6 s
    page = out / "comparison.md"
    markdown = page.read_text()
    for number in range(1, 11):
        for figure in CASE_FIGURES:
            assert f"(study/paper/case{number:02d}_{figure})" in markdown
    _check_self_contained(out / "comparison.html", page)
    assert "DIR/" not in markdown and "../shared" not in markdown
