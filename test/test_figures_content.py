"""Figures checked by what they show: labels with units, colormaps, text boxes, axis bounds, data.

Text overlap is measured on the drawn figure with matplotlib's renderer extents
(lubrig_testkit.figures.overlapping_texts), so a label printed on top of another fails here.
"""

from __future__ import annotations

import numpy as np
import pytest
from lubrig_testkit.figures import colormap_names, overlapping_texts, texts_outside
from matplotlib.collections import PathCollection, QuadMesh

from lubrig_ros.app.analysis.policy import DEFAULT_POLICY, analyze_displacement
from lubrig_ros.core.friction import friction_coefficient, friction_minimum, friction_peak
from lubrig_ros.core.params import RigParameters
from lubrig_ros.core.presets import RunConfig, load_case
from lubrig_ros.core.run import simulate
from lubrig_ros.figures import style
from lubrig_ros.figures.curves import plot_friction_curve, plot_stability_map
from lubrig_ros.figures.run import wavelet_title
from lubrig_ros.figures.timeseries import FIGURES, friction_velocity_figure, mu_velocity_figure
from lubrig_ros.figures.wavelet import analysis_figure
from lubrig_ros.study.figures import verdict_map_figure

UNIT = ("(m)", "(nm)", "(m/s)", "(s)", "(Hz)", "(–)", "(kg)", "|W|²/σ²", "(N)")


def _run(case: int, duration: float = 4.0, **overrides: object) -> tuple[RunConfig, object]:
    config = load_case(case).with_overrides(duration=duration, **overrides)
    return config, simulate(config)


@pytest.fixture(scope="module")
def case7() -> tuple[RunConfig, object]:
    return _run(7)


@pytest.fixture(scope="module")
def case1() -> tuple[RunConfig, object]:
    return _run(1)


@pytest.fixture(scope="module")
def stickslip() -> tuple[RunConfig, object]:
    """Case 1 in the physical reading: stick-slip, v_rel reverses and μ goes negative."""
    return _run(1, duration=8.0, convention="physical")


def _check_text(fig: object) -> None:
    assert overlapping_texts(fig) == []
    assert texts_outside(fig) == []


def _check_units(fig: object) -> None:
    """Every y label and every drawn x label of the data axes states a unit."""
    for ax in fig.axes:
        for label in (ax.get_ylabel(), ax.get_xlabel()):
            if label:
                assert any(unit in label for unit in UNIT), label
        assert ax.get_ylabel(), f"axes without y label: {ax.get_title()!r}"
    assert fig.axes[-1].get_xlabel() or fig.axes[-2].get_xlabel()


@pytest.mark.parametrize("name", sorted(FIGURES))
@pytest.mark.parametrize("which", ["case1", "case7", "stickslip"])
def test_run_figures_text_units_colormaps_title(
    name: str, which: str, request: pytest.FixtureRequest
) -> None:
    config, traj = request.getfixturevalue(which)
    fig = FIGURES[name](traj, config.name, config.rig.convention, config.rig)
    _check_text(fig)
    _check_units(fig)
    assert colormap_names(fig) <= style.UNIFORM_CMAPS
    title = fig.axes[0].get_title()
    number = int(config.name[4:])
    assert f"case {number}," in title and config.rig.coupling_label in title, title
    assert "v_rel = v_band − γ ẋ" in title


def test_wavelet_case7_labels_apart_axis_bounded_viridis(case7: tuple) -> None:
    config, traj = case7
    analysis = analyze_displacement(
        traj.time, traj.displacement, config.sample_rate, config.band.fundamental_hz, DEFAULT_POLICY
    )
    fig = analysis_figure(analysis, wavelet_title(config), config.rig.natural_frequency)
    _check_text(fig)
    _check_units(fig)
    ax = fig.axes[1]
    marks = [t.get_text() for t in ax.texts]
    # f0 and the band fundamental are both 10 Hz: one label names both, no second label on it
    assert "f0 = f_band 10 Hz" in marks
    assert sum("10 Hz" in m for m in marks) == 1
    assert "2 f_band 20 Hz" in marks and "3 f_band 30 Hz" in marks
    # the axis ends one octave above the highest mark (3 × 10 Hz), not at the analysis' rate / 4
    fmax = float(analysis.wavelet.frequencies.max())
    assert fmax > 200.0
    assert ax.get_ylim()[1] == pytest.approx(60.0)
    assert ax.get_ylim()[0] == pytest.approx(float(analysis.wavelet.frequencies.min()))
    meshes = [c for c in ax.collections if isinstance(c, QuadMesh)]
    assert [m.get_cmap().name for m in meshes] == [style.POWER_CMAP] and style.POWER_CMAP == "viridis"
    title = fig.axes[0].get_title()
    assert "case 7" in title and "paper convention" in title and "c7" not in title


def test_wavelet_case8_marks_apart(tmp_path: object) -> None:
    config, traj = _run(8)
    analysis = analyze_displacement(
        traj.time, traj.displacement, config.sample_rate, config.band.fundamental_hz, DEFAULT_POLICY
    )
    fig = analysis_figure(analysis, wavelet_title(config), config.rig.natural_frequency)
    _check_text(fig)
    marks = [t.get_text() for t in fig.axes[1].texts]
    assert "f0 10 Hz" in marks and "f_band 20 Hz" in marks
    assert fig.axes[1].get_ylim()[1] == pytest.approx(120.0)  # 2 × 3 f_band


def _trajectory_points(fig: object) -> np.ndarray:
    (points,) = [c for c in fig.axes[0].collections if isinstance(c, PathCollection)]
    return np.asarray(points.get_offsets())


@pytest.mark.parametrize("which", ["case1", "case7", "stickslip"])
def test_mu_velocity_trajectory_lies_on_the_friction_law(which: str, request: pytest.FixtureRequest) -> None:
    config, traj = request.getfixturevalue(which)
    fig = mu_velocity_figure(traj, config.name, config.rig.convention, config.rig)
    ax = fig.axes[0]
    xy = _trajectory_points(fig)
    assert len(xy) == len(traj.time)
    np.testing.assert_allclose(xy[:, 0], traj.relative_velocity)  # v_rel, not v_band
    law = friction_coefficient(xy[:, 0], config.rig.friction)
    np.testing.assert_allclose(xy[:, 1], law, rtol=1e-9, atol=1e-15)
    (curve,) = [line for line in ax.get_lines() if line.get_label() == "friction law μ(v_rel)"]
    expected = friction_coefficient(curve.get_xdata(), config.rig.friction)
    np.testing.assert_allclose(curve.get_ydata(), expected)
    lo, hi = ax.get_xlim()
    assert lo < xy[:, 0].min() and xy[:, 0].max() < hi
    assert ax.get_ylim()[0] < xy[:, 1].min() and xy[:, 1].max() < ax.get_ylim()[1]
    assert "signed" in ax.get_ylabel() and "v_rel" in ax.get_xlabel()
    assert colormap_names(fig) == {style.TIME_CMAP}
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    # zones shaded where the axis reaches them: case 1 spans the minimum (zones 2 and 3)
    peak, minimum = friction_peak(config.rig.friction), friction_minimum(config.rig.friction)
    edges = {1: (0.0, peak.velocity), 2: (peak.velocity, minimum.velocity), 3: (minimum.velocity, np.inf)}
    for zone, (a, b) in edges.items():
        forward = min(b, hi) > max(a, lo, 0.0)
        backward = lo < 0 and min(b, -lo) > a
        assert any(t.startswith(f"zone {zone}") for t in legend) == (forward or backward), (zone, legend)
    if which == "case1":
        assert not any(t.startswith("zone 1") for t in legend)
        assert any(t.startswith("zone 2") for t in legend) and any(t.startswith("zone 3") for t in legend)


def test_mu_velocity_symlog_when_v_rel_reverses(stickslip: tuple) -> None:
    config, traj = stickslip
    assert traj.relative_velocity.min() < 0 and traj.friction_coefficient.min() < -0.05
    fig = mu_velocity_figure(traj, config.name, config.rig.convention, config.rig)
    assert fig.axes[0].get_xscale() == "symlog"
    xy = _trajectory_points(fig)
    backwards = xy[:, 0] < 0
    assert backwards.any() and (xy[backwards, 1] < 0).all()  # signed μ: backward sliding, μ < 0


def test_band_velocity_drawn_on_top_of_relative_velocity(case1: tuple) -> None:
    config, traj = case1
    fig = friction_velocity_figure(traj, config.name, config.rig.convention, config.rig)
    lines = {line.get_label(): line for line in fig.axes[1].get_lines()}
    band = next(v for k, v in lines.items() if k.startswith("band v_band"))
    rel = next(v for k, v in lines.items() if k.startswith("relative v_rel"))
    np.testing.assert_array_equal(band.get_ydata(), traj.band_velocity)
    np.testing.assert_array_equal(rel.get_ydata(), traj.relative_velocity)
    assert band.get_zorder() > rel.get_zorder() and band.get_linestyle() == "--"
    assert rel.get_linewidth() > band.get_linewidth()  # the wider v_rel shows around the dashes
    assert "signed" in fig.axes[0].get_ylabel()


def _paper_map() -> object:
    return plot_stability_map(RigParameters(convention="paper"))


@pytest.mark.parametrize("make", [plot_friction_curve, _paper_map])
def test_curves_text_and_units(make: object) -> None:
    fig = make()
    _check_text(fig)
    _check_units(fig)


def test_verdict_map_uses_no_red_green_map() -> None:
    s = np.logspace(-3, 0, 5)
    agree = np.array([[1, 0, 1, 0, 1], [0, 0, 1, 1, 1]], bool)
    fig = verdict_map_figure(s, ["A", "B"], agree, {"paper": 0.016})
    (mesh,) = [c for c in fig.axes[0].collections if isinstance(c, QuadMesh)]
    assert mesh.get_cmap().name == "lubrig_binary"
    assert list(mesh.get_cmap().colors) == list(style.BINARY_COLOURS)
