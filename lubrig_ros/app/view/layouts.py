"""Viewer layouts of a rig namespace: Foxglove (layout JSON) and PlotJuggler (layout XML); no ROS.

The files shipped in config/foxglove/ and config/plotjuggler/ are these for the default namespace
(test/test_view_layouts.py keeps them equal); `lubrig view --layout foxglove|plotjuggler
--namespace NS` prints them for another rig. What they show (docs/viewing.md):

- x, ẋ, μ and the two velocities v_band, v_rel against rig time (``<ns>/state``, RigState: the
  live view turns sim mode's ``state_block`` into these samples);
- μ against v_rel (the operating point on the friction curve);
- the wavelet power image (``<ns>/wavelet_image``) and the dominant frequency;
- the stability flags (``<ns>/stability``, StabilityFlags) as state transitions and as numbers;
- ``/diagnostics``.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from typing import Any

from ..interface.contract import DEFAULT_NAMESPACE, resolve

#: (field of <ns>/state, label, unit) of the time plots, one panel per group.
STATE_PLOTS: tuple[tuple[str, tuple[tuple[str, str], ...], str], ...] = (
    ("x: displacement", (("displacement", "x"),), "m"),
    ("ẋ: velocity of the mass", (("velocity", "ẋ"),), "m/s"),
    ("μ: friction coefficient (signed, sign of v_rel)", (("friction_coefficient", "μ"),), "1"),
    ("velocities", (("band_velocity", "v_band"), ("relative_velocity", "v_rel")), "m/s"),
)
#: Fields of <ns>/stability shown as state transitions (enumerations and flags).
STABILITY_STATES: tuple[tuple[str, str], ...] = (
    ("linear_zone", "zone (1 junction, 2 falling, 3 viscous)"),
    ("linear_stable", "linearly stable"),
    ("oscillation", "oscillation (1 steady, 2 decaying, 3 growing)"),
    ("sticking", "sticking"),
    ("resonance", "resonance"),
)
#: Numbers of <ns>/stability plotted (PlotJuggler) beside the flags.
STABILITY_VALUES: tuple[str, ...] = (
    "critical_damping_ratio",
    "damping_ratio",
    "effective_damping",
    "growth_rate",
    "stick_share",
)
COLORS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd")


def _t(namespace: str, name: str) -> str:
    return resolve(namespace, name)


# ----------------------------------------------------------------------------------- Foxglove


def _split(items: list[Any], direction: str) -> Any:
    """A mosaic tree of equal parts (Foxglove's layout: first / second / splitPercentage)."""
    if len(items) == 1:
        return items[0]
    return {
        "direction": direction,
        "first": items[0],
        "second": _split(items[1:], direction),
        "splitPercentage": round(100 / len(items), 2),
    }


def foxglove_layout(namespace: str = DEFAULT_NAMESPACE) -> dict[str, Any]:
    """The Foxglove layout (the app's "Import layout from file" JSON) for a rig in `namespace`."""
    state, stability = _t(namespace, "state"), _t(namespace, "stability")
    panels: dict[str, dict[str, Any]] = {}
    plots = []
    for k, (title, series, unit) in enumerate(STATE_PLOTS):
        pid = f"Plot!state{k}"
        panels[pid] = {
            "foxglovePanelTitle": f"{title} ({unit})",
            "paths": [
                {
                    "value": f"{state}.{field}",
                    "label": f"{label} ({unit})",
                    "enabled": True,
                    "timestampMethod": "receiveTime",
                    "color": COLORS[i],
                }
                for i, (field, label) in enumerate(series)
            ],
            "xAxisVal": "timestamp",
            "showLegend": True,
            "legendDisplay": "floating",
            "showXAxisLabels": True,
            "showYAxisLabels": True,
            "isSynced": True,
            "yAxisLabel": unit,
            "xAxisLabel": "rig time (s)",
        }
        plots.append(pid)
    panels["Plot!mu_v"] = {
        "foxglovePanelTitle": "μ against v_rel (operating point on the friction curve)",
        "paths": [
            {
                "value": f"{state}.friction_coefficient",
                "label": "μ (1)",
                "enabled": True,
                "timestampMethod": "receiveTime",
                "color": COLORS[0],
            }
        ],
        "xAxisVal": "custom",
        "xAxisPath": {"value": f"{state}.relative_velocity", "enabled": True},
        "xAxisLabel": "v_rel (m/s)",
        "yAxisLabel": "μ (1)",
        "showLegend": False,
        "showXAxisLabels": True,
        "showYAxisLabels": True,
    }
    panels["Image!wavelet"] = {
        "foxglovePanelTitle": "wavelet power of x (high frequency on top; log power, 4 decades)",
        "imageMode": {"imageTopic": _t(namespace, "wavelet_image")},
    }
    panels["Plot!frequency"] = {
        "foxglovePanelTitle": "dominant frequency (Hz)",
        "paths": [
            {
                "value": f"{_t(namespace, 'dominant_frequency')}.data",
                "label": "f (Hz)",
                "enabled": True,
                "timestampMethod": "receiveTime",
                "color": COLORS[0],
            }
        ],
        "xAxisVal": "timestamp",
        "showLegend": False,
        "showXAxisLabels": True,
        "showYAxisLabels": True,
        "isSynced": True,
        "yAxisLabel": "Hz",
    }
    panels["StateTransitions!stability"] = {
        "foxglovePanelTitle": "stability flags",
        "paths": [
            {"value": f"{stability}.{field}", "label": label, "timestampMethod": "receiveTime"}
            for field, label in STABILITY_STATES
        ],
        "isSynced": True,
        "showPoints": True,
    }
    panels["RawMessages!stability"] = {
        "foxglovePanelTitle": "stability: values",
        "topicPath": stability,
        "diffEnabled": False,
        "diffMethod": "custom",
        "diffTopicPath": "",
        "showFullMessageForDiff": False,
        "expansion": "all",
    }
    panels["DiagnosticSummary!rig"] = {
        "foxglovePanelTitle": "diagnostics",
        "topicToRender": "/diagnostics",
        "minLevel": 0,
        "pinnedIds": [],
        "hardwareIdFilter": "",
        "sortByLevel": True,
    }
    left = _split([*plots, "Plot!mu_v"], "column")
    right = _split(
        [
            "Image!wavelet",
            "Plot!frequency",
            "StateTransitions!stability",
            _split(["RawMessages!stability", "DiagnosticSummary!rig"], "row"),
        ],
        "column",
    )
    return {
        "configById": panels,
        "globalVariables": {},
        "userNodes": {},
        "playbackConfig": {"speed": 1},
        "layout": {"direction": "row", "first": left, "second": right, "splitPercentage": 55},
    }


def foxglove_json(namespace: str = DEFAULT_NAMESPACE) -> str:
    """foxglove_layout as the text of the shipped file."""
    return json.dumps(foxglove_layout(namespace), indent=2, ensure_ascii=False) + "\n"


# --------------------------------------------------------------------------------- PlotJuggler


def _pj_plot(parent: ET.Element, name: str, curves: list[str]) -> None:
    area = ET.SubElement(parent, "DockArea", name=name)
    plot = ET.SubElement(area, "plot", mode="TimeSeries", style="Lines", flip_x="false", flip_y="false")
    ET.SubElement(plot, "range", top="1", bottom="0", left="0", right="1")
    ET.SubElement(plot, "limitY")
    for i, curve in enumerate(curves):
        ET.SubElement(plot, "curve", name=curve, color=COLORS[i % len(COLORS)])


def _pj_splitter(parent: ET.Element, orientation: str, count: int) -> ET.Element:
    sizes = ";".join([f"{1 / count:.6f}"] * count)
    return ET.SubElement(parent, "DockSplitter", orientation=orientation, sizes=sizes, count=str(count))


def plotjuggler_layout(namespace: str = DEFAULT_NAMESPACE) -> ET.Element:
    """The PlotJuggler layout (File -> Load layout) for a rig in `namespace`.

    Curve names are PlotJuggler's for ROS 2 messages: ``<topic>/<field>``.
    """
    state, stability = _t(namespace, "state"), _t(namespace, "stability")
    root = ET.Element("root")
    tabs = ET.SubElement(root, "tabbed_widget", {"name": "Main Window", "parent": "main_window"})
    tab = ET.SubElement(tabs, "Tab", tab_name="rig", containers="1")
    container = ET.SubElement(tab, "Container")
    columns = _pj_splitter(container, "|", 2)
    left = _pj_splitter(columns, "-", len(STATE_PLOTS))
    for title, series, unit in STATE_PLOTS:
        _pj_plot(left, f"{title} ({unit})", [f"{state}/{field}" for field, _label in series])
    right = _pj_splitter(columns, "-", 3)
    _pj_plot(right, "stability flags", [f"{stability}/{field}" for field, _label in STABILITY_STATES])
    _pj_plot(right, "stability values", [f"{stability}/{field}" for field in STABILITY_VALUES])
    _pj_plot(right, "dominant frequency (Hz)", [f"{_t(namespace, 'dominant_frequency')}/data"])
    ET.SubElement(tabs, "currentTabIndex", index="0")
    ET.SubElement(root, "use_relative_time_offset", enabled="1")
    plugins = ET.SubElement(root, "Plugins")
    ET.SubElement(plugins, "plugin", ID="DataLoad MCAP")
    streamer = ET.SubElement(plugins, "plugin", ID="ROS2 Topic Subscriber")
    ET.SubElement(streamer, "use_header_stamp", value="true")
    ET.SubElement(streamer, "discard_large_arrays", value="true")
    ET.SubElement(streamer, "max_array_size", value="100")
    ET.SubElement(streamer, "boolean_strings_to_number", value="true")
    ET.SubElement(streamer, "remove_suffix_from_strings", value="true")
    topics = [state, stability, _t(namespace, "dominant_frequency")]
    ET.SubElement(streamer, "selected_topics", value=";".join(topics))
    ET.SubElement(root, "previouslyLoaded_Datafiles")
    ET.SubElement(root, "previouslyLoaded_Streamer", name="ROS2 Topic Subscriber")
    return root


def plotjuggler_xml(namespace: str = DEFAULT_NAMESPACE) -> str:
    """plotjuggler_layout as the text of the shipped file."""
    root = plotjuggler_layout(namespace)
    ET.indent(root, space=" ")
    return "<?xml version='1.0' encoding='UTF-8'?>\n" + ET.tostring(root, encoding="unicode") + "\n"


LAYOUTS = {"foxglove": foxglove_json, "plotjuggler": plotjuggler_xml}
SHIPPED = {"foxglove": "foxglove/lubrig_layout.json", "plotjuggler": "plotjuggler/lubrig_layout.xml"}
