"""Soak of the realtime rig: resident memory of every node over a long run, flat or growing.

    .venv/bin/python bench/bench_soak.py [--duration 600] [--every 10] [--hogs N] [--case 1]
                                         [--namespace /lubrig] [--keep DIR]

Starts the same rig as bench/bench_realtime.py (``lubrig rig --mode realtime --case C ... --force
--no-report``: plant, belt_drive, analysis and the recorder with its workers) on its own
ROS_DOMAIN_ID, and from the moment every node process is up samples the resident set size
(psutil ``memory_info().rss``) of each node every --every s for --duration s: one line per sample
(MB; the recorder is the sum over the recorder, its fork server and its workers, so pages the
forked workers share are counted once per process). Verdict per node: flat when the largest RSS
after the first minute is within 10 % of the RSS at 60 s (the first sample at or after 60 s);
the slope after 60 s (least squares) is printed beside it.

--hogs N runs N ``python3 -c 'while True: pass'`` beside it, always killed at the end. Prints the
load average at the start and the end (and the 1-min value with every sample). The rig is stopped
with SIGINT to the launcher, then its group is killed. Prints, does not assert: exit status 0
once the series was printed.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import psutil
from bench_realtime import ROLES, Rig, cpu_hogs, load_average, rig_arguments, stop_on_signals
from lubrig_testkit.harness import DomainLease, ros_env

FIRST_MINUTE_S = 60.0
FLAT_WITHIN = 0.10
MB = 1e6


@dataclass
class Series:
    """RSS samples: times since the nodes were up and bytes per role."""

    times: list[float] = field(default_factory=list)
    rss: dict[str, list[float]] = field(default_factory=lambda: {role: [] for role in ROLES})
    processes: dict[str, list[int]] = field(default_factory=lambda: {role: [] for role in ROLES})


def rss_by_role(rig: Rig) -> tuple[dict[str, float], dict[str, int]]:
    """Summed RSS (bytes) and process count of each node's processes (NaN if none is alive)."""
    groups = rig.processes()
    rss: dict[str, float] = {}
    count: dict[str, int] = {}
    for role in ROLES:
        total, n = 0, 0
        for proc in groups.get(role, []):
            try:
                total += proc.memory_info().rss
                n += 1
            except psutil.Error:
                continue
        rss[role], count[role] = (float(total) if n else float("nan")), n
    return rss, count


def verdict_line(role: str, series: Series) -> str:
    """The flat-or-growing verdict of one node."""
    t = np.asarray(series.times)
    mb = np.asarray(series.rss[role]) / MB
    after = t >= FIRST_MINUTE_S
    if after.sum() < 2 or not np.isfinite(mb[after]).all():
        return f"  {role}: n/a (needs samples at and after {FIRST_MINUTE_S:g} s; run --duration > 60)"
    at_minute = float(mb[after][0])
    worst = float(mb[after].max())
    growth = worst / at_minute - 1.0
    slope = float(np.polyfit(t[after], mb[after], 1)[0]) * 600.0  # MB per 10 min
    flat = "flat" if growth <= FLAT_WITHIN else "GROWING"
    return (
        f"  {role}: {at_minute:.1f} MB at {t[after][0]:.0f} s, max after it {worst:.1f} MB"
        f" ({100 * growth:+.1f} %; slope {slope:+.2f} MB per 10 min, start {mb[0]:.1f} MB):"
        f" {flat} (flat = within {100 * FLAT_WITHIN:g} %)"
    )


def soak(args: argparse.Namespace, run_dir: Path) -> int:
    """Run the rig, print the series and the verdicts; the rig is stopped whatever happens."""
    print(
        f"soak: realtime 1 kHz, case {args.case}, rig with recording, {args.duration:g} s,"
        f" RSS every {args.every:g} s, {args.hogs} CPU hog(s)"
    )
    print(f"load average (1/5/15 min) at start {load_average()}")
    series = Series()
    lease = DomainLease()
    rig: Rig | None = None
    failed = ""
    try:
        rig = Rig(
            run_dir,
            args.startup_timeout + args.duration + 30.0,
            args.case,
            args.namespace,
            ros_env(lease.domain),
        )
        end = time.monotonic() + args.startup_timeout
        while not rig.nodes_up():
            if not rig.running() or time.monotonic() > end:
                raise RuntimeError(
                    f"the node processes did not all start (launcher status {rig.popen.returncode})"
                )
            time.sleep(0.2)
        origin = time.monotonic()
        print(f"nodes up {origin - (end - args.startup_timeout):.1f} s after the launcher started")
        header = "".join(f"{role + ' MB':>14s}" for role in ROLES)
        print(f"{'t s':>6s}{header}{'load1':>8s}")
        k = 0
        while True:
            due = origin + k * args.every
            while time.monotonic() < due:
                if not rig.running():
                    raise RuntimeError(f"the launcher exited with status {rig.popen.returncode}")
                time.sleep(min(0.2, max(due - time.monotonic(), 0.0)))
            t = time.monotonic() - origin
            rss, count = rss_by_role(rig)
            series.times.append(t)
            cells = ""
            for role in ROLES:
                series.rss[role].append(rss[role])
                series.processes[role].append(count[role])
                extra = f"({count[role]})" if role == "recorder" else ""
                cells += f"{rss[role] / MB:>{14 - len(extra)}.1f}{extra}"
            print(f"{t:6.0f}{cells}{psutil.getloadavg()[0]:8.2f}", flush=True)
            if t >= args.duration - 1e-6:
                break
            k += 1
    except RuntimeError as exc:
        failed = str(exc) + ("\n" + rig.log_tails() if rig is not None else "")
    finally:
        status = rig.stop() if rig is not None else None
        lease.close()
    if failed:
        print(f"soak failed: {failed}")
    if series.times:
        print(
            f"verdict per node (max RSS after {FIRST_MINUTE_S:g} s versus the RSS at {FIRST_MINUTE_S:g} s):"
        )
        for role in ROLES:
            print(verdict_line(role, series))
        rec = series.processes["recorder"]
        print(f"  recorder processes (recorder, fork server, workers): {min(rec)}..{max(rec)}")
    print(f"load average at end {load_average()}")
    print(f"rig stopped (SIGINT to the launcher): exit status {status}")
    return 0 if series.times else 1


def main() -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--duration", type=float, default=600.0, help="soak length, s (default 600)")
    parser.add_argument("--every", type=float, default=10.0, help="sampling period, s (default 10)")
    rig_arguments(parser)
    args = parser.parse_args()
    if args.duration <= 0 or args.every <= 0 or args.hogs < 0:
        parser.error("expected --duration > 0, --every > 0, --hogs >= 0")
    stop_on_signals()
    with contextlib.ExitStack() as stack:
        if args.keep is not None:
            base = args.keep.resolve()
            base.mkdir(parents=True, exist_ok=True)
        else:
            base = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="bench_soak_")))
        stack.enter_context(cpu_hogs(args.hogs))
        status = soak(args, base / "soak")
        if args.keep is not None:
            print(f"run folder {base / 'soak'}")
    return status


if __name__ == "__main__":
    try:
        sys.exit(main())
    except KeyboardInterrupt:
        print("bench: interrupted; rig and hogs stopped", file=sys.stderr)
        sys.exit(130)
