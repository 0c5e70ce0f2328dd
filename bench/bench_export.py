"""`lubrig bag export` throughput: rows per second of a long sim bag, and the exporter's peak memory.

    .venv/bin/python bench/bench_export.py [--duration 600] [--formats csv parquet] [--keep DIR]

A sim bag of case 1 of --duration s of rig time at 1 kHz is written with the project's BagWriter
in the sim plant's layout (state_block and band_velocity_block of DEFAULT_BLOCK_LENGTH samples, a
/clock per block, the run configuration), from the core integrator's run. Each format is then
exported by `lubrig bag export` in its own process: the figures are rows per second (every row of
every table over the process's wall time, Python start-up included) and the process's peak
resident memory (VmHWM) with its anonymous and file-backed parts: the anonymous part (what the
export holds) stays that of a short bag if the export streams; the file-backed part grows with
the bag, whose file is memory-mapped (page cache). The load average is printed before and after.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from lubrig_ros.app.interface.node_parameters import DEFAULT_BLOCK_LENGTH
from lubrig_ros.app.plant.output import BeltTravel, trajectory_columns
from lubrig_ros.bag.layout import typestore
from lubrig_ros.bag.writer import BagWriter, serialize_string
from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import simulate

NS = "/lubrig"
STATE_TYPE, BAND_TYPE = "lubrig_interfaces/msg/RigStateBlock", "lubrig_interfaces/msg/BandVelocityBlock"


def write_sim_bag(path: Path, duration: float) -> int:
    """Case 1 for `duration` s as the sim recorder writes it; returns the state samples written."""
    config = load_case(1).with_overrides(duration=duration)
    traj = simulate(config)
    store = typestore()
    period = 1.0 / config.sample_rate
    normal = config.rig.friction.normal_force
    values = trajectory_columns(traj, BeltTravel().add_many(traj.time, traj.band_velocity), normal)
    types = store.types
    header, stamp, clock = (
        types["std_msgs/msg/Header"],
        types["builtin_interfaces/msg/Time"],
        types["rosgraph_msgs/msg/Clock"],
    )
    writer = BagWriter(path, run_config=config.to_yaml())
    writer.add_topic(f"{NS}/run_config", "std_msgs/msg/String", 1, latched=True)
    writer.write(f"{NS}/run_config", "std_msgs/msg/String", 0, serialize_string(config.to_yaml()))
    n, block = len(traj), DEFAULT_BLOCK_LENGTH
    for k0 in range(0, n, block):
        ks = slice(k0, min(k0 + block, n))
        t_ns = round(k0 * period * 1e9)
        t = stamp(*divmod(t_ns, 1_000_000_000))
        common = {"header": header(t, ""), "sample_period": period, "first_sample_index": k0, "segment": 0}
        state = types[STATE_TYPE](
            **common, **{k: v[ks] for k, v in values.items()}, lateness=np.zeros(0), skipped=0
        )
        band = types[BAND_TYPE](**common, band_velocity=values["band_velocity"][ks])
        writer.write(
            "/clock",
            "rosgraph_msgs/msg/Clock",
            t_ns,
            bytes(store.serialize_cdr(clock(t), "rosgraph_msgs/msg/Clock")),
        )
        writer.write(
            f"{NS}/band_velocity_block", BAND_TYPE, t_ns, bytes(store.serialize_cdr(band, BAND_TYPE))
        )
        writer.write(f"{NS}/state_block", STATE_TYPE, t_ns, bytes(store.serialize_cdr(state, STATE_TYPE)))
    writer.close()
    return n


#: `lubrig bag export` as `lubrig` runs it, then the process's peak resident set (VmHWM, of its own
#: address space: getrusage's ru_maxrss would also count this benchmark's memory, inherited at fork).
CHILD = (
    "import sys\n"
    "from lubrig_ros.cli.main import main\n"
    "rc = main(sys.argv[1:])\n"
    "print(next(x for x in open('/proc/self/status') if x.startswith('VmHWM:')).strip())\n"
    "sys.exit(rc)\n"
)


def _rss_mb(pid: int) -> tuple[int, int]:
    """(anonymous, file-backed) resident MB of a running process, (0, 0) once it is gone."""
    found = {"RssAnon": 0, "RssFile": 0}
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                key = line.split(":")[0]
                if key in found:
                    found[key] = int(line.split()[1]) // 1024
    except OSError:
        pass
    return found["RssAnon"], found["RssFile"]


def export(bag: Path, fmt: str, out: Path) -> tuple[float, int, int, tuple[int, int]]:
    """(wall s, rows, peak RSS bytes, (peak anonymous MB, peak file-backed MB)) of one export process.

    The anonymous and file-backed peaks are sampled every 20 ms: the file-backed part holds the
    bag's memory-mapped pages (the page cache's, given back under pressure), the anonymous part is
    what the export itself holds.
    """
    argv = [sys.executable, "-c", CHILD, "bag", "export", str(bag), "--format", fmt, "--out", str(out)]
    started = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    anon = mapped = 0
    while proc.poll() is None:
        a, m = _rss_mb(proc.pid)
        anon, mapped = max(anon, a), max(mapped, m)
        time.sleep(0.02)
    elapsed = time.perf_counter() - started
    stdout, stderr = proc.communicate()
    if proc.returncode:
        raise SystemExit(f"export failed ({proc.returncode}): {stderr}")
    lines = stdout.splitlines()
    rows = sum(int(line.split(": ")[1].split()[0]) for line in lines if " rows -> " in line)
    hwm_kb = int(next(line for line in lines if line.startswith("VmHWM:")).split()[1])
    return elapsed, rows, hwm_kb * 1024, (anon, mapped)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=600.0, help="rig time of the bag, s (1 kHz)")
    ap.add_argument("--formats", nargs="+", choices=("csv", "parquet"), default=["csv", "parquet"])
    ap.add_argument("--keep", type=Path, help="write the bag and tables here (default: a temporary folder)")
    args = ap.parse_args()
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    with tempfile.TemporaryDirectory(prefix="bench_export_") as tmp:
        root = args.keep or Path(tmp)
        bag = root / "bag"
        started = time.perf_counter()
        n = write_sim_bag(bag, args.duration)
        size = sum(p.stat().st_size for p in bag.iterdir())
        print(
            f"sim bag: case 1, {args.duration:g} s of rig time, {n} state samples, {size / 1e6:.1f} MB "
            f"(written in {time.perf_counter() - started:.1f} s)"
        )
        for fmt in args.formats:
            elapsed, rows, rss, (anon, mapped) = export(bag, fmt, root / f"tables_{fmt}")
            tables = sum(p.stat().st_size for p in (root / f"tables_{fmt}").iterdir())
            print(
                f"export {fmt:<7}: {rows} rows in {elapsed:.2f} s = {rows / elapsed:,.0f} rows/s; "
                f"peak RSS {rss / 1e6:.0f} MB (anonymous {anon} MB, file-backed {mapped} MB); "
                f"tables {tables / 1e6:.1f} MB"
            )
    print(f"load average after:  {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
