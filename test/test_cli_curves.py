"""`lubrig friction` / `lubrig stability`, and the figures they draw.

One test runs the real console script (same output as in-process, one-line errors from a fresh
interpreter); the others call the same main() in-process (lubrig_testkit.cli), which is cheaper.
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pytest
from lubrig_testkit.cli import lubrig

from lubrig_ros.core.friction import friction_coefficient, friction_minimum, friction_peak
from lubrig_ros.core.params import RigParameters
from lubrig_ros.core.stability import critical_damping_ratio
from lubrig_ros.figures.curves import CSV_HEADER, plot_friction_curve, plot_stability_map

SCRIPT = Path(sys.executable).with_name("lubrig")
COMMAND = [str(SCRIPT)] if SCRIPT.exists() else [sys.executable, "-m", "lubrig_ros.cli.main"]


def lubrig_process(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*COMMAND, *args], capture_output=True, text=True, timeout=120, check=False)


def lubrig_json(*args: str) -> dict:
    result = lubrig(*args, "--json")
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def assert_one_line_error(result: subprocess.CompletedProcess[str], *fragments: str) -> None:
    assert result.returncode != 0
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    for fragment in fragments:
        assert fragment in lines[0]
    assert "Traceback" not in result.stderr


def assert_png_has_content(path: Path, min_size: tuple[int, int] = (600, 400)) -> None:
    image = mpimg.imread(path)
    height, width = image.shape[:2]
    assert width >= min_size[0] and height >= min_size[1]
    rgb = image[..., :3]
    # not blank: many distinct colours and a real spread of brightness
    assert rgb.std() > 0.05
    assert len(np.unique(rgb.reshape(-1, 3), axis=0)) > 50


# --- lubrig friction -------------------------------------------------------------------------


def test_friction_and_stability_as_real_processes() -> None:
    """The console script itself: the in-process answers, and bad values as one stderr line."""
    for args in (("friction", "--at", "1e-7", "--json"), ("stability", "--zeta", "0.01", "--json")):
        result = lubrig_process(*args)
        assert result.returncode == 0, result.stderr
        assert json.loads(result.stdout) == json.loads(lubrig(*args).stdout)
    result = lubrig_process("friction", "--at", "1e-7")
    assert result.returncode == 0 and "6.55305e-03" in result.stdout, result.stderr
    assert_one_line_error(lubrig_process("friction", "--at", "nan"), "--at", "'nan'", "finite")
    assert_one_line_error(lubrig_process("stability", "--zeta", "-0.1"), "--zeta", "'-0.1'", ">= 0")


def test_friction_json_landmarks_and_points() -> None:
    report = lubrig_json("friction", "--at", "1e-7", "-1e-7", "2e-7", "1e-6")
    assert report["peak"]["mu"] == pytest.approx(0.161, rel=0.01)
    assert report["peak"]["velocity"] == pytest.approx(4.08e-12, rel=0.01)
    assert report["minimum"]["mu"] == pytest.approx(6.486e-3, rel=0.01)
    assert report["minimum"]["velocity"] == pytest.approx(1.35e-7, rel=0.01)
    points = report["points"]
    assert [p["velocity"] for p in points] == [1e-7, -1e-7, 2e-7, 1e-6]
    assert points[0]["mu"] == pytest.approx(6.553e-3, rel=0.01)
    assert points[1]["mu"] == -points[0]["mu"]  # odd
    assert points[1]["dmu_dv"] == points[0]["dmu_dv"]  # even slope
    assert points[0]["dmu_dv"] < 0 < points[2]["dmu_dv"]  # 1e-7 in zone 2, 2e-7 in zone 3
    assert points[3]["mu"] == pytest.approx(9.20e-3, rel=0.01)


def test_friction_json_without_at_has_no_points() -> None:
    report = lubrig_json("friction")
    assert set(report) >= {"peak", "minimum"}
    assert "points" not in report


def test_friction_negative_integer_velocity_is_accepted() -> None:
    report = lubrig_json("friction", "--at", "-1")
    assert report["points"][0]["mu"] == pytest.approx(-float(friction_coefficient(1.0)))


def test_friction_zero_velocity_has_null_slope() -> None:
    report = lubrig_json("friction", "--at", "0")
    assert report["points"][0] == {"velocity": 0.0, "mu": 0.0, "dmu_dv": None}


def test_friction_printed_area_is_ten_times_smaller() -> None:
    corrected = lubrig_json("friction", "--at", "1e-7")
    printed = lubrig_json("friction", "--at", "1e-7", "--contact-area", "printed")
    assert printed["contact_area_m2"] == pytest.approx(28.3e-12)
    assert corrected["points"][0]["mu"] / printed["points"][0]["mu"] == pytest.approx(10, rel=1e-12)
    assert printed["peak"]["mu"] * 10 == pytest.approx(corrected["peak"]["mu"], rel=1e-12)
    numeric = lubrig_json("friction", "--at", "1e-7", "--contact-area", "5.66e-10")
    assert numeric["points"][0]["mu"] == pytest.approx(2 * corrected["points"][0]["mu"], rel=1e-12)


def test_friction_human_table() -> None:
    result = lubrig("friction", "--at", "1e-7")
    assert result.returncode == 0, result.stderr
    assert "peak" in result.stdout and "minimum" in result.stdout
    assert "6.55305e-03" in result.stdout  # μ(1e-7) to 6 digits
    with pytest.raises(json.JSONDecodeError):
        json.loads(result.stdout)


@pytest.mark.parametrize(
    ("args", "fragments"),
    [
        (["--at", "nan"], ["--at", "'nan'", "finite"]),
        (["--at", "1e-7", "inf"], ["--at", "'inf'"]),
        (["--at", "fast"], ["--at", "'fast'", "not a number"]),
        (["--contact-area", "huge"], ["--contact-area", "'huge'", "printed"]),
        (["--contact-area", "-1e-10"], ["--contact-area", "'-1e-10'"]),
    ],
)
def test_friction_bad_input_is_one_error_line(args: list[str], fragments: list[str]) -> None:
    assert_one_line_error(lubrig("friction", *args), *fragments)


def test_friction_out_writes_csv_and_figure(tmp_path: Path) -> None:
    out = tmp_path / "curves"
    report = lubrig_json("friction", "--out", str(out))
    csv_path, png_path = out / "friction_curve.csv", out / "friction_curve.png"
    assert sorted(report["files"]) == sorted([str(csv_path), str(png_path)])
    with csv_path.open() as handle:
        rows = list(csv.reader(handle))
    assert ",".join(rows[0]) == CSV_HEADER
    table = np.array(rows[1:], dtype=float)
    v, mu, slope = table.T
    assert v[0] == pytest.approx(1e-15) and v[-1] == pytest.approx(1e-2)
    steps = np.diff(np.log10(v))
    np.testing.assert_allclose(steps, steps[0], rtol=1e-6)  # log spaced
    assert np.isfinite(table).all()
    np.testing.assert_allclose(mu, friction_coefficient(v), rtol=1e-11)
    # the written derivative agrees with the written curve (central differences, smooth part)
    numeric = np.gradient(mu, v)
    interior = slice(5, -5)
    zeros = np.abs(slope[interior]) < 1e-2 * np.abs(slope).max()
    rel = np.abs(numeric[interior] / slope[interior] - 1)[~zeros]
    assert np.median(rel) < 1e-2
    # the low-velocity maximum (zone 1/2 edge) is where the landmark says
    low = v < 1e-9
    assert v[low][mu[low].argmax()] == pytest.approx(friction_peak().velocity, rel=0.05)
    assert_png_has_content(png_path)


# --- lubrig stability ------------------------------------------------------------------------


def test_stability_json_physical_default() -> None:
    report = lubrig_json("stability", "--zeta", "0", "0.01", "0.1")
    assert report["convention"] == "physical"
    assert [r["zeta"] for r in report["results"]] == [0.0, 0.01, 0.1]
    ((lo0, hi0),) = report["results"][0]["unstable_intervals"]
    assert lo0 == pytest.approx(friction_peak().velocity, rel=1e-8)
    assert hi0 == pytest.approx(friction_minimum().velocity, rel=1e-8)
    ((lo1, hi1),) = report["results"][1]["unstable_intervals"]
    assert lo1 < 1e-7 < hi1  # V1 unstable at the rig's damping (physical)
    ((_, hi2),) = report["results"][2]["unstable_intervals"]
    assert hi2 < hi1 < hi0


def test_stability_json_paper_convention() -> None:
    report = lubrig_json("stability", "--zeta", "0.01", "--convention", "paper")
    assert report["convention"] == "paper"
    ((lo, hi),) = report["results"][0]["unstable_intervals"]
    assert lo < hi < 1e-7  # V1 = 1e-7 is stable at ζ = 0.01 in the paper convention
    rig = RigParameters(convention="paper")
    assert float(critical_damping_ratio(hi, rig)) == pytest.approx(0.01, rel=1e-6)


def test_stability_zeta_crit_at_velocity() -> None:
    report = lubrig_json("stability", "--zeta", "0.01", "--at", "3e-8", "--convention", "paper")
    expected = float(critical_damping_ratio(3e-8, RigParameters(convention="paper")))
    assert report["critical_damping_ratio"]["zeta_crit"] == pytest.approx(expected, rel=1e-12)


def test_stability_large_damping_has_no_unstable_interval() -> None:
    report = lubrig_json("stability", "--zeta", "1e9")
    assert report["results"][0]["unstable_intervals"] == []


@pytest.mark.parametrize(
    ("args", "fragments"),
    [
        (["--zeta", "-0.1"], ["--zeta", "'-0.1'", ">= 0"]),
        (["--zeta", "nan"], ["--zeta", "'nan'"]),
        (["--zeta", "0.01", "x"], ["--zeta", "'x'"]),
        (["--convention", "bogus"], ["--convention", "'bogus'", "physical", "paper"]),
        (["--at", "-3e-8"], ["--at", "'-3e-8'", "> 0"]),
    ],
)
def test_stability_bad_input_is_one_error_line(args: list[str], fragments: list[str]) -> None:
    assert_one_line_error(lubrig("stability", *args), *fragments)


def test_stability_out_writes_map(tmp_path: Path) -> None:
    report = lubrig_json("stability", "--convention", "paper", "--out", str(tmp_path))
    png = tmp_path / "stability_map.png"
    assert report["files"] == [str(png)]
    assert_png_has_content(png)


# --- figures as objects ----------------------------------------------------------------------


def test_friction_figure_content() -> None:
    fig = plot_friction_curve()
    (ax,) = fig.axes
    assert ax.get_xscale() == "log"
    assert "m/s" in ax.get_xlabel() and "μ" in ax.get_ylabel()
    (curve,) = [line for line in ax.get_lines() if line.get_label() == "μ(v)"]
    v, mu = np.asarray(curve.get_xdata()), np.asarray(curve.get_ydata())
    assert v.min() == pytest.approx(1e-15) and v.max() == pytest.approx(1e-2)
    low = v < 1e-9
    assert mu[low].max() == pytest.approx(friction_peak().mu, rel=1e-3)
    np.testing.assert_allclose(mu, friction_coefficient(v), rtol=1e-12)
    assert ax.get_ylim()[0] == 0.0 and mu.max() < ax.get_ylim()[1]  # nothing clipped
    texts = " ".join(t.get_text() for t in ax.texts)
    assert all(f"zone {n}" in texts for n in (1, 2, 3))
    legend = " ".join(t.get_text() for t in ax.get_legend().get_texts())
    assert "peak" in legend and "minimum" in legend
    # zone shading: three spans between the axis limits and the two landmarks
    assert len(ax.patches) >= 3


@pytest.mark.parametrize("convention", ["physical", "paper"])
def test_stability_figure_content(convention: str) -> None:
    rig = RigParameters(convention=convention)
    fig = plot_stability_map(rig)
    (ax,) = fig.axes
    assert ax.get_xscale() == "log" and ax.get_yscale() == "log"
    assert convention in ax.get_title()
    assert "m/s" in ax.get_xlabel() and "ζ" in ax.get_ylabel()
    (zeta_line,) = [line for line in ax.get_lines() if "ζ_crit" in line.get_label()]
    v, zc = np.asarray(zeta_line.get_xdata()), np.asarray(zeta_line.get_ydata())
    finite = np.isfinite(zc)
    # ζ_crit is drawn only in zone 2, and its maximum is within the y range
    assert v[finite].min() >= friction_peak().velocity * (1 - 1e-9)
    assert v[finite].max() <= friction_minimum().velocity * (1 + 1e-9)
    assert np.nanmax(zc) < ax.get_ylim()[1]
    np.testing.assert_allclose(zc[finite], critical_damping_ratio(v[finite], rig), rtol=1e-12)
    assert len(ax.collections) >= 1  # the shaded unstable region
