"""`lubrig sweep`: points equal direct core runs, resume after SIGKILL, failures, spec validation."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
import yaml
from scipy.stats import qmc

from lubrig_ros.app.analysis.policy import analyze_displacement
from lubrig_ros.cli.main import main
from lubrig_ros.core.presets import from_mapping, load_case
from lubrig_ros.core.run import simulate, summarize
from lubrig_ros.sweep import load_spec, parse_spec, run_sweep
from lubrig_ros.sweep.point import SUMMARY_KEYS

ROOT = Path(__file__).resolve().parents[1]
LUBRIG = Path(sys.executable).with_name("lubrig")
#: Columns that legitimately differ between two computations of the same point.
TIMING = ("simulate_seconds", "point_seconds", "worker", "started_at", "finished_at")

CYCLE = {
    "rig": {"convention": "paper"},
    "band": {
        "kind": "cycle",
        "low_velocity": 1e-7,
        "high_velocity": 1e-6,
        "plateau_time": 0.01,
        "ramp_time": 0.2,
    },
}


def write_spec(path, data):
    path.write_text(yaml.safe_dump(data))
    return path


def comparable(table):
    return table.drop_columns(list(TIMING))


@pytest.mark.slow
def test_points_equal_direct_core_runs(tmp_path):
    spec = {
        "name": "equal",
        "base": {**CYCLE, "simulation": {"duration": 1.0}},
        "axes": [
            {"parameter": "band.ramp_time", "values": [0.02, 0.2]},
            {"parameter": "rig.damping_ratio", "linspace": {"start": 0.0, "stop": 0.05, "num": 2}},
            {"parameter": "rig.friction.contact_area", "values": [2.83e-10]},
        ],
    }
    result = run_sweep(parse_spec(spec), tmp_path / "out", workers=2, progress=None, figures=False)
    assert (result.total, result.computed, result.failed) == (4, 4, 0)
    rows = pq.read_table(result.table).to_pylist()
    assert [r["index"] for r in rows] == [0, 1, 2, 3]
    for row in rows:
        # the same run built independently of the sweep code: the study rig, the values set by hand
        config = from_mapping(
            {
                "rig": {
                    "convention": "paper",
                    "damping_ratio": row["rig.damping_ratio"],
                    "friction": {"contact_area": row["rig.friction.contact_area"]},
                },
                "band": {**CYCLE["band"], "ramp_time": row["band.ramp_time"]},
                "simulation": {"duration": 1.0},
            }
        )
        trajectory = simulate(config)
        summary = summarize(trajectory, config)
        for key in SUMMARY_KEYS:
            assert row[key] == summary[key], key
        assert row["mu_range"] == summary["mu_max"] - summary["mu_min"]
        # the one wavelet policy (app/analysis/policy.py: second half, rate/4 … 3/window) on the direct run
        components = analyze_displacement(
            trajectory.time, trajectory.displacement, 1000.0, config.band.fundamental_hz
        ).components[:3]
        assert row["wavelet_frequencies_hz"] == [c.frequency_hz for c in components]
        assert row["frequency_ratio"] == components[0].frequency_hz / summary["band_fundamental_hz"]
        assert row["status"] == "ok" and row["error"] is None
    assert {r["rig.damping_ratio"] for r in rows} == {0.0, 0.05}
    # and `lubrig simulate` (the real script) of the last point writes the same summary
    row = rows[-1]
    run_dir = tmp_path / "simulate"
    subprocess.run(
        [
            str(LUBRIG),
            "simulate",
            "--cycle",
            "1e-7",
            "1e-6",
            "0.01",
            repr(row["band.ramp_time"]),
            "--convention",
            "paper",
            "--zeta",
            repr(row["rig.damping_ratio"]),
            "--duration",
            "1",
            "--out",
            str(run_dir),
        ],
        check=True,
        capture_output=True,
        timeout=120,
    )
    summary = json.loads((run_dir / "summary.json").read_text())
    for key in SUMMARY_KEYS:
        assert row[key] == summary[key], key


def test_shipped_sweeps_hold_the_study_cases():
    spec = load_spec(ROOT / "config/sweeps/ramp_plateau.yaml")
    assert len(spec.points) == 42
    configs = {(p.values["band.ramp_time"], p.values["band.plateau_time"]): p.config for p in spec.points}
    for case, key in {
        4: (0.2, 0.01),
        5: (0.2, 0.1),
        6: (0.2, 1.0),
        7: (0.02, 0.08),
        8: (0.01, 0.04),
        10: (0.02, 0.01),
    }.items():
        expected = load_case(case).to_dict()
        expected.pop("lubrig_ros_version")
        got = dict(configs[key])
        assert got.pop("name").startswith("ramp_plateau#")
        expected.pop("name")
        assert got == {**expected, "description": got["description"]}, case
    velocity = load_spec(ROOT / "config/sweeps/velocity_damping.yaml")
    assert len(velocity.points) == 143
    assert {p.config["rig"]["convention"] for p in velocity.points} == {"physical"}
    v = sorted({p.values["band.velocity"] for p in velocity.points})
    assert v[0] == pytest.approx(1e-9) and v[-1] == pytest.approx(1e-6)


@pytest.mark.slow
def test_kill_mid_sweep_then_resume_computes_each_point_once(tmp_path):
    spec_path = write_spec(
        tmp_path / "spec.yaml",
        {
            "name": "killme",
            "base": {**CYCLE, "simulation": {"duration": 10.0}},
            "axes": [{"parameter": "band.plateau_time", "linspace": {"start": 0.01, "stop": 0.5, "num": 12}}],
        },
    )
    out = tmp_path / "out"
    command = [str(LUBRIG), "sweep", str(spec_path), "--out", str(out), "--workers", "1", "--no-figures"]
    proc = subprocess.Popen(
        command, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    try:
        deadline = time.monotonic() + 120
        while len(list((out / "points").glob("*.json"))) < 3:
            assert proc.poll() is None, "sweep ended before it could be killed"
            assert time.monotonic() < deadline, "no points finished in time"
            time.sleep(0.02)
        os.killpg(proc.pid, signal.SIGKILL)  # the driver and its worker processes, no cleanup
    finally:
        proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    before = {p.name: p.read_bytes() for p in (out / "points").glob("*.json")}
    assert 3 <= len(before) < 12
    assert not (out / "results.parquet").exists()

    resumed = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    assert f"({len(before)} resumed, {12 - len(before)} computed, 0 failed)" in resumed.stdout
    after = {p.name: p.read_bytes() for p in (out / "points").glob("*.json")}
    assert len(after) == 12
    assert all(after[name] == data for name, data in before.items())  # finished points untouched

    journal = [json.loads(line) for line in (out / "journal.jsonl").read_text().splitlines()]
    starts = [e["run"] for e in journal if e["event"] == "start"]
    assert len(starts) == 2
    written = [e for e in journal if e["event"] == "point"]
    first = {e["point_id"] for e in written if e["run"] == starts[0]}
    second = {e["point_id"] for e in written if e["run"] == starts[1]}
    assert not first & second
    assert len(written) == len({e["point_id"] for e in written})  # no point computed twice
    # Every point is journalled once, except that a SIGKILL can land between a point's file and its
    # journal line: that point is then resumed from its file (never recomputed) and has no line.
    resumed_ids = {json.loads(data)["point_id"] for data in before.values()}
    assert not second & resumed_ids
    assert first | second | resumed_ids == {json.loads(d)["point_id"] for d in after.values()}
    assert len(first - resumed_ids) == 0 and len(resumed_ids - first) <= 1
    assert [e["resumed"] for e in journal if e["event"] == "start"] == [0, len(before)]

    reference = run_sweep(
        load_spec(spec_path), tmp_path / "ref", scheduler="serial", progress=None, figures=False
    )
    table, expected = pq.read_table(out / "results.parquet"), pq.read_table(reference.table)
    assert comparable(table).equals(comparable(expected))
    assert table.schema.metadata[b"lubrig_sweep_spec"] == expected.schema.metadata[b"lubrig_sweep_spec"]


def test_failed_point_is_recorded_and_does_not_stop_the_others(tmp_path, capsys):
    spec_path = write_spec(
        tmp_path / "spec.yaml",
        {
            "name": "fails",
            "base": {"band": {"kind": "constant", "velocity": 1e-7}, "simulation": {"duration": 1.0}},
            "axes": [{"parameter": "band.velocity", "values": [1e-7, 0.0, 2e-7]}],
        },
    )
    out = tmp_path / "out"
    assert main(["sweep", str(spec_path), "--out", str(out), "--scheduler", "serial"]) == 0
    rows = pq.read_table(out / "results.parquet").to_pylist()
    assert [r["status"] for r in rows] == ["ok", "error", "ok"]
    assert "band_velocity=0.0" in rows[1]["error"] and rows[1]["x_peak_to_peak"] is None
    assert rows[2]["x_peak_to_peak"] is not None and rows[2]["linear_zone"] == 3
    for name in ("amplitude", "mu_range", "stick_fraction", "frequency", "linear"):
        assert (out / f"map_{name}.png").read_bytes()[:4] == b"\x89PNG"
    assert "1 failed" in capsys.readouterr().out
    # rerun: nothing recomputed; --retry-failed: only the failed point again
    assert main(["sweep", str(spec_path), "--out", str(out), "--scheduler", "serial"]) == 0
    assert "(3 resumed, 0 computed, 0 failed)" in capsys.readouterr().out
    assert main(["sweep", str(spec_path), "--out", str(out), "--scheduler", "serial", "--retry-failed"]) == 0
    assert "(2 resumed, 1 computed, 1 failed)" in capsys.readouterr().out


BAD_SPECS = {
    "unknown parameter": ({"parameter": "rig.dampin_ratio", "values": [0.1]}, "rig.dampin_ratio"),
    "unknown band parameter": ({"parameter": "band.velocity", "values": [1e-7]}, "band.velocity"),
    "empty values": ({"parameter": "band.ramp_time", "values": []}, "values=[]"),
    "empty linspace": (
        {"parameter": "band.ramp_time", "linspace": {"start": 0.1, "stop": 0.2, "num": 0}},
        "num=0",
    ),
    "negative damping": (
        {"parameter": "rig.damping_ratio", "linspace": {"start": -0.1, "stop": 0.1, "num": 3}},
        "damping_ratio=-0.1 must be >= 0",
    ),
    "logspace exponents": (
        {"parameter": "band.ramp_time", "logspace": {"start": -2, "stop": 0, "num": 3}},
        "not exponents",
    ),
    "grid too large": (  # counted from num: 10**12 values are never built
        {"parameter": "band.ramp_time", "linspace": {"start": 0.1, "stop": 0.2, "num": 10**12}},
        "the grid has 1000000000000 points (1000000000000); at most 1000000 are allowed",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD_SPECS))
def test_bad_spec_fails_before_any_work(tmp_path, capsys, case):
    axis, needle = BAD_SPECS[case]
    spec_path = write_spec(tmp_path / "spec.yaml", {"base": CYCLE, "axes": [axis]})
    out = tmp_path / "out"
    assert main(["sweep", str(spec_path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("lubrig sweep: error: ") and needle in err and err.count("\n") == 1
    assert not out.exists()


def test_duplicate_axis_and_bad_options_fail_before_any_work(tmp_path, capsys):
    axis = {"parameter": "rig.damping_ratio", "values": [0.01]}
    spec_path = write_spec(tmp_path / "spec.yaml", {"base": CYCLE, "axes": [axis, dict(axis)]})
    out = tmp_path / "out"
    assert main(["sweep", str(spec_path), "--out", str(out)]) == 2
    assert "duplicate axis 'rig.damping_ratio'" in capsys.readouterr().err
    good = write_spec(tmp_path / "good.yaml", {"base": CYCLE, "axes": [axis]})
    for options, needle in ((["--workers", "0"], "--workers 0"), (["--scheduler", "nowhere"], "'nowhere'")):
        assert main(["sweep", str(good), "--out", str(out), *options]) == 2
        assert needle in capsys.readouterr().err
    sampled = {
        "base": CYCLE,
        "design": "lhs",
        "samples": 4,
        "seed": 1,
        "axes": [{"parameter": "rig.damping_ratio", "uniform": {"low": 0.1, "high": 0.1}}],
    }
    assert main(["sweep", str(write_spec(tmp_path / "lhs.yaml", sampled)), "--out", str(out)]) == 2
    assert "empty range" in capsys.readouterr().err
    assert not out.exists()


def test_directory_of_another_sweep_is_refused(tmp_path, capsys):
    base = {"base": {**CYCLE, "simulation": {"duration": 0.5}}, "wavelet": False}
    one = write_spec(
        tmp_path / "one.yaml", {**base, "axes": [{"parameter": "rig.damping_ratio", "values": [0.01]}]}
    )
    two = write_spec(
        tmp_path / "two.yaml", {**base, "axes": [{"parameter": "rig.damping_ratio", "values": [0.02]}]}
    )
    out = tmp_path / "out"
    assert main(["sweep", str(one), "--out", str(out), "--scheduler", "serial", "--no-figures"]) == 0
    listing = sorted(p.name for p in out.rglob("*"))
    assert main(["sweep", str(two), "--out", str(out), "--scheduler", "serial"]) == 2
    assert "holds a different sweep" in capsys.readouterr().err
    assert sorted(p.name for p in out.rglob("*")) == listing
    # the stored spec is the sweep: rerunning it from DIR resumes, it does not recompute
    assert (
        main(["sweep", str(out / "spec.yaml"), "--out", str(out), "--scheduler", "serial", "--no-figures"])
        == 0
    )
    assert "(1 resumed, 0 computed" in capsys.readouterr().out


def test_latin_hypercube_and_random_designs(tmp_path):
    axes = [
        {"parameter": "rig.damping_ratio", "uniform": {"low": 0.0, "high": 0.2}},
        {"parameter": "band.ramp_time", "loguniform": {"low": 0.01, "high": 1.0}},
    ]
    lhs = {"base": CYCLE, "design": "lhs", "samples": 8, "seed": 3, "axes": axes}
    points = parse_spec(lhs).points
    zeta = np.array([p.values["rig.damping_ratio"] for p in points])
    ramp = np.array([p.values["band.ramp_time"] for p in points])
    # one sample per stratum on each axis (linear strata for uniform, log strata for loguniform)
    assert sorted(np.floor(zeta / 0.2 * 8).astype(int)) == list(range(8))
    assert sorted(np.floor((np.log(ramp) - np.log(0.01)) / np.log(100) * 8).astype(int)) == list(range(8))
    unit = qmc.LatinHypercube(d=2, seed=np.random.default_rng(3)).random(8)
    assert np.array_equal(zeta, 0.2 * unit[:, 0])
    assert [p.values for p in parse_spec(lhs).points] == [p.values for p in points]  # seeded
    other = parse_spec({**lhs, "seed": 4}).points
    assert [p.values for p in other] != [p.values for p in points]
    rand = parse_spec({**lhs, "design": "random"}).points
    assert len(rand) == 8 and all(0.01 <= p.values["band.ramp_time"] <= 1.0 for p in rand)
    spec = parse_spec({**lhs, "samples": 3, "base": {**CYCLE, "simulation": {"duration": 0.5}}})
    result = run_sweep(spec, tmp_path / "out", scheduler="serial", progress=None)
    assert result.failed == 0 and len(result.figures) == 5
    table = pq.read_table(result.table)
    assert yaml.safe_load(table.schema.metadata[b"lubrig_sweep_spec"]) == spec.source
    assert load_spec(tmp_path / "out" / "spec.yaml").fingerprint == spec.fingerprint


def test_progress_reports_time_left(tmp_path):
    import io

    stream = io.StringIO()
    spec = parse_spec(
        {
            "base": {**CYCLE, "simulation": {"duration": 0.5}},
            "wavelet": False,
            "axes": [{"parameter": "rig.damping_ratio", "values": [0.01, 0.02, 0.03]}],
        }
    )
    run_sweep(spec, tmp_path / "out", scheduler="serial", progress=stream, figures=False)
    lines = stream.getvalue().splitlines()
    assert lines and lines[-1].startswith("sweep sweep: 3/3 points (0 resumed, 0 failed)")
    assert all("left" in line for line in lines)


def test_steady_sliding_has_no_dominant_frequency():
    spec = parse_spec(
        {
            "base": {
                "band": {"kind": "constant", "velocity": 1e-6},
                "rig": {"damping_ratio": 0.2},
                "simulation": {"duration": 20.0},
            },
            "axes": [{"parameter": "band.velocity", "values": [1e-6]}],
        }
    )
    from lubrig_ros.core.integrator import RigIntegrator
    from lubrig_ros.sweep import run_point
    from lubrig_ros.sweep.point import STEADY_RELATIVE_PTP

    record = run_point(spec.points[0])
    settled = RigIntegrator(from_mapping(spec.points[0].config).rig, 1e-6).equilibrium_displacement
    # settled to rounding: the stage solve stops within its tolerance, not on an exact fixed point
    assert record["status"] == "ok" and record["x_peak_to_peak"] <= STEADY_RELATIVE_PTP * settled
    assert record["dominant_frequency_hz"] is None and record["wavelet_frequency_hz"] is None
    assert "constant in the window" in record["wavelet_error"] and record["linear_stable"] is True


@pytest.mark.parametrize(
    "extra",
    [[], [{"parameter": "band.ramp_time", "values": [0.2]}]],
    ids=["grid map", "scatter over more axes"],
)
def test_text_axis_maps_to_ticks(tmp_path, capsys, extra):
    """A text-valued axis (rig.convention) in a 2-axis grid or scatter: its values become ticks."""
    spec_path = write_spec(
        tmp_path / "spec.yaml",
        {
            "base": {**CYCLE, "simulation": {"duration": 0.5}},
            "wavelet": False,
            "axes": [
                {"parameter": "rig.convention", "values": ["physical", "paper"]},
                {"parameter": "rig.damping_ratio", "values": [0.01, 0.1]},
                *extra,
            ],
        },
    )
    out = tmp_path / "out"
    assert main(["sweep", str(spec_path), "--out", str(out), "--scheduler", "serial"]) == 0, (
        capsys.readouterr().err
    )
    for name in ("amplitude", "mu_range", "stick_fraction", "frequency", "linear"):
        assert (out / f"map_{name}.png").read_bytes()[:4] == b"\x89PNG"
    from lubrig_ros.figures.sweep import map_figure

    table = pq.read_table(out / "results.parquet")
    axes = json.loads(table.schema.metadata[b"lubrig_sweep_axes"])
    fig = map_figure(table.to_pydict(), axes, "x_peak_to_peak", "amplitude", True, "t")
    ax = fig.axes[0]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["physical", "paper"]
    assert ax.get_xlabel() == "rig.convention"


@pytest.mark.parametrize(
    ("band", "linear_velocity"),
    [
        ({"kind": "table", "times": [0.0, 0.2, 1.0], "velocities": [0.0, 2e-7, 1e-6]}, 2e-7),
        ({"kind": "table", "times": [0.0, 1.0], "velocities": [0.0, 0.0]}, None),
        ({"kind": "sine", "mean_velocity": 0.0, "amplitude": 1e-6, "frequency": 2.0}, None),
    ],
    ids=["table from rest", "table at rest", "sine mean 0"],
)
def test_band_from_rest_keeps_the_point(band, linear_velocity):
    """A table starting from rest (or a sine with mean ≤ 0) is judged at its lowest velocity > 0,
    or has null linear columns: the point, whose simulation succeeded, is not an error."""
    from lubrig_ros.sweep import run_point

    spec = parse_spec(
        {
            "base": {"band": band, "simulation": {"duration": 1.0}},
            "wavelet": False,
            "axes": [{"parameter": "rig.damping_ratio", "values": [0.05]}],
        }
    )
    record = run_point(spec.points[0])
    assert record["status"] == "ok", record["error"]
    assert record["x_peak_to_peak"] is not None
    assert record["linear_velocity_m_s"] == linear_velocity
    assert (record["linear_stable"] is None) == (linear_velocity is None)
