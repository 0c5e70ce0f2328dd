"""The one figure style of lubrig_ros: colormaps, colours of each quantity, titles, text checks.

Every figure module takes its colours, colormaps, sizes and title wording from here, so a change
of style is one edit. Colormaps are perceptually uniform (viridis family, never jet/rainbow);
colours of the quantities are the same in every figure (the band velocity is always black and
dashed, drawn above the relative velocity so it is never hidden).
"""

from __future__ import annotations

import re
from typing import Any

from matplotlib.figure import Figure

from ..core.params import CONVENTIONS, RigParameters

#: Wavelet power and other magnitude maps.
POWER_CMAP = "viridis"
#: Time along a trajectory (μ–v figure).
TIME_CMAP = "cividis"
#: Continuous maps of sweep results.
MAP_CMAP = "viridis"
#: Two-valued maps (agree / differs, stable / unstable): the ends of cividis (colour-blind safe).
BINARY_COLOURS = ("#00224e", "#fee838")
#: The colormaps this package may use (tests check every figure against it).
UNIFORM_CMAPS = frozenset({"viridis", "magma", "cividis", "inferno", "plasma"})

#: One colour per quantity, the same in every figure.
COLOURS = {
    "displacement": "#1f4e79",
    "velocity": "#d95f02",  # mass velocity ẋ
    "band_velocity": "black",  # v_band: black, dashed, on top
    "relative_velocity": "#1b9e77",  # v_rel
    "friction_coefficient": "#7b3294",
    "curve": "black",
    "transient": "0.65",
    "lateness": "#31688e",  # realtime lateness of a sample (the lag of rig time behind wall time)
    "deadline": "0.25",  # one sample period after a sample's due time
    "max_lag": "#b2182b",  # the plant's bound on the lag before it skips samples
    "skipped": "#e08214",  # samples the plant declared skipped (a declared gap)
}
BAND_STYLE: dict[str, Any] = {"color": "black", "ls": "--", "lw": 1.1, "zorder": 5}

#: Zones of the friction law (model doc §3): light fills, labels in words.
ZONE_COLOURS = {1: "#e5f5e0", 2: "#fde0dd", 3: "#deebf7"}
ZONE_LABELS = {
    1: "zone 1\nrising\n(stable)",
    2: "zone 2\nfalling\n(unstable unless damped)",
    3: "zone 3\nrising, viscous\n(stable)",
}

#: Axis labels used in several figures (SI units stated on every axis).
MU_SIGNED = "friction coefficient μ (–)\nsigned: μ < 0 when v_rel < 0"
V_REL = "relative sliding velocity v_rel = v_band − γ ẋ (m/s)"
TIME = "time t (s)"
FREQUENCY = "frequency (Hz)"

#: Resolution of saved run figures (dpi) and the report's figure size (inches).
DPI = 110
WIDE = (9.0, 6.0)
SQUARE = (6.5, 5.5)
TITLE_SIZE = 10
LEGEND_SIZE = 8
MARK_SIZE = 8

_CASE = re.compile(r"^case0*(\d+)$")


def run_name(name: str) -> str:
    """A run's name as a title says it: 'case07' → 'case 7'; other names unchanged."""
    match = _CASE.match(name)
    return f"case {match.group(1)}" if match else name


def coupling_text(coupling: str | RigParameters) -> str:
    """'paper convention (γ = 0.0159)' from a rig, 'paper convention' from a convention name."""
    if isinstance(coupling, RigParameters):
        return coupling.coupling_label
    return f"{coupling} convention" if coupling in CONVENTIONS else str(coupling)


def summary_coupling(summary: dict[str, Any]) -> str:
    """The coupling text of a summary.json ('paper convention (γ = 0.0159)' or 'γ = 0.05')."""
    gamma = summary.get("velocity_coupling")
    text = f"γ = {gamma:.3g}" if isinstance(gamma, (int, float)) else ""
    convention = summary.get("convention")
    if convention in CONVENTIONS:
        return f"{convention} convention" + (f" ({text})" if text else "")
    return text or "velocity coupling not stated"


def run_title(name: str, coupling: str | RigParameters, what: str = "") -> str:
    """'What — case 7, paper convention (γ = 0.0159), v_rel = v_band − γ ẋ'."""
    head = f"{what} — " if what else ""
    return f"{head}{run_name(name)}, {coupling_text(coupling)}, v_rel = v_band − γ ẋ"


def _axes_texts(ax: Any) -> list[Any]:
    """Every text matplotlib draws for one axes: titles, labels, drawn tick labels, texts, legend."""
    texts = [ax.title, ax._left_title, ax._right_title]
    for axis in (ax.xaxis, ax.yaxis):
        texts += [axis.label, axis.get_offset_text()]
        for tick in axis._update_ticks():  # the ticks inside the view (those drawn)
            texts += [tick.label1, tick.label2]
    texts += list(ax.texts)
    legend = ax.get_legend()
    if legend is not None:
        texts += [*legend.get_texts(), legend.get_title()]
    return texts


def text_boxes(fig: Figure) -> list[tuple[Any, Any]]:
    """(text artist, window extent in pixels) of every drawn, non-empty text of a figure.

    Titles, axis labels, the tick labels drawn, legend texts and free texts (ax.text, fig.text);
    the figure is drawn first so the extents are those of the saved image.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    texts = [t for ax in fig.axes for t in _axes_texts(ax)] + list(fig.texts)
    suptitle = fig._suptitle  # type: ignore[attr-defined]
    if suptitle is not None and not any(t is suptitle for t in texts):  # fig.texts may hold it
        texts.append(suptitle)
    boxes = []
    for text in texts:
        if text.get_visible() and str(text.get_text()).strip():
            boxes.append((text, text.get_window_extent(renderer)))
    return boxes


def overlapping_texts(fig: Figure) -> list[tuple[str, str]]:
    """Pairs of drawn texts whose boxes overlap by more than one pixel each way (touching is fine)."""
    boxes = text_boxes(fig)
    pairs = []
    for i, (a, box_a) in enumerate(boxes):
        for b, box_b in boxes[i + 1 :]:
            dx = min(box_a.x1, box_b.x1) - max(box_a.x0, box_b.x0)
            dy = min(box_a.y1, box_b.y1) - max(box_a.y0, box_b.y0)
            if dx > 1.0 and dy > 1.0:
                pairs.append((str(a.get_text()), str(b.get_text())))
    return pairs


def texts_outside(fig: Figure) -> list[str]:
    """Drawn texts that do not fit inside the figure (cut off in the saved image)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    boxes = text_boxes(fig)
    width, height = FigureCanvasAgg(fig).get_width_height()
    return [
        str(t.get_text())
        for t, box in boxes
        if box.x0 < -1.0 or box.y0 < -1.0 or box.x1 > width + 1.0 or box.y1 > height + 1.0
    ]


def colormap_names(fig: Figure) -> set[str]:
    """Names of the colormaps of every image, mesh and scatter drawn in a figure."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.contour import ContourSet

    names = set()
    for artist in fig.findobj(lambda a: isinstance(a, ScalarMappable)):
        mappable: Any = artist  # a ScalarMappable (findobj is typed as returning Artists)
        if mappable.get_array() is not None and not isinstance(artist, ContourSet):
            names.add(mappable.get_cmap().name)
    return names
