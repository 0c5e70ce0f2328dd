"""Bad invocations of every `lubrig` subcommand, each a real process.

Each must end with exit status 2 and one line on stderr that names the bad value, no traceback,
before any work starts. The per-process timeout (10 s) detects a hang or an unbounded run; it is
not a rate assertion. The processes run a few at a time (each one is mostly Python start-up).
"""

from __future__ import annotations

import os
import signal
import struct
import subprocess
import sys
import textwrap
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from lubrig_ros.bag import BagWriter

TIMEOUT_S = 10.0
PARALLEL = 3
LUBRIG = [sys.executable, "-m", "lubrig_ros.cli.main"]


def _files(root: Path) -> dict[str, Path]:
    """Inputs the invocations refer to: bad configs, a bad profile, sweep specs and a bag."""
    files = {}

    def write(name: str, text: str) -> None:
        files[name] = root / name
        files[name].write_text(textwrap.dedent(text))

    write("yield.yaml", "rig: {friction: {yield_distance: 1.0e+308}}\n")
    write("area.yaml", "rig: {friction: {contact_area: 1.0e+308}}\n")
    write("floor.yaml", "rig: {friction: {thermal_break_time: 5.0e-324}}\n")
    write("coupling.yaml", "rig: {velocity_coupling: 1.0e+308}\n")
    write("perturb.yaml", "simulation: {initial_perturbation: -1.0e+308}\n")
    write("thick.yaml", "rig: {friction: {interpenetration_thickness: 1.0e-8}}\n")
    write("sine.yaml", "band: {kind: sine, mean_velocity: 0.008, amplitude: 0.005}\n")
    write("nyquist.yaml", "band: {kind: sine, frequency: 900.0}\n")
    write("ramp.yaml", "band: {kind: cycle, ramp_time: 0.0}\n")
    write("stribeck.yaml", "rig: {friction: {law: stribeck, static_coefficient: 1.0e+308}}\n")
    write("samples.yaml", "simulation: {duration: 1.0e+6, sample_rate: 1.0e+5}\n")
    write("unknown.yaml", "rig: {masss: 1.0}\n")
    write("notyaml.yaml", "rig: [unclosed\n")
    write("fast.csv", "time_s,band_velocity_m_s\n0,0\n1,1.0\n")
    write("text.csv", "time_s,band_velocity_m_s\n0,0\n1,abc\n")
    rows = "".join(f"{k / 1000},1e-7,{1e-8 if k != 7 else 'inf'}\n" for k in range(40))
    write("infinite.csv", "time,band_velocity,displacement\n" + rows)
    write(
        "grid.yaml",
        """\
        name: big
        base: {simulation: {duration: 1.0e+5}}
        axes:
          - parameter: band.velocity
            logspace: {start: 1.0e-9, stop: 1.0e-6, num: 200}
        """,
    )
    write(  # refused from the stated sizes: the axis is never built (it would not fit in memory)
        "huge.yaml",
        """\
        name: huge
        axes:
          - parameter: band.velocity
            linspace: {start: 1.0e-9, stop: 1.0e-6, num: 1000000000000}
        """,
    )
    write(
        "wide.yaml",
        """\
        name: wide
        axes:
          - parameter: rig.mass
            linspace: {start: 0.1, stop: 1.0, num: 1001}
          - parameter: rig.damping_ratio
            logspace: {start: 0.001, stop: 0.1, num: 1000}
        """,
    )
    write(
        "badpoint.yaml",
        """\
        name: bad
        axes:
          - parameter: rig.mass
            values: [0.1, 1.0e+308]
        """,
    )
    bag = root / "bag"
    writer = BagWriter(bag, run_config="a: 1\n")
    for k in range(100):  # 1 s of one topic
        writer.write(
            "/lubrig/displacement",
            "std_msgs/msg/Float64",
            10**9 + k * 10**7,
            b"\x00\x01\x00\x00" + struct.pack("<d", float(k)),
        )
    writer.close()
    files["bag"] = bag
    files["missing"] = root / "missing"
    return files


def _invocations(f: dict[str, Path], out: Path) -> list[tuple[list[str], str]]:
    """(arguments, a text the error line must hold: the bad value or what it names)."""
    o = ["--out", str(out / "o")]
    sim = ["simulate", *o]
    cases: list[tuple[list[str], str]] = []
    for value in ("-1", "0", "nan", "inf", "1e308", "5e-324", "abc", "1e-5"):
        cases.append(([*sim, "--duration", value], value if value not in ("0", "-1") else "duration"))
    cases += [
        ([*sim, "--duration", "900000"], "samples"),
        ([*sim, "--duration", "1e6", "--sample-rate", "1e5"], "samples"),
    ]
    for option, values in {
        "--sample-rate": ("0", "-5", "1e308", "5e-324", "nan", "10"),
        "--rtol": ("0", "1", "1e-20", "nan", "5e-324", "1e308"),
        "--mass": ("0", "-1", "1e308", "5e-324", "1e4", "inf"),
        "--natural-frequency": ("0", "1e308", "1000", "5e-324"),
        "--zeta": ("-0.1", "3", "1e308", "nan"),  # ζ is the rig's damping_ratio
        "--band-velocity": ("1e308", "-1e308", "0.02", "inf", "abc"),
        "--velocity-coupling": ("0", "-1", "1e308", "5e-324", "bogus"),
        "--contact-area": ("1e308", "5e-324", "0", "bogus"),
    }.items():
        name = {
            "--zeta": "damping_ratio",
            "--band-velocity": "velocity",
            "--velocity-coupling": "coupling",
        }.get(option, option.removeprefix("--").replace("-", "_"))
        for value in values:
            cases.append(([*sim, option, value], value if value in ("nan", "inf", "abc", "bogus") else name))
    for cycle, named in (
        ("2e-7 1e-7 0.01 0.2", "high_velocity"),
        ("1e-7 2e-7 0.01 0", "ramp_time"),
        ("1e-7 2e-7 -1 0.2", "plateau_time"),
        ("1e-7 1e308 0.01 0.2", "high_velocity"),
        ("1e-7 2e-7 0.01 1e308", "ramp_time"),
        ("1e-7 2e-7 nan 0.2", "nan"),
    ):
        cases.append(([*sim, "--cycle", *cycle.split()], named))
    cases += [
        ([*sim, "--convention", "bogus"], "bogus"),
        ([*sim, "--profile", str(f["missing"])], "missing"),
        ([*sim, "--profile", str(f["fast.csv"])], "velocity=1.0"),
        ([*sim, "--profile", str(f["text.csv"])], "abc"),
        ([*sim, "--case", "11"], "11"),
        ([*sim, "--case", "abc"], "abc"),
        ([*sim, "--case", "1", "--config", str(f["yield.yaml"])], "not allowed with"),
        (["simulate", "--duration", "1"], "--out"),
    ]
    for name, named in (
        ("yield.yaml", "yield_distance"),
        ("area.yaml", "contact_area"),
        ("floor.yaml", "thermal_break_time"),
        ("coupling.yaml", "velocity_coupling"),
        ("perturb.yaml", "initial_perturbation"),
        ("thick.yaml", "interpenetration_thickness"),
        ("sine.yaml", "amplitude"),
        ("nyquist.yaml", "900"),
        ("ramp.yaml", "ramp_time"),
        ("stribeck.yaml", "static_coefficient"),
        ("samples.yaml", "samples"),
        ("unknown.yaml", "masss"),
        ("notyaml.yaml", "notyaml.yaml"),
        ("missing", "missing"),
    ):
        cases.append(([*sim, "--config", str(f[name])], named))
    cases += [
        (["friction", "--at", "inf"], "inf"),
        (["friction", "--at", "nan"], "nan"),
        (["friction", "--at", "abc"], "abc"),
        (["friction", "--at", *["1e-7"] * 10_001], "10001"),
        (["friction", "--contact-area", "1e308"], "1e308"),
        (["friction", "--contact-area", "-1"], "-1"),
        (["friction", "--case", "99"], "99"),
        (["friction", "--config", str(f["yield.yaml"])], "yield_distance"),
        (["stability", "--zeta", "-1"], "-1"),
        (["stability", "--zeta", "-inf"], "-inf"),
        (["stability", "--zeta", "nan"], "nan"),
        (["stability", "--zeta", *["0.01"] * 1001], "1001"),
        (["stability", "--at", "0"], "--at"),
        (["stability", "--at", "1e308"], "1e308"),
        (["stability", "--at", "-1"], "-1"),
        (["stability", "--velocity-coupling", "1e308"], "velocity_coupling"),
        (["stability", "--convention", "bogus"], "bogus"),
        (["stability", "--contact-area", "5e-324"], "5e-324"),
        (["stability", "--config", str(f["thick.yaml"])], "interpenetration_thickness"),
    ]
    run_dir = str(out / "r")
    for option, value in (
        ("--dj", "5e-324"),
        ("--dj", "0"),
        ("--dj", "1e308"),
        ("--fmin", "5e-324"),
        ("--fmax", "1e308"),
        ("--components", "1e308"),
        ("--components", "2.5"),
        ("--start", "-1"),
        ("--start", "nan"),
    ):
        cases.append((["analyze", run_dir, option, value], value))
    cases.append((["analyze", str(f["missing"])], "missing"))
    rig = ["rig", "--run-dir", run_dir]
    cases += [
        ([*rig, "--duration", "1e308"], "1e308"),
        ([*rig, "--duration", "5e-324"], "5e-324"),
        ([*rig, "--duration", "-1"], "-1"),
        ([*rig, "--case", "11"], "11"),
        ([*rig, "--mode", "x"], "'x'"),
        ([*rig, "--mode", "realtime", "--max-lag", "1e308"], "max_lag"),
        ([*rig, "--max-lag", "0.1"], "--max-lag"),
        ([*rig, "--namespace", "bad-ns"], "bad-ns"),
        ([*rig, "--config", str(f["area.yaml"])], "contact_area"),
        ([*rig, "--timeout", "inf"], "inf"),
        ([*rig, "--view", "99999"], "99999"),
        ([*rig, "--view", "0"], "1..65535"),
        ([*rig, "--view", "-1"], "-1"),
        ([*rig, "--view", "http"], "http"),
        ([*rig, "--view", "--view-allow", "root"], "'root'"),
        ([*rig, "--view-allow", "services"], "--view-allow services applies with --view only"),
        (["rig", "--duration", "1"], "--run-dir"),
    ]
    bag = str(f["bag"])
    cases += [
        (["replay", bag, "--rate", "inf"], "--rate inf"),
        (["replay", bag, "--rate", "nan"], "--rate nan"),
        (["replay", bag, "--rate", "0"], "--rate 0"),
        (["replay", bag, "--rate", "-2"], "--rate -2"),
        (["replay", bag, "--rate", "1e308"], "--rate 1e+308"),
        (["replay", bag, "--start", "5"], "--start 5"),
        (["replay", bag, "--start", "1e308"], "--start 1e+308"),
        (["replay", bag, "--start", "-1"], "--start -1"),
        (["replay", bag, "--start", "nan"], "--start nan"),
        (["replay", bag, "--wait-for-subscribers", "inf"], "inf"),
        (["replay", bag, "--topics", "/nope"], "/nope"),
        (["replay", bag, "--until", "5"], "--until 5"),
        (["replay", bag, "--until", "nan"], "--until nan"),
        (["replay", bag, "--until", "1e308"], "--until 1e+308"),
        (["replay", bag, "--start", "0.5", "--until", "0.2"], "--until 0.2"),
        (["replay", bag, "--lossless", "lubrig_recorder"], "/lubrig/state_block"),
        (["replay", bag, "--lossless", "bad name"], "bad name"),
        (["replay", bag, "--flow-window", "0"], "--flow-window 0"),
        (["replay", str(f["missing"])], "missing"),
        (["view", "--port", "99999"], "99999"),
        (["view", "--port", "abc"], "abc"),
        (["view", "--namespace", "bad-ns"], "bad-ns"),
        (["view", "--default-rate", "nan"], "nan"),
        (["view", "--rate", "state=abc"], "abc"),
        (["report", str(f["missing"]), "--out", str(out / "rep")], "missing"),
        (["bag", "info", str(f["missing"])], "missing"),
        (["bag", "check", str(f["missing"])], "missing"),
        (["bag", "repair", str(f["missing"])], "missing"),
        (["bag", "frobnicate", bag], "frobnicate"),
        (["bag", "export", bag, "--topics", "/nope", "--out", str(out / "e")], "/nope"),
        (["bag", "export", bag, "--topics", "/lubrig/displacement", "--out", str(out / "e")], "displacement"),
        (["bag", "export", bag, "--out", str(out / "e")], "no sample stream"),
        (["bag", "export", bag, "--start", "2", "--end", "1", "--out", str(out / "e")], "--start 2"),
        (["bag", "export", bag, "--end", "nan", "--out", str(out / "e")], "nan"),
        (["bag", "export", bag, "--format", "xlsx", "--out", str(out / "e")], "xlsx"),
        (["bag", "export", str(f["missing"]), "--out", str(out / "e")], "missing"),
        (["bag", "export", bag, "--out", f"{f['yield.yaml']}/e"], f"{f['yield.yaml']}/e"),
        (["bag", "crop", bag, "--start", "5", "--end", "6", "--out", str(out / "c")], "--start 5"),
        (["bag", "crop", bag, "--start", "0.5", "--end", "0.5", "--out", str(out / "c")], "--start 0.5"),
        (["bag", "crop", bag, "--start", "-1", "--end", "1", "--out", str(out / "c")], "--start -1"),
        (["bag", "crop", bag, "--start", "0", "--end", "1", "--out", bag], bag),
        (
            ["bag", "crop", str(f["missing"]), "--start", "0", "--end", "1", "--out", str(out / "c")],
            "missing",
        ),
        (["bag", "filter", bag, "--topics", "/nope", "--out", str(out / "c")], "/nope"),
        (["bag", "filter", bag, "--out", f"{f['yield.yaml']}/c"], f"{f['yield.yaml']}/c"),
        (["bag", "merge", bag, str(f["missing"]), "--out", str(out / "m")], "missing"),
        (["bag", "merge", bag, "--out", str(out / "m")], "two bags"),
        (["paper", "--out", str(out / "p"), "--duration", "1e308"], "1e308"),
        (["paper", "--out", str(out / "p"), "--duration", "900000"], "samples"),
        (["paper", "--out", str(out / "p"), "--duration", "1"], "1"),
        (["paper", "--out", str(out / "p"), "--duration", "nan"], "nan"),
        (["paper", "--out", str(out / "p"), "--recompute-scan", "--workers", "100000"], "100000"),
        (["paper", "--out", str(out / "p"), "--recompute-scan", "--workers", "0"], "0"),
        (["sweep", str(f["grid.yaml"]), "--out", str(out / "s"), "--scheduler", "serial"], "samples"),
        (["sweep", str(f["badpoint.yaml"]), "--out", str(out / "s")], "mass"),
        (["sweep", str(f["huge.yaml"]), "--out", str(out / "s")], "1000000000000 points"),
        (["sweep", str(f["wide.yaml"]), "--out", str(out / "s")], "1001000 points (1001 x 1000)"),
        (["sweep", str(f["missing"]), "--out", str(out / "s")], "missing"),
        (["sweep", str(f["badpoint.yaml"]), "--out", str(out / "s"), "--workers", "100000"], "100000"),
        (["sweep", str(f["badpoint.yaml"]), "--out", str(out / "s"), "--worker-timeout", "inf"], "inf"),
        (["sweep", str(f["badpoint.yaml"]), "--out", str(out / "s"), "--worker-timeout", "1e308"], "1e308"),
        (
            [
                "sweep",
                str(f["badpoint.yaml"]),
                "--out",
                str(out / "s"),
                "--scheduler",
                "tcp://127.0.0.1:1",
                "--worker-timeout",
                "1e3",
            ],
            "tcp://127.0.0.1:1",
        ),
        (["sweep", str(f["badpoint.yaml"]), "--out", str(out / "s"), "--scheduler", "bogus"], "bogus"),
        (["frobnicate"], "frobnicate"),
    ]
    fit = ["fit", str(f["infinite.csv"]), *o]
    cases += [
        ([*fit, "--free", "bogus"], "bogus"),
        ([*fit, "--free", "damping_ratio", "damping_ratio"], "damping_ratio"),
        ([*fit, "--free", "damping_ratio", "--segment", "nan"], "nan"),
        ([*fit, "--free", "damping_ratio", "--segment", "-1"], "-1"),
        ([*fit, "--free", "damping_ratio", "--workers", "0"], "--workers"),
        ([*fit, "--free", "damping_ratio", "--max-evaluations", "0"], "max-evaluations"),
        ([*fit, "--free", "damping_ratio", "--case", "11"], "11"),
        ([*fit, "--free", "damping_ratio"], "inf"),
        (["fit", str(f["missing"]), *o, "--free", "damping_ratio"], "missing"),
        (["fit", str(f["text.csv"]), *o, "--free", "damping_ratio"], "abc"),
    ]
    return cases


def _names(line: str, named: str) -> bool:
    """The line holds the text, or the number as Python writes it (1e308 -> 1e+308)."""
    try:
        number = repr(float(named))
    except ValueError:
        number = named
    return named in line or number in line


def _run(argv: list[str], env: dict[str, str]) -> tuple[int | None, str]:
    proc = subprocess.Popen(
        [*LUBRIG, *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        start_new_session=True,
    )
    try:
        _, err = proc.communicate(timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        return None, ""
    return proc.returncode, err


def test_every_bad_invocation_ends_in_one_line_naming_the_value(tmp_path: Path, ros_domain: int) -> None:
    files = _files(tmp_path)
    cases = _invocations(files, tmp_path / "out")
    assert len(cases) >= 100
    assert {a[0] for a, _ in cases} >= {
        "friction",
        "stability",
        "simulate",
        "analyze",
        "rig",
        "bag",
        "replay",
        "view",
        "report",
        "paper",
        "sweep",
        "fit",
    }
    env = {**os.environ, "ROS_DOMAIN_ID": str(ros_domain)}
    with ThreadPoolExecutor(PARALLEL) as pool:
        results = list(pool.map(lambda case: _run(case[0], env), cases))
    bad = []
    for (argv, named), (code, err) in zip(cases, results, strict=True):
        shown = " ".join(argv if len(argv) < 12 else [*argv[:8], "..."])
        lines = err.strip().splitlines()
        if code is None:
            bad.append(f"{shown}: still running after {TIMEOUT_S:g} s")
        elif code != 2 or len(lines) != 1 or "Traceback" in err or not _names(lines[0], named):
            bad.append(f"{shown}: exit {code}, stderr {err.strip()[-400:]!r} (expected {named!r})")
    assert not bad, "\n".join(bad)
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").rglob("*.csv"))
