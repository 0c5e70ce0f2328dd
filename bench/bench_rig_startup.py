"""Where the start-up of `lubrig rig` goes: a timeline of one start and the CPU of each process.

    .venv/bin/python bench/bench_rig_startup.py [--repeat 3] [--no-recorder] [--duration 2]
    .venv/bin/python bench/bench_rig_startup.py --repeat 3 --against ../wt-base   # A/B, alternately

Runs `lubrig rig --case 1 --duration 2 --no-report` on a ROS domain of its own (the test kit's
lease) with LUBRIG_STARTUP_TRACE=1, which makes the launcher and each node print when it reached
a start-up step (app/processes/startup_trace.py). Meanwhile it polls /proc every 10 ms for the launcher's
descendants (exec time, CPU seconds). Printed per run, seconds after the command started:

- launcher: its trace marks (imports done, namespace check begun and ended, processes started);
- per process: exec, imports done, node created (its trace marks), and its first log line;
- plant announced (flow_progress, the recorder subscribed), recorder recording, belt_drive's
  first band block (the start-up figure of bench_sim_rate.py);
- CPU seconds of each process (its helpers included) from exec to the first band block.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

BIN = Path(sys.executable).parent
HZ = os.sysconf("SC_CLK_TCK")
MARKS = {  # node log: what marks a step (first line holding it)
    "plant announced": ("plant", "flow_progress as"),
    "recorder recording": ("recorder", "recorder: recording"),
    "first band block": ("belt_drive", "sending band samples"),
}


def _boot_time() -> float:
    """Epoch s of boot, to 10 ms (/proc/stat's btime is whole seconds)."""
    return time.time() - float(Path("/proc/uptime").read_text().split()[0])


def _children() -> dict[int, list[int]]:
    tree: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        tree.setdefault(int(fields[1]), []).append(int(entry.name))
    return tree


class ProcWatch(threading.Thread):
    """Polls the descendants of `root`: name, exec time (epoch s), CPU s at each poll."""

    def __init__(self, root: int) -> None:
        super().__init__(daemon=True)
        self.root, self.btime = root, _boot_time()
        self.procs: dict[int, dict] = {}
        self.stop = threading.Event()

    def _sample(self) -> None:
        tree, now = _children(), time.time()
        todo, seen = [self.root], []
        while todo:
            pid = todo.pop()
            seen.append(pid)
            todo += tree.get(pid, [])
        for pid in seen:
            try:
                fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
                argv = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
            except OSError:
                continue
            info = self.procs.setdefault(
                pid, {"start": self.btime + int(fields[19]) / HZ, "cpu": [], "name": "?"}
            )
            if any(argv):  # a zombie's is empty
                info["name"] = _name([a.decode(errors="replace") for a in argv if a])
            info["parent"] = int(fields[1])
            info["cpu"].append((now, (int(fields[11]) + int(fields[12])) / HZ))

    def run(self) -> None:
        while not self.stop.is_set():
            self._sample()
            time.sleep(0.01)

    def cpu_until(self, pid: int, t: float) -> float:
        samples = [c for when, c in self.procs[pid]["cpu"] if when <= t]
        return samples[-1] if samples else 0.0


def _name(argv: list[str]) -> str:
    for arg in argv[:3]:
        base = Path(arg).name
        if base in ("plant", "belt_drive", "analysis", "recorder", "view", "lubrig"):
            return base
    return Path(argv[0]).name if argv else "?"


def _log_lines(path: Path) -> list[tuple[float | None, str]]:
    out = []
    for line in path.read_text(errors="replace").splitlines() if path.is_file() else []:
        stamp = None
        if line.startswith("[") and "] [" in line:
            try:
                stamp = float(line.split("]")[1].strip(" ["))
            except ValueError:
                stamp = None
        out.append((stamp, line))
    return out


def _trace_marks(lines: list[tuple[float | None, str]]) -> list[tuple[str, float]]:
    marks = []
    for _stamp, line in lines:
        if line.startswith("startup-trace "):
            _, who, when, what = line.split(" ", 3)
            marks.append((f"{who}: {what}", float(when)))
    return marks


def _first_stamp(lines: list[tuple[float | None, str]], text: str) -> float | None:
    return next((s for s, line in lines if s is not None and text in line), None)


def one_run(duration: float, record: bool, tmp: Path, domain: int, tree: str = "") -> float:
    from lubrig_testkit.harness import ros_env

    out = tmp / f"run{time.monotonic_ns()}"
    argv = [str(BIN / "lubrig"), "rig", "--case", "1", "--duration", f"{duration:g}"]
    argv += ["--run-dir", str(out), "--no-report"] + ([] if record else ["--no-recorder"])
    env = {**ros_env(domain), "LUBRIG_STARTUP_TRACE": "1"}
    if tree:  # another checkout of lubrig_ros (e.g. the commit before) with this venv
        env["PYTHONPATH"] = tree
    began = time.time()
    proc = subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    watch = ProcWatch(proc.pid)
    watch.start()
    output, _ = proc.communicate(timeout=600)
    watch.stop.set()
    watch.join()
    if proc.returncode != 0:
        raise RuntimeError(f"{argv} failed ({proc.returncode}):\n{output}")
    logs = {p.stem: _log_lines(p) for p in (out / "logs").glob("*.log")}
    launcher = [(None, line) for line in output.splitlines()]
    events: list[tuple[float, str]] = [(t, w) for w, t in _trace_marks(launcher)]
    for name, lines in logs.items():
        events += [(t, w) for w, t in _trace_marks(lines)]
        first = next((s for s, _line in lines if s is not None), None)
        if first is not None:
            events.append((first, f"{name}: first log line"))
    for what, (name, text) in MARKS.items():
        when = _first_stamp(logs.get(name, []), text)
        if when is None and name == "recorder":
            when = next((t for w, t in _trace_marks(logs.get(name, [])) if "recording" in w), None)
        if when is not None:
            events.append((when, what))
    for pid, info in watch.procs.items():
        if pid != proc.pid:
            events.append((info["start"], f"{info['name']} ({pid}): exec"))
    events.sort()
    first_band = _first_stamp(logs.get("belt_drive", []), "sending band samples") or began
    print(
        f"run at {time.strftime('%H:%M:%S', time.gmtime(began))} UTC, load {os.getloadavg()[0]:.2f}"
        + (f", lubrig_ros from {tree}" if tree else "")
    )
    for when, what in events:
        if when <= first_band + 0.5:
            print(f"  {when - began:6.2f} s  {what}")
    cpu: dict[str, float] = {}
    for pid in watch.procs:
        top = pid  # the launcher's child this process descends from
        while watch.procs[top]["parent"] in watch.procs and watch.procs[top]["parent"] != proc.pid:
            top = watch.procs[top]["parent"]
        label = "launcher" if pid == proc.pid else watch.procs[top]["name"]
        cpu[label] = cpu.get(label, 0.0) + watch.cpu_until(pid, first_band)
    total = sum(cpu.values())
    shown = ", ".join(f"{k} {v:.2f}" for k, v in sorted(cpu.items(), key=lambda kv: -kv[1]))
    print(f"  start-up {first_band - began:.2f} s; CPU s until the first band block: {total:.2f} ({shown})")
    return first_band - began


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--duration", type=float, default=2.0)
    parser.add_argument("--no-recorder", action="store_true")
    parser.add_argument(
        "--against",
        metavar="TREE",
        default="",
        help="alternate runs with lubrig_ros from this checkout (PYTHONPATH), e.g. the commit before",
    )
    args = parser.parse_args()
    from lubrig_testkit.harness import DomainLease

    trees = ["", args.against] if args.against else [""]
    starts: dict[str, list[float]] = {t: [] for t in trees}
    with DomainLease() as domain, tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.repeat):
            for tree in trees:
                starts[tree].append(one_run(args.duration, not args.no_recorder, Path(tmp), domain, tree))
    for tree, values in starts.items():
        print(f"start-up, {tree or 'this checkout'}: " + ", ".join(f"{v:.2f}" for v in values) + " s")


if __name__ == "__main__":
    main()
