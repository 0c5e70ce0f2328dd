"""The realtime timing of a recorded run in `lubrig report`: lateness, declared gaps, the figure.

Bags are written without ROS: RigStateBlock messages serialized by rosbags (the project's type
store, lubrig_interfaces' .msg files) and written with BagWriter (the recorder's writer). A
realtime bag is stamped like the realtime plant stamps its blocks: the wall-clock due time of
the first sample (about 1.8e9 s), with per-sample lateness and the skipped count of a block after
samples the plant skipped.
"""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from lubrig_testkit.figures import overlapping_texts, texts_outside
from matplotlib.image import imread

import lubrig_ros.bag.layout as layout
from lubrig_ros.app.plant.output import BLOCK_FIELDS, BeltTravel, trajectory_columns
from lubrig_ros.app.recording.lateness import DEFAULT_MAX_LAG, rig_timing
from lubrig_ros.bag import BagWriter, read_arrays
from lubrig_ros.bag.layout import interface_definitions, typestore
from lubrig_ros.bag.writer import serialize_string
from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import simulate
from lubrig_ros.figures import style
from lubrig_ros.figures.timing import timing_figure
from lubrig_ros.report import trajectory_from_bag, write_report
from lubrig_ros.report.frombag import read_run, recording_summary

NS = "/lubrig"
BLOCK = "lubrig_interfaces/msg/RigStateBlock"
FIELDS = BLOCK_FIELDS
START_NS = 1_800_000_000_123_456_789  # wall clock of the segment's start (sample 0 due)
SKIPS = ((500, 30), (1200, 10))  # (first skipped index, count): declared gaps
DURATION = 2.0


def _lateness(n: int) -> np.ndarray:
    """Lateness (s) per recorded sample: 0.1 ms mostly, 40 at 2 ms, 8 at 15 ms, one at 18 ms."""
    late = np.full(n, 1e-4)
    late[100:140] = 2e-3
    late[900:908] = 1.5e-2
    late[1500] = 1.8e-2
    return late


def _ns_stamp(store: Any, ns: int) -> Any:
    time_cls, header_cls = store.types["builtin_interfaces/msg/Time"], store.types["std_msgs/msg/Header"]
    return header_cls(stamp=time_cls(sec=ns // 10**9, nanosec=ns % 10**9), frame_id="")


def _diagnostics(store: Any, max_lag: float) -> bytes:
    """A /diagnostics message with the plant's timing status stating its max_lag (lag_bound_s)."""
    kv, status_cls, array_cls = (
        store.types[f"diagnostic_msgs/msg/{n}"] for n in ("KeyValue", "DiagnosticStatus", "DiagnosticArray")
    )
    status = status_cls(
        level=0,
        name=f"{NS}/plant: timing",
        message="ok",
        hardware_id="lubrig",
        values=[kv(key="mode", value="realtime"), kv(key="lag_bound_s", value=f"{max_lag:g}")],
    )
    msg = array_cls(header=_ns_stamp(store, START_NS), status=[status])
    return bytes(store.serialize_cdr(msg, "diagnostic_msgs/msg/DiagnosticArray"))


def _write(
    path: Path, realtime: bool, max_lag: float | None = None, store: Any = None, block: int = 100
) -> dict[str, Any]:
    """Case 1 for DURATION s as state blocks; realtime: wall-clock stamps, lateness, skips.

    Returns what was put in: the config, trajectory, recorded indices and their lateness.
    """
    store = store if store is not None else typestore()
    config = load_case(1).with_overrides(duration=DURATION)
    traj = simulate(config)
    n, period = len(traj), 1.0 / config.sample_rate
    travel = BeltTravel().add_many(traj.time, traj.band_velocity)
    values = trajectory_columns(traj, travel, config.rig.friction.normal_force)
    skipped = {first + count: count for first, count in SKIPS} if realtime else {}
    kept = np.ones(n, bool)
    for first, count in SKIPS if realtime else ():
        kept[first : first + count] = False
    index = np.flatnonzero(kept)
    late = _lateness(index.size)
    late_of = dict(zip(index.tolist(), late.tolist(), strict=True))
    # blocks: contiguous recorded samples, cut at every skip and every `block` samples
    cuts = [0, *[k for k in range(1, index.size) if index[k] != index[k - 1] + 1], index.size]
    blocks = [index[a:b][i : i + block] for a, b in itertools.pairwise(cuts) for i in range(0, b - a, block)]
    cls = store.types[BLOCK]
    writer = BagWriter(path, run_config=config.to_yaml())
    writer.write(f"{NS}/run_config", "std_msgs/msg/String", 0, serialize_string(config.to_yaml()))
    if max_lag is not None:
        writer.write(
            "/diagnostics", "diagnostic_msgs/msg/DiagnosticArray", START_NS, _diagnostics(store, max_lag)
        )
    has_timing = "lateness" in dict(store.fielddefs[BLOCK][1])
    for ks in blocks:
        k0 = int(ks[0])
        due_ns = START_NS + k0 * 1_000_000 if realtime else round(k0 * period * 1e9)
        fields = {name: values[name][ks] for name in FIELDS}
        if has_timing:
            fields["lateness"] = np.array([late_of[k] for k in ks.tolist()]) if realtime else np.zeros(0)
            fields["skipped"] = skipped.get(k0, 0)
        msg = cls(
            header=_ns_stamp(store, due_ns), sample_period=period, first_sample_index=k0, segment=0, **fields
        )
        log_ns = due_ns + (round(late_of[k0] * 1e9) if realtime else 0)
        writer.write(f"{NS}/state_block", BLOCK, log_ns, bytes(store.serialize_cdr(msg, BLOCK)))
    writer.close()
    return {"config": config, "traj": traj, "index": index, "lateness": late}


@pytest.fixture(scope="module")
def realtime(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    bag = tmp_path_factory.mktemp("rt") / "bag"
    return bag, _write(bag, realtime=True)


def _p(values: np.ndarray, q: float) -> float:
    """The q-quantile as the smallest value at least q of the samples do not exceed."""
    ordered = np.sort(values)
    return float(ordered[math.ceil(q * ordered.size) - 1])


def test_reader_flattens_lateness_and_skipped_per_sample(realtime: tuple) -> None:
    bag, put = realtime
    state = read_arrays(bag, [f"{NS}/state_block"])[f"{NS}/state_block"]
    np.testing.assert_array_equal(state["sample_index"], put["index"])
    np.testing.assert_array_equal(state["lateness"], put["lateness"])
    declared = {int(k): int(s) for k, s in zip(state["sample_index"], state["skipped"], strict=True) if s}
    assert declared == {first + count: count for first, count in SKIPS}


def test_realtime_time_axis_is_rig_time_of_the_segment(realtime: tuple) -> None:
    bag, put = realtime
    config, rebuilt = trajectory_from_bag(bag)
    np.testing.assert_array_equal(rebuilt.time, put["index"] / config.sample_rate)  # due − start
    assert rebuilt.time[0] == 0.0
    np.testing.assert_array_equal(rebuilt.displacement, put["traj"].displacement[put["index"]])
    stream = recording_summary(bag)["streams"][f"{NS}/state_block"]
    assert stream["gaps"] == [] and stream["complete"] and stream["skipped"] == 40  # declared, not lost
    declared = stream["declared_gaps"]
    assert [(g["first_index"], g["count"]) for g in declared] == list(SKIPS)
    assert [g["rig_time_s"] for g in declared] == pytest.approx([f / 1000 for f, _ in SKIPS], abs=1e-9)


def test_timing_section_equals_what_was_recorded(realtime: tuple, tmp_path: Path) -> None:
    bag, put = realtime
    late = put["lateness"]
    page = write_report(bag, tmp_path / "report")
    timing = json.loads((tmp_path / "report" / "summary.json").read_text())["timing"]
    assert timing["samples"] == late.size == len(put["traj"]) - sum(c for _f, c in SKIPS)
    assert timing["lateness_p50_s"] == _p(late, 0.50) == 1e-4
    assert timing["lateness_p99_s"] == _p(late, 0.99) == 2e-3
    assert timing["lateness_max_s"] == 1.8e-2
    assert timing["late_samples"] == 49 and timing["late_share"] == pytest.approx(49 / late.size)
    assert timing["skipped_samples"] == 40
    assert [(g["first_index"], g["count"]) for g in timing["gaps"]] == list(SKIPS)
    assert [g["rig_time_s"] for g in timing["gaps"]] == pytest.approx([0.5, 1.2], abs=1e-12)
    assert (timing["max_lag_s"], timing["max_lag_source"]) == (DEFAULT_MAX_LAG, "default")
    assert timing["figure"] == "timing.png"
    image = imread(tmp_path / "report" / "timing.png")
    assert image.shape[0] > 600 and float(np.std(image[..., :3])) > 0.02
    text = page.read_text()
    assert "## Realtime timing" in text and "![realtime timing](timing.png)" in text
    assert "| lateness p50 / p99 / max | 0.1 ms / 2 ms / 18 ms |" in text
    assert "- declared gap: 30 samples skipped from index 500 of segment 0 at rig time 0.500000 s" in text
    assert "- declared gap: 10 samples skipped from index 1200 of segment 0 at rig time 1.200000 s" in text
    assert "40 skipped by the plant: complete" in text and "**gap**" not in text
    assert 'alt="realtime timing"' in (tmp_path / "report" / "report.html").read_text()


def test_stated_max_lag_is_taken_from_the_plant_timing_status(tmp_path: Path) -> None:
    _write(tmp_path / "bag", realtime=True, max_lag=0.05)
    timing = read_run(tmp_path / "bag").timing
    assert timing is not None and (timing.max_lag, timing.max_lag_stated) == (0.05, True)
    fig = timing_figure(timing, "t")
    assert any(np.allclose(line.get_ydata(), 50.0) for line in fig.axes[1].get_lines())  # ms
    assert timing.summary()["max_lag_source"] == "recording"


def test_sim_bag_gets_no_timing_section(tmp_path: Path) -> None:
    put = _write(tmp_path / "bag", realtime=False)
    run = read_run(tmp_path / "bag")
    assert run.timing is None
    np.testing.assert_allclose(run.trajectory.time, put["traj"].time, rtol=0, atol=1e-12)
    page = write_report(tmp_path / "bag", tmp_path / "report")
    assert "timing" not in json.loads((tmp_path / "report" / "summary.json").read_text())
    assert not (tmp_path / "report" / "timing.png").exists()
    assert "Realtime timing" not in page.read_text()


def test_bag_recorded_before_the_timing_fields_still_reads(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """RigStateBlock without lateness/skipped (its older definition): read, no timing."""

    def older(text: str) -> str:
        return "\n".join(
            line
            for line in text.splitlines()
            if line.split("#")[0].split()[1:2] not in (["lateness"], ["skipped"])
        )

    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_KILTED)
    for name, text in interface_definitions().items():
        store.register(get_types_from_msg(older(text) if name == BLOCK else text, name))
    assert "lateness" not in dict(store.fielddefs[BLOCK][1])
    with monkeypatch.context() as patch:
        patch.setattr(layout, "_TYPESTORE", store)  # the writer stores the older schema and hash
        put = _write(tmp_path / "bag", realtime=False, store=store)
    run = read_run(tmp_path / "bag")
    assert run.timing is None
    np.testing.assert_array_equal(run.trajectory.displacement, put["traj"].displacement)
    state = read_arrays(tmp_path / "bag", [f"{NS}/state_block"])[f"{NS}/state_block"]
    assert np.isnan(state["lateness"]).all() and not state["skipped"].any()


def test_timing_figure_reads_with_many_gaps_and_with_none() -> None:
    """Texts never overlap nor leave the figure; every gap drawn, at most the largest labelled."""
    period, n = 1e-3, 20_000
    rng = np.random.default_rng(3)
    index = np.arange(n)
    late = rng.lognormal(np.log(1e-4), 0.5, n)
    skipped = np.zeros(n, np.int64)
    skipped[rng.choice(np.arange(1, n), 40, replace=False)] = rng.integers(1, 80, 40)
    for skip in (skipped, np.zeros(n, np.int64)):
        timing = rig_timing(0, period, index, late, skip)
        assert timing is not None
        fig = timing_figure(timing, style.run_title("case01", "paper", "Realtime timing"))
        assert overlapping_texts(fig) == []
        assert texts_outside(fig) == []
        stems = [c for c in fig.axes[2].collections if c.get_segments()]
        assert sum(len(c.get_segments()) for c in stems) == int(np.count_nonzero(skip))
    assert rig_timing(0, period, index, np.full(n, np.nan), skipped) is None
