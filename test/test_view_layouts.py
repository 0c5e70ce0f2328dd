"""Live view without ROS: decimation rules (app/view/display.py) and the shipped viewer layouts.

The layouts are checked against what they name: every topic is a contract topic, every field
exists in that topic's message definition (lubrig_interfaces/msg/*.msg, the installed .msg of
standard types), and every Foxglove panel setting is one Foxglove's own SDK (foxglove.layouts)
knows for that panel.
"""

from __future__ import annotations

import dataclasses
import itertools
import re
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from lubrig_ros.app.interface import contract
from lubrig_ros.app.view import display, layouts
from lubrig_ros.core.params import ParameterError

ROOT = Path(__file__).resolve().parents[1]
MS = 1_000_000


# ------------------------------------------------------------------------------- decimation


def test_decimator_bounds_count_and_spacing_by_message_time():
    d = display.Decimator(50.0, wall_factor=1e6)  # wall ceiling out of the way
    stamps = [i * MS for i in range(10_000)]  # 10 s of 1 kHz samples, delivered at once
    taken = [t for t in stamps if d.take(t, 0)]
    assert len(taken) == 500  # one per 20 ms: 10 s × 50 Hz
    assert all(b - a >= 20 * MS for a, b in itertools.pairwise(taken))
    assert taken[:3] == [0, 20 * MS, 40 * MS]


def test_decimator_blocks_take_the_same_samples_as_single_messages():
    single = display.Decimator(30.0, wall_factor=1e6)
    blocks = display.Decimator(30.0, wall_factor=1e6)
    singles = [i for i in range(5000) if single.take(i * MS, 0)]
    taken = []
    for k in range(50):  # blocks of 100 samples, 1 ms apart
        taken += [k * 100 + i for i in blocks.take_block(k * 100 * MS, 1e6, 100, 0)]
    assert taken == singles


def _shown_with_envelope(rate: float, series, n: int = 5000) -> list[int]:
    """Sample indices shown of n samples 1 ms apart (blocks of 20), series(i) their field values."""
    d = display.Decimator(rate, wall_factor=1e6)
    env = display.Envelope(len(series(0)))
    shown: list[int] = []
    for k in range(0, n, 20):
        taken = set(d.take_block(k * MS, 1e6, 20, 0))
        for i in range(20):
            values = series(k + i)
            if i not in taken:
                env.offer(values, k + i)
                continue
            shown += env.shown(values)  # type: ignore[arg-type]
            shown.append(k + i)
    return shown


def test_envelope_keeps_a_one_sample_spike_and_adds_nothing_to_a_monotone_stretch():
    spikes = {1234, 2000 + 17, 4099}
    plain = _shown_with_envelope(30.0, lambda i: [1e-9 * i, 1e-8, 0.1])  # ramp, constants
    single = display.Decimator(30.0, wall_factor=1e6)
    assert plain == [i for i in range(5000) if single.take(i * MS, 0)]  # the rate rule alone
    spiky = _shown_with_envelope(30.0, lambda i: [1e-9 * i, 5e-6 if i in spikes else 1e-8, 0.1])
    assert set(spiky) - set(plain) == spikes and set(plain) <= set(spiky)
    assert spiky == sorted(spiky)  # time order
    dips = _shown_with_envelope(30.0, lambda i: [1e-9 * i, 1e-8, -0.2 if i == 3001 else 0.1])
    assert set(dips) - set(plain) == {3001}  # the least value too, of any field


def test_envelope_keeps_the_peaks_of_an_oscillation_faster_than_the_display_rate():
    import math

    def sine(i):
        return [math.sin(2 * math.pi * 37.0 * i * 1e-3)]

    shown = _shown_with_envelope(20.0, sine)
    anchors = _shown_with_envelope(20.0, lambda i: [0.0])
    values = [sine(i)[0] for i in shown]
    assert max(values) > 0.999 and min(values) < -0.999  # the samples every 50 ms alone miss them
    assert len(shown) <= 3 * len(anchors)  # at most a least and a greatest value per interval


def test_decimator_restarts_when_time_goes_back():
    d = display.Decimator(10.0, wall_factor=1e6)
    assert d.take(5_000 * MS, 0)
    assert not d.take(5_050 * MS, 0)
    assert d.take(0, 0)  # a reset: rig time back to 0
    assert not d.take(50 * MS, 0) and d.take(100 * MS, 0)


def test_decimator_wall_ceiling_limits_a_fast_sim_run():
    d = display.Decimator(50.0)  # at most 100 per wall second (burst 50)
    taken = sum(d.take(i * 20 * MS, wall_ns=i * MS) for i in range(2000))  # 50× faster than real time
    # 2 wall seconds: the burst (50) and 100 per second after it, far below the 2000 rig periods
    assert 200 <= taken <= 50 + 2 * 100 + 1


def test_rate_zero_forwards_everything_and_rates_resolve_in_the_namespace():
    d = display.Decimator(0.0)
    assert all(d.take(0, 0) for _ in range(10))
    assert d.take_block(0, 1e6, 7, 0) == list(range(7))
    rates = display.DisplayRates("/rig2", display.parse_rates(["state=20", "/diagnostics=1"], "/rig2"))
    assert rates.rate("/rig2/state") == 20 and rates.rate("/diagnostics") == 1
    assert rates.rate("/rig2/run_config") == 0 and rates.rate("/rig2/wavelet_image") == 10
    assert rates.rate("/rig2/anything_else") == display.DEFAULT_DISPLAY_RATE
    assert rates.rate("/lubrig/wavelet_image") == display.DEFAULT_DISPLAY_RATE  # another rig's


@pytest.mark.parametrize(
    ("item", "says"),
    [
        ("state", "TOPIC=HZ"),
        ("=5", "TOPIC=HZ"),
        ("state=fast", "'fast' is not a number"),
        ("state=-1", ">= 0 Hz"),
        ("state=nan", ">= 0 Hz"),
        ("bad-name=5", "rate topic"),
    ],
)
def test_bad_rates_are_refused_naming_the_value(item, says):
    with pytest.raises(ParameterError, match=re.escape(says)):
        display.parse_rates([item], "/lubrig")


def test_expanded_blocks_have_the_fields_of_their_sample_type():
    for block, (sample, msgtype) in display.EXPANDED_BLOCKS.items():
        assert contract.topic(sample).msgtype == msgtype
        block_fields = _msg_fields(contract.topic(block).msgtype)
        sample_fields = _msg_fields(msgtype)
        per_sample = set(sample_fields) - {"header", "sample_index", "segment"}
        assert per_sample <= set(block_fields), per_sample - set(block_fields)
        assert all(block_fields[f].endswith("[]") for f in per_sample)


# ---------------------------------------------------------------------------------- layouts


def _msg_fields(msgtype: str) -> dict[str, str]:
    """field -> type of a message definition (.msg in this repo, else the installed one)."""
    pkg, _msg, name = msgtype.split("/")
    path = ROOT / pkg / "msg" / f"{name}.msg"
    if not path.is_file():
        path = Path(sys.prefix) / "share" / pkg / "msg" / f"{name}.msg"
    fields = {}
    for raw in path.read_text().splitlines():
        line = raw.split("#", 1)[0].strip()
        parts = line.split()
        if len(parts) < 2 or "=" in line:  # blank, comment or constant
            continue
        fields[parts[1]] = parts[0]
    return fields


def _check_path(path: str) -> None:
    """'<topic>.<field>' (Foxglove) or '<topic>/<field>' names a contract topic and its field."""
    docs = contract.documented_topics()
    topic = next((t for t in sorted(docs, key=len, reverse=True) if path.startswith(t)), None)
    assert topic is not None, f"{path}: no contract topic"
    field = path[len(topic) + 1 :]
    assert field in _msg_fields(docs[topic].msgtype), f"{path}: no field {field!r} in {docs[topic].msgtype}"


def test_shipped_layouts_are_the_generated_ones():
    for kind, relative in layouts.SHIPPED.items():
        shipped = (ROOT / "config" / relative).read_text()
        assert shipped == layouts.LAYOUTS[kind](contract.DEFAULT_NAMESPACE), (
            f"config/{relative} is stale: lubrig view --layout {kind} > config/{relative}"
        )


def _sdk_keys(cls) -> set[str]:
    """The JSON keys Foxglove's SDK writes for a panel config class."""
    required = {f.name: None for f in dataclasses.fields(cls)}
    return set(cls(**required)._to_dict())


def test_foxglove_layout_names_real_topics_fields_and_panel_settings():
    import foxglove.layouts as fl

    layout = layouts.foxglove_layout()
    sdk = {
        "Plot": _sdk_keys(fl.PlotConfig),
        "Image": _sdk_keys(fl.ImageConfig),
        "StateTransitions": _sdk_keys(fl.StateTransitionsConfig),
        "RawMessages": _sdk_keys(fl.RawMessagesConfig),
        "DiagnosticSummary": _sdk_keys(fl.DiagnosticsSummaryConfig),
    }
    series_keys = _sdk_keys(fl.PlotSeries) | _sdk_keys(fl.StateTransitionsSeries)
    image_keys = _sdk_keys(fl.ImageModeConfig)
    seen = set()

    def leaves(node):
        if isinstance(node, str):
            yield node
        else:
            yield from leaves(node["first"])
            yield from leaves(node["second"])

    panels = list(leaves(layout["layout"]))
    assert sorted(panels) == sorted(layout["configById"])  # every panel placed once
    for pid, config in layout["configById"].items():
        kind = pid.split("!")[0]
        assert set(config) - {"foxglovePanelTitle"} <= sdk[kind], (pid, set(config) - sdk[kind])
        for series in config.get("paths", []):
            assert set(series) <= series_keys, series
            _check_path(series["value"])
            seen.add(series["value"])
        if "xAxisPath" in config:
            _check_path(config["xAxisPath"]["value"])
        if "imageMode" in config:
            assert set(config["imageMode"]) <= image_keys
            assert contract.documented_topics()[config["imageMode"]["imageTopic"]].msgtype == (
                "sensor_msgs/msg/Image"
            )
        if "topicPath" in config:
            assert config["topicPath"] in contract.documented_topics()
    # what the issue asks for: x, ẋ, μ, v_band, v_rel; the wavelet image; stability; diagnostics
    for field in ("displacement", "velocity", "friction_coefficient", "band_velocity", "relative_velocity"):
        assert f"/lubrig/state.{field}" in seen
    assert "/lubrig/stability.linear_zone" in seen and "Image!wavelet" in panels
    assert layout["configById"]["DiagnosticSummary!rig"]["topicToRender"] == "/diagnostics"


def test_plotjuggler_layout_names_real_topics_and_fields():
    root = ET.fromstring((ROOT / "config" / layouts.SHIPPED["plotjuggler"]).read_text())
    curves = [c.get("name") for c in root.iter("curve")]
    assert curves
    for curve in curves:
        _check_path(curve)
    for splitter in root.iter("DockSplitter"):
        assert int(splitter.get("count")) == len(list(splitter)) == len(splitter.get("sizes").split(";"))
    assert {"/lubrig/state/displacement", "/lubrig/state/relative_velocity"} <= set(curves)


def test_layouts_follow_the_namespace():
    assert "/rig2/state.displacement" in layouts.foxglove_json("/rig2")
    assert "/lubrig/" not in layouts.foxglove_json("/rig2")
    assert "/rig2/state/displacement" in layouts.plotjuggler_xml("/rig2")
