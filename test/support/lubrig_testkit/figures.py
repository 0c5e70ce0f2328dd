"""Checks of drawn figures for the tests: texts that overlap or fall outside, colormaps, data ranges.

Read off a matplotlib Figure after drawing it (test/test_figures_content.py,
test/test_report_timing.py, test/test_simulate_cli.py); the package draws, these look.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.figure import Figure


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


def plotted_range(fig: Figure, axis: int = 0) -> tuple[float, float]:
    """Min and max of the y data drawn on one axes (for checks of figure content)."""
    ys = np.concatenate([line.get_ydata() for line in fig.axes[axis].get_lines()])
    return float(np.min(ys)), float(np.max(ys))
