"""Sim throughput of the node suite (targets: `lubrig rig --case 1` recorded at >= 50 x real time and
at >= 1/3 of the core's rate in the same run; start-up < 3 s quiet).

    .venv/bin/python bench/bench_sim_rate.py [--short 2] [--long 20] [--case 1] [--repeat 1]
    .venv/bin/python bench/bench_sim_rate.py --blocks 10,50,100,200,500   # block length choice

Part 1 (`lubrig rig`): runs the whole command (node processes, recorder unless --no-bag, report
skipped) for a short and a long run of rig time and prints the MARGINAL rate, (long - short) rig
seconds per (wall_long - wall_short) wall seconds, with the start-up (processes, imports,
discovery, the recorder's readiness, shutdown: the wall time of a zero-length run, extrapolated)
reported separately; next to core.run.simulate's own rate on the same configuration. Wall times
are of the whole `lubrig rig` process. Also without the recorder (`--no-recorder`). On a shared,
loaded machine the start-up varies by seconds from run to run, which swamps the difference of
the whole-command times; the run phase (belt_drive's first band block to the plant's "run
complete", from the node logs' ROS time stamps) is printed too, and its marginal rate; and per
run the start-up (command start -> the first band block) and the shutdown (run complete -> exit)
on their own, from the same stamps (system clock in both modes).

Part 2 (--blocks): plant + belt_drive + a probe process that is a required consumer of the flow
control (it takes every state block and reports flow_progress, like the recorder), for each
block length: the marginal rate between a short and a long run, measured from the first state
block to the last (start-up excluded). This is the measurement behind the default block_length.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

BIN = Path(sys.executable).parent


def _log_time(path: Path, text: str) -> float:
    """The ROS log time stamp (s) of the first line of a node log that contains text."""
    for line in path.read_text(errors="replace").splitlines():
        if text in line:
            return float(line.split("]")[1].strip(" ["))
    raise RuntimeError(f"{text!r} not in {path}")


def run_phase(out: Path) -> float:
    """Wall seconds from belt_drive's first band block to the plant's run complete (node logs)."""
    logs = out / "logs"
    start = _log_time(logs / "belt_drive.log", "sending band samples")
    return _log_time(logs / "plant.log", "run complete") - start


def rig_wall(case: int, duration: float, out: Path, record: bool) -> tuple[float, float, float]:
    """Wall seconds of one `lubrig rig` command (report skipped), and its start and end (epoch s)."""
    argv = [
        str(BIN / "lubrig"),
        "rig",
        "--case",
        str(case),
        "--duration",
        f"{duration:g}",
        "--bag",
        str(out),
        "--no-report",
    ]
    if not record:
        argv.append("--no-recorder")
    start, epoch = time.perf_counter(), time.time()
    done = subprocess.run(argv, capture_output=True, text=True, timeout=600, check=False)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        kept = Path(tempfile.mkdtemp(prefix="bench_sim_rate_failed_"))
        shutil.copytree(out, kept / out.name)  # the node logs outlive the temporary directory
        raise RuntimeError(
            f"{argv} failed ({done.returncode}), run folder kept in {kept}:\n{done.stdout}\n{done.stderr}"
        )
    return wall, epoch, epoch + wall


def start_and_stop(out: Path, began: float, ended: float) -> tuple[float, float]:
    """Start-up (command start -> belt_drive's first band block) and shutdown (the plant's run
    complete -> the command's exit), s, from the node logs' stamps (system clock)."""
    logs = out / "logs"
    first = _log_time(logs / "belt_drive.log", "sending band samples")
    return first - began, ended - _log_time(logs / "plant.log", "run complete")


def core_rate(case: int, duration: float) -> float:
    from lubrig_ros.core.presets import load_case
    from lubrig_ros.core.run import simulate

    config = load_case(case).with_overrides(duration=duration)
    simulate(config.with_overrides(duration=0.1))  # compiled kernels loaded
    start = time.perf_counter()
    simulate(config)
    return duration / (time.perf_counter() - start)


def marginal(short: tuple[float, float], long: tuple[float, float]) -> tuple[float, float]:
    """(rig s per wall s between the two runs, start-up s = wall at zero rig time)."""
    (d0, w0), (d1, w1) = short, long
    rate = (d1 - d0) / (w1 - w0)
    return rate, w0 - d0 / rate


def bench_rig(args: argparse.Namespace, tmp: Path) -> None:
    modes = [("recorded", True), ("no recorder", False)] if not args.no_bag else [("no recorder", False)]
    recorded: dict[str, list[float]] = {"marginal": [], "run phase": [], "start-up": []}
    for label, record in modes:
        for rep in range(args.repeat):
            walls, phases, ends = {}, {}, {}
            for duration in (args.short, args.long):
                out = tmp / f"{label[:2]}{rep}_{duration:g}"
                walls[duration], began, ended = rig_wall(args.case, duration, out, record)
                phases[duration] = run_phase(out)
                ends[duration] = start_and_stop(out, began, ended)
            rate, startup = marginal((args.short, walls[args.short]), (args.long, walls[args.long]))
            print(
                f"lubrig rig --case {args.case} ({label}): {args.short:g} s run "
                f"{walls[args.short]:.2f} s wall, {args.long:g} s run {walls[args.long]:.2f} s wall -> "
                f"marginal {rate:.1f} rig s per wall s, start-up + shutdown {startup:.2f} s"
            )
            inside = (args.long - args.short) / (phases[args.long] - phases[args.short])
            if record:
                recorded["marginal"].append(rate)
                recorded["run phase"].append(inside)
                recorded["start-up"] += [ends[d][0] for d in (args.short, args.long)]
            print(
                f"  run phase (first band block -> run complete, node logs): {args.short:g} s in "
                f"{phases[args.short]:.2f} s, {args.long:g} s in {phases[args.long]:.2f} s -> "
                f"marginal {inside:.1f} rig s per wall s; {args.long:g} s run overall "
                f"{args.long / phases[args.long]:.1f}; outside the run phase: "
                f"{walls[args.long] - phases[args.long]:.2f} s"
            )
            print(
                "  start-up (command -> first band block) / shutdown (run complete -> exit): "
                + ", ".join(
                    f"{d:g} s run {ends[d][0]:.2f} s / {ends[d][1]:.2f} s" for d in (args.short, args.long)
                )
            )
    rate = core_rate(args.case, args.long)
    print(f"core.run.simulate, case {args.case}, {args.long:g} s: {rate:.1f} rig s per wall s")
    if recorded["marginal"]:
        for name in ("marginal", "run phase"):
            ratios = ", ".join(f"{r / rate:.2f}" for r in recorded[name])
            print(f"recorded {name} / core: {ratios} (target >= 0.33; >= 50 x: {min(recorded[name]) >= 50})")
        starts = ", ".join(f"{t:.2f}" for t in recorded["start-up"])
        print(f"recorded start-up: {starts} s (target < 3 s quiet)")


def block_run(length: int, duration: float, tmp: Path) -> float:
    """Wall seconds from the first to the last state block of a plant + belt_drive + probe run."""
    from lubrig_testkit.harness import DomainLease, Probe, Processes, ros_env
    from std_msgs.msg import Bool

    from lubrig_ros.nodes import common

    ns = common.DEFAULT_NAMESPACE
    with DomainLease() as domain:
        probe, procs = Probe(domain), Processes(ros_env(domain), tmp / f"b{length}_{duration:g}")
        try:
            probe.subscribe(f"{ns}/run_complete", Bool, common.LATCHED_QOS)
            me = probe.consume_blocks(ns)
            procs.node("plant", case=1, duration=duration, wait_for_subscriber="probe")
            procs.node(
                "belt_drive",
                case=1,
                duration=duration,
                block_length=length,
                flow_window=min(1000, 98 * length),
                required_consumers=f"['{me}']",
            )
            n = round(duration * 1000) + 1
            blocks = f"{ns}/state_block"
            if not probe.wait_for(
                lambda: sum(len(b.displacement) for b in list(probe.messages[blocks])) >= n,
                120 + 10 * duration,
            ):
                raise RuntimeError("run did not complete:\n" + procs.logs())
            times = probe.times[blocks]
            return times[-1] - times[0]
        finally:
            procs.stop_all()
            probe.close()


def bench_blocks(args: argparse.Namespace, tmp: Path) -> None:
    for length in (int(x) for x in args.blocks.split(",")):
        w0 = block_run(length, args.short, tmp)
        w1 = block_run(length, args.long, tmp)
        rate = (args.long - args.short) / (w1 - w0)
        print(
            f"block_length {length:5d}: {args.short:g} s run {w0:.2f} s, {args.long:g} s run {w1:.2f} s "
            f"-> marginal {rate:.1f} rig s per wall s (plant + belt_drive + a required consumer)"
        )


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--case", type=int, default=1)
    parser.add_argument("--short", type=float, default=2.0, help="short run, rig s (default 2)")
    parser.add_argument("--long", type=float, default=20.0, help="long run, rig s (default 20)")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--no-bag", action="store_true", help="only runs without the recorder")
    parser.add_argument("--blocks", default="", help="comma-separated block lengths: part 2 only")
    args = parser.parse_args()
    print(f"load: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f} (1/5/15 min)")
    with tempfile.TemporaryDirectory() as tmp:
        if args.blocks:
            bench_blocks(args, Path(tmp))
        else:
            bench_rig(args, Path(tmp))


if __name__ == "__main__":
    main()
