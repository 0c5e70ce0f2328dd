"""Realtime rig as a user runs it: deadline misses, lag, what a separate subscriber gets, CPU per node.

    .venv/bin/python bench/bench_realtime.py [--duration 60] [--hogs N] [--repeat K] [--case 1]
                                             [--namespace /lubrig] [--keep DIR]

Each run starts the whole realtime rig with recording, ``lubrig rig --mode realtime --case C
--duration D --run-dir DIR --force --no-report``, as a subprocess on its own ROS_DOMAIN_ID (leased
like a test's, lubrig_testkit.harness; discovery on this host only). This process is the separate
subscriber: an rclpy node (raw subscription, EventsExecutor spun with spin_once in a thread) on
``<ns>/state`` (one RigState per sample; stamp and sample_index read from the CDR bytes), on
/diagnostics (the plant's ``<ns>/plant: timing`` status) and, where RigStateBlock declares
``skipped``, on ``<ns>/state_block`` for the samples the plant skipped behind real time
(lag_policy skip: never published, so not counted as lost by this subscriber).

The steady window opens at the first plant timing status that arrives after every node process
is up (plant, belt_drive, analysis, recorder), the analysis has published a status and states
arrive here; it closes at the first timing status after --duration s. Over the window:

- deadline misses: difference of the plant's ``deadline_misses`` (and ``samples``) between the
  first and the last status of the window, count and share; worst lateness (``max_lateness_s``,
  the plant's whole run) and, from the state blocks' ``lateness``, the window's samples' lateness
  (p50 / p99 / max, and how many were later than one period);
- lag of rig time behind wall time at the end: ``lag_s`` of the last status (``max_lag_s``,
  ``lag_bound_s``, ``lag_policy``, ``skipped_samples`` beside it; "n/a" where the plant does not
  report them), and independently at this subscriber: system time now − the due time of the
  newest state received (segment start from the block stamps + sample_index × period; where the
  blocks are subscribed) and now − its stamp (the node clock when the plant computed it);
- states per second received here, the share of the samples published that were received (the
  sample_index span of the window less the samples the plant declared skipped), the share of
  consecutive samples (index k and k + 1 both received) whose stamps are more than 1.5 ms apart
  and the worst such gap;
- the machine's floor in the same window (lubrig_testkit.wakeup, run beside the rig one SCHED_FIFO
  priority below the plant's loop): how often a bare 1 kHz loop that only sleeps to absolute
  deadlines woke more than one period late, and the host's steal time (the hypervisor running
  other guests on this VM's vCPUs); the plant cannot miss fewer deadlines than this loop does;
- the machine's speed before the run (a fixed pure-Python loop, best of 3): CPU seconds of the
  same work grow when the host is slower, so CPU figures of different days compare in proportion;
- CPU seconds per wall second (user + system, psutil) of each node process, found as descendants
  of the launcher by their command lines; the recorder's fork server and workers count under
  "recorder"; and their total. The launcher and this process are shown apart (not in the total).

--hogs N starts N ``python3 -c 'while True: pass'`` for the whole bench and always kills them
(also on an error, Ctrl-C or SIGTERM). The load average is printed at the start and the end of
each run. The rig is stopped with SIGINT to the launcher (it stops the nodes, then the recorder),
then its process group is killed. A benchmark prints, it does not assert: the exit status is 0
once figures were printed (1 only if no run produced any). Soak (memory): bench/bench_soak.py.
"""

from __future__ import annotations

import argparse
import bisect
import contextlib
import ctypes
import functools
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import psutil
from lubrig_testkit.harness import DomainLease, ros_env

from lubrig_ros.app.interface import contract
from lubrig_ros.app.interface.cdr import sample_span

BIN = Path(sys.executable).parent
ROLES = ("plant", "belt_drive", "analysis", "recorder")
RIG_STATE = "lubrig_interfaces/msg/RigState"
SAMPLE_RATE_HZ = 1000.0
GAP_PERIOD_S = 1.0 / SAMPLE_RATE_HZ  # a sample later than this after its due time missed its deadline
GAP_S = 1.5e-3  # consecutive state stamps further apart than this count as a gap
STOP_GRACE_S = 90.0  # the launcher stops the nodes (10 s grace, +5 s), then the recorder (40 s, +5 s)
# the realtime targets (docs/benchmarks.md "Nodes in real time")
MISS_TARGET_PERCENT = {0: 0.1, 1: 0.5, 2: 2.0}
LAG_TARGET_S = 0.050
RECEIVED_TARGET_PERCENT = 99.5
GAP_TARGET_PERCENT = 1.0
CPU_TARGET_CORES = 0.35

Group = dict[str, list[psutil.Process]]


# --------------------------------------------------------------------------------- helpers


def load_average() -> str:
    """os.getloadavg() as '1.23 1.10 0.90' (1, 5, 15 min)."""
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def _raise_interrupt(signum: int, _frame: object) -> None:
    raise KeyboardInterrupt(f"signal {signum}")


def stop_on_signals() -> None:
    """SIGINT, SIGTERM and SIGHUP end the bench like Ctrl-C: every `finally` runs (hogs, rig stopped).

    SIGINT too, explicitly: a shell starts a background job with SIGINT ignored, and Python keeps
    an ignored SIGINT ignored.
    """
    signal.signal(signal.SIGINT, signal.default_int_handler)
    for sig in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, _raise_interrupt)


_LIBC = ctypes.CDLL(None, use_errno=True)
_PR_SET_PDEATHSIG = 1


def _die_with_parent(sig: int) -> Callable[[], None]:
    """preexec_fn: the child gets `sig` when this process dies (even by SIGKILL)."""

    def set_death_signal() -> None:
        _LIBC.prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0)

    return set_death_signal


def _kill_group(pid: int) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(pid, signal.SIGKILL)


@contextlib.contextmanager
def cpu_hogs(n: int) -> Iterator[list[subprocess.Popen[bytes]]]:
    """N `python3 -c 'while True: pass'` for the duration of the block; always killed after it."""
    python = shutil.which("python3") or sys.executable
    hogs: list[subprocess.Popen[bytes]] = []
    try:
        for _ in range(n):
            hogs.append(
                subprocess.Popen(
                    [python, "-c", "while True: pass"],
                    start_new_session=True,
                    preexec_fn=_die_with_parent(signal.SIGKILL),
                )
            )
        if n:
            print(f"{n} CPU hog(s) running: {python} -c 'while True: pass' (pids {[h.pid for h in hogs]})")
        yield hogs
    finally:
        for hog in hogs:
            _kill_group(hog.pid)
        for hog in hogs:
            with contextlib.suppress(subprocess.TimeoutExpired):
                hog.wait(timeout=10)
        if hogs:
            print(f"{len(hogs)} CPU hog(s) killed")


def fmt(value: float | None, scale: float = 1.0, digits: int = 3, unit: str = "") -> str:
    """A figure with its unit, or 'n/a'."""
    if value is None or not math.isfinite(value):
        return "n/a"
    return f"{value * scale:.{digits}f}{' ' + unit if unit else ''}"


def number(values: dict[str, str], key: str) -> float | None:
    """A numeric value of a status, None when absent or not a number."""
    try:
        return float(values[key])
    except (KeyError, ValueError):
        return None


def verdict(ok: bool | None) -> str:
    """'meets' / 'does not meet' / 'n/a'."""
    return "n/a" if ok is None else ("meets" if ok else "DOES NOT MEET")


# ------------------------------------------------------------------------------------ the rig


def role_of(cmdline: list[str]) -> str:
    """plant / belt_drive / analysis / recorder / view from a command line; else the program name."""
    for arg in cmdline[:2]:
        name = Path(arg).name
        if name in (*ROLES, "view"):
            return name
    return Path(cmdline[0]).name if cmdline else "?"


@functools.cache
def has_no_report() -> bool:
    """True when `lubrig rig` has --no-report (asked once)."""
    argv = [str(BIN / "lubrig"), "rig", "--help"]
    return "--no-report" in subprocess.run(argv, capture_output=True, text=True, check=False).stdout


class Rig:
    """`lubrig rig --mode realtime` with recording, as a subprocess in its own session."""

    def __init__(self, run_dir: Path, duration: float, case: int, namespace: str, env: dict[str, str]):
        self.run_dir = run_dir
        self.argv = [
            str(BIN / "lubrig"),
            "rig",
            "--mode",
            "realtime",
            "--case",
            str(case),
            "--namespace",
            namespace,
            "--duration",
            f"{duration:g}",
            "--run-dir",
            str(run_dir),
            "--force",
        ]
        if has_no_report():
            self.argv.append("--no-report")
        run_dir.mkdir(parents=True, exist_ok=True)
        self.log_path = run_dir.parent / f"{run_dir.name}.launcher.log"
        with open(self.log_path, "wb") as log:
            # own session: a terminal Ctrl-C reaches this bench only, which stops the rig itself;
            # should this process die without stopping it, the launcher gets SIGINT (death signal)
            self.popen = subprocess.Popen(
                self.argv,
                env=env,
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
                preexec_fn=_die_with_parent(signal.SIGINT),
            )
        self.launcher = psutil.Process(self.popen.pid)

    def running(self) -> bool:
        """True while the launcher runs."""
        return self.popen.poll() is None

    def processes(self) -> Group:
        """Role -> processes: each child of the launcher with all its descendants."""
        groups: Group = {}
        with contextlib.suppress(psutil.Error):
            for child in self.launcher.children(recursive=False):
                try:
                    role = role_of(child.cmdline())
                    members = [child, *child.children(recursive=True)]
                except psutil.Error:
                    continue
                groups.setdefault(role, []).extend(members)
        return groups

    def nodes_up(self) -> bool:
        """Every node process (plant, belt_drive, analysis, recorder) is running."""
        groups = self.processes()
        return all(groups.get(role) for role in ROLES)

    def stop(self) -> int | None:
        """SIGINT to the launcher, wait up to STOP_GRACE_S, then SIGKILL its group; exit status."""
        try:
            if self.popen.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    self.popen.send_signal(signal.SIGINT)
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.popen.wait(timeout=STOP_GRACE_S)
        finally:
            _kill_group(self.popen.pid)  # whatever is left (nodes, recorder workers)
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.popen.wait(timeout=10)
        return self.popen.returncode

    def log_tails(self, lines: int = 15) -> str:
        """The last lines of the launcher's output and of every node log (for a failed run)."""
        parts = []
        for path in [self.log_path, *sorted((self.run_dir / "logs").glob("*.log"))]:
            if path.is_file():
                text = path.read_text(errors="replace").strip().splitlines()[-lines:]
                parts.append(f"--- {path.name}:\n" + "\n".join(text))
        return "\n".join(parts)


@dataclass
class CpuSnapshot:
    """CPU seconds (user + system) of every process of the rig at one moment."""

    wall: float
    cpu: dict[int, tuple[str, float, float]]  # pid -> (role, create_time, cpu s)


def cpu_snapshot(rig: Rig) -> CpuSnapshot:
    """CPU times of the launcher (role 'launcher') and every descendant by role."""
    wall = time.monotonic()
    cpu: dict[int, tuple[str, float, float]] = {}
    members = [("launcher", rig.launcher)]
    members += [(role, p) for role, procs in rig.processes().items() for p in procs]
    for role, proc in members:
        try:
            with proc.oneshot():
                times = proc.cpu_times()
                cpu[proc.pid] = (role, proc.create_time(), times.user + times.system)
        except psutil.Error:
            continue
    return CpuSnapshot(wall, cpu)


def cpu_per_role(first: CpuSnapshot, last: CpuSnapshot) -> tuple[dict[str, float], dict[str, int], int]:
    """CPU s per wall s by role between two snapshots, processes per role, processes that vanished.

    A process that started inside the window counts from zero; one that ended inside it is lost
    (its share is not counted; reported as vanished).
    """
    seconds = max(last.wall - first.wall, 1e-9)
    used: dict[str, float] = {}
    count: dict[str, int] = {}
    for pid, (role, created, cpu) in last.cpu.items():
        before = first.cpu.get(pid)
        base = before[2] if before is not None and before[1] == created else 0.0
        used[role] = used.get(role, 0.0) + max(cpu - base, 0.0)
        count[role] = count.get(role, 0) + 1
    vanished = sum(1 for pid in first.cpu if pid not in last.cpu)
    return {role: s / seconds for role, s in used.items()}, count, vanished


# ---------------------------------------------------------------------------------- the probe


class Subscriber:
    """The separate subscriber: <ns>/state (raw) and /diagnostics, EventsExecutor in a thread."""

    def __init__(self, domain: int, namespace: str) -> None:
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.context import Context
        from rclpy.experimental.events_executor import EventsExecutor
        from rclpy.node import Node
        from rclpy.signals import SignalHandlerOptions

        from lubrig_ros.app.processes.discovery import discovery_environment
        from lubrig_ros.nodes.interfaces import message_class, qos_profile

        os.environ.update(discovery_environment(os.environ).env)  # this host only, as the rig
        self.timing_name = f"{contract.resolve(namespace, 'plant')}: timing"
        self.analysis_prefix = f"{contract.resolve(namespace, 'analysis')}:"
        self.context = Context()
        # no rclpy signal handlers: Ctrl-C / SIGTERM must reach this bench (KeyboardInterrupt),
        # which stops the rig and the hogs
        rclpy.init(context=self.context, domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
        self.node = Node("lubrig_bench_subscriber", context=self.context)
        state = contract.topic("state").resolved(namespace)
        diagnostics = contract.topic("/diagnostics")
        self.node.create_subscription(
            message_class(state.msgtype), state.name, self._on_state, qos_profile(state.qos), raw=True
        )
        self.node.create_subscription(
            DiagnosticArray, diagnostics.name, self._on_diagnostics, qos_profile(diagnostics.qos)
        )
        # skipped samples, declared by the plant in its state blocks (RigStateBlock.skipped, where
        # the installed message has it): (segment, first skipped index, last skipped index)
        self.skips: list[tuple[int, int, int]] | None = None
        self.segment_start_ns: dict[int, tuple[int, float]] = {}  # segment -> (due of index 0, period)
        block = contract.topic("state_block").resolved(namespace)
        block_class: Any = message_class(block.msgtype)
        if "skipped" in block_class.get_fields_and_field_types():
            self.skips = []
            self.node.create_subscription(block_class, block.name, self._on_block, qos_profile(block.qos))
        # what the callbacks fill (one writer: the spin thread)
        self.states = 0
        self.bad_states = 0
        self.newest_stamp_ns: int | None = None
        self.newest_index: tuple[int, int] | None = None  # (segment, sample_index)
        self.window = False
        self.stamps: list[int] = []
        self.indices: list[int] = []
        self.segments: list[int] = []
        self.received_ns: list[int] = []
        self.block_lateness: list[float] = []  # the window's samples' lateness, from the blocks
        self.late_due_ns: list[int] = []  # due times (system clock) of the window's late samples
        self.timing: list[tuple[float, dict[str, str]]] = []  # (monotonic arrival, values)
        self.analysis_seen = False
        self._stop = threading.Event()
        self.executor = EventsExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        # EventsExecutor.spin() in this wheel fires no timer and keeps a core busy: spin_once loop
        with contextlib.suppress(Exception):
            while not self._stop.is_set():
                self.executor.spin_once(timeout_sec=0.05)

    def _on_state(self, data: bytes) -> None:
        received = time.time_ns()
        try:
            span = sample_span(RIG_STATE, data)
        except ValueError:
            self.bad_states += 1
            return
        self.states += 1
        self.newest_stamp_ns = span.stamp_ns
        self.newest_index = (span.segment, span.first_index)
        if self.window:
            self.stamps.append(span.stamp_ns)
            self.indices.append(span.first_index)
            self.segments.append(span.segment)
            self.received_ns.append(received)

    def _on_block(self, msg: Any) -> None:
        # realtime: the stamp is the due time of the block's first sample (RigStateBlock.msg)
        stamp_ns = int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
        period_ns = float(msg.sample_period) * 1e9
        start = stamp_ns - int(msg.first_sample_index) * period_ns
        self.segment_start_ns[int(msg.segment)] = (round(start), period_ns)
        if self.window:
            self.block_lateness.extend(msg.lateness)
            self.late_due_ns.extend(
                round(stamp_ns + i * period_ns)
                for i, v in enumerate(msg.lateness)
                if v > 1.0 / SAMPLE_RATE_HZ
            )
        if msg.skipped and self.skips is not None:
            first = int(msg.first_sample_index)
            self.skips.append((int(msg.segment), first - int(msg.skipped), first - 1))

    def _on_diagnostics(self, array: Any) -> None:
        arrival = time.monotonic()
        for status in array.status:
            if status.name == self.timing_name:
                self.timing.append((arrival, {kv.key: kv.value for kv in status.values}))
            elif status.name.startswith(self.analysis_prefix):
                self.analysis_seen = True

    def open_window(self) -> None:
        """Start recording the states of the window."""
        self.stamps, self.indices, self.segments, self.received_ns = [], [], [], []
        self.block_lateness = []
        self.late_due_ns = []
        self.window = True

    def newest_due_lag_s(self, now_ns: int) -> float | None:
        """now − the due time of the newest state received, s (None without its segment's blocks)."""
        if self.newest_index is None or self.newest_index[0] not in self.segment_start_ns:
            return None
        start, period_ns = self.segment_start_ns[self.newest_index[0]]
        return (now_ns - start - self.newest_index[1] * period_ns) * 1e-9

    def close_window(self) -> None:
        """Stop recording the states of the window."""
        self.window = False

    def close(self) -> None:
        """Stop the spin thread, then the executor, the node and the context."""
        self._stop.set()
        self._thread.join(timeout=5)
        with contextlib.suppress(Exception):
            self.executor.shutdown()
        with contextlib.suppress(Exception):
            self.node.destroy_node()
        self.context.try_shutdown()


@dataclass
class StateFigures:
    """What the subscriber received over the window."""

    received: int
    seconds: float
    expected: int  # sample_index span(s) of the window
    pairs: int  # consecutive samples (k, k + 1 in one segment) both received
    gaps: int  # of those, stamps more than GAP_S apart
    worst_gap_s: float | None
    backwards: int  # of those, stamp of k + 1 not after k's
    skipped: int | None = None  # of the span, samples the plant skipped (declared, not published)
    late_s: tuple[float, float, float] | None = None  # stamp − due time: p50, p99, max
    block_samples: int = 0  # samples of the window's state blocks (their lateness)
    block_over_period: int = 0  # of those, later than one period (the plant's deadline miss)
    block_late_s: tuple[float, float, float] | None = None  # their lateness: p50, p99, max
    delivery_s: tuple[float, float, float] | None = None  # receipt − stamp: p50, p99, max
    skipped_from: str = "its state blocks"

    @property
    def rate(self) -> float:
        """States per second received."""
        return self.received / self.seconds if self.seconds > 0 else math.nan

    @property
    def span_share(self) -> float | None:
        """Received / the sample_index span (skipped samples included)."""
        return self.received / self.expected if self.expected else None

    @property
    def published(self) -> int:
        """Samples the plant published in the window: the span less what it skipped."""
        return self.expected - (self.skipped or 0)

    @property
    def received_share(self) -> float | None:
        """Received / published."""
        return self.received / self.published if self.published > 0 else None

    @property
    def gap_share(self) -> float | None:
        """Gaps / pairs."""
        return self.gaps / self.pairs if self.pairs else None


def state_figures(sub: Subscriber, seconds: float) -> StateFigures:
    """Counts, expected count from the sample_index span per segment, stamp gaps of the window."""
    stamps = np.asarray(sub.stamps, dtype=np.int64)
    indices = np.asarray(sub.indices, dtype=np.int64)
    segments = np.asarray(sub.segments, dtype=np.int64)
    received = np.asarray(sub.received_ns, dtype=np.int64)
    n = min(len(stamps), len(indices), len(segments), len(received))  # a callback may close late
    stamps, indices, segments, received = stamps[:n], indices[:n], segments[:n], received[:n]
    expected = 0
    skipped: int | None = None if sub.skips is None else 0
    for seg in np.unique(segments):
        idx = indices[segments == seg]
        low, high = int(idx.min()), int(idx.max())
        expected += high - low + 1
        if skipped is not None and sub.skips is not None:
            for s, a, b in list(sub.skips):  # the part of each declared gap inside the span
                if s == seg:
                    skipped += max(0, min(b, high) - max(a, low) + 1)
    lateness = np.asarray(sub.block_lateness, dtype=float)
    if len(stamps) < 2:
        figures = StateFigures(len(stamps), seconds, expected, 0, 0, None, 0, skipped)
        return _with_blocks(figures, lateness)
    delivery = (received - stamps) * 1e-9
    due = np.full(len(stamps), np.nan)
    for seg, (start, period_ns) in list(sub.segment_start_ns.items()):
        mask = segments == seg
        due[mask] = start + indices[mask] * period_ns
    late = (stamps - due)[np.isfinite(due)] * 1e-9
    consecutive = (np.diff(indices) == 1) & (segments[1:] == segments[:-1])
    step = np.diff(stamps)[consecutive] * 1e-9
    figures = StateFigures(
        received=len(stamps),
        seconds=seconds,
        expected=expected,
        pairs=int(consecutive.sum()),
        gaps=int((step > GAP_S).sum()),
        worst_gap_s=float(step.max()) if len(step) else None,
        backwards=int((step <= 0).sum()),
        skipped=skipped,
        late_s=_p50_p99_max(late),
        delivery_s=_p50_p99_max(delivery),
    )
    return _with_blocks(figures, lateness)


def _with_blocks(figures: StateFigures, lateness: np.ndarray) -> StateFigures:
    figures.block_samples = len(lateness)
    figures.block_over_period = int((lateness > 1.0 / SAMPLE_RATE_HZ).sum())
    figures.block_late_s = _p50_p99_max(lateness)
    return figures


def _p50_p99_max(x: np.ndarray) -> tuple[float, float, float] | None:
    if not len(x):
        return None
    p50, p99 = np.percentile(x, [50.0, 99.0])
    return float(p50), float(p99), float(x.max())


def _ms3(x: tuple[float, float, float] | None) -> str:
    return "n/a" if x is None else " / ".join(f"{1e3 * v:.2f}" for v in x) + " ms"


# ------------------------------------------------------------------------------------- a run


@dataclass
class RunResult:
    """The figures of one run (None where not measured)."""

    hogs: int
    load_start: str
    load_end: str = ""
    startup_s: float = math.nan
    first: dict[str, str] = field(default_factory=dict)
    last: dict[str, str] = field(default_factory=dict)
    window_s: float = math.nan
    states: StateFigures | None = None
    probe_lag_s: float | None = None  # now − stamp of the newest state
    probe_due_lag_s: float | None = None  # now − due time of the newest state
    cpu: dict[str, float] = field(default_factory=dict)
    cpu_count: dict[str, int] = field(default_factory=dict)
    vanished: int = 0
    own_cpu: float = math.nan
    floor: dict[str, Any] | None = None  # lubrig_testkit.wakeup over the window
    speed_s: float = math.nan  # python_speed() before the run
    plant_late: int = 0  # the window's samples later than one period (state blocks)
    explained: int = 0  # ... of which due while the bare loop was late too
    launcher_status: int | None = None
    error: str = ""

    def delta(self, key: str) -> float | None:
        """Last minus first value of a counter of the timing status (None if absent)."""
        a, b = number(self.first, key), number(self.last, key)
        return None if a is None or b is None else b - a

    @property
    def miss_share(self) -> float | None:
        """Deadline misses / ticks over the window."""
        misses, ticks = self.delta("deadline_misses"), self.delta("samples")
        return None if misses is None or not ticks else misses / ticks

    @property
    def total_cpu(self) -> float:
        """CPU s per wall s of the four nodes together."""
        return sum(self.cpu.get(role, 0.0) for role in ROLES)


def wait(condition: Callable[[], object], timeout: float, rig: Rig, what: str, every: float = 0.005) -> None:
    """Poll until condition holds; RuntimeError on timeout or if the launcher exits."""
    end = time.monotonic() + timeout
    while not condition():
        if not rig.running():
            raise RuntimeError(f"{what}: the launcher exited with status {rig.popen.returncode}")
        if time.monotonic() > end:
            raise RuntimeError(f"{what}: not within {timeout:g} s")
        time.sleep(every)


def next_timing(sub: Subscriber, rig: Rig, timeout: float, what: str) -> dict[str, str]:
    """Values of the next plant timing status to arrive."""
    seen = len(sub.timing)
    wait(lambda: len(sub.timing) > seen, timeout, rig, what)
    return sub.timing[-1][1]


def explained_by_floor(late_due_ns: list[int], floor_late: list[list[int]]) -> int:
    """How many late samples were due while the bare loop was late too (±1 period around its stall)."""
    period = round(1e9 / SAMPLE_RATE_HZ)
    spans = sorted((due - period, due + late + period) for due, late in floor_late)
    starts = [a for a, _ in spans]
    count = 0
    for t in late_due_ns:
        i = bisect.bisect_right(starts, t) - 1
        if any(a <= t <= b for a, b in spans[max(0, i - 8) : i + 1]):
            count += 1
    return count


def python_speed(iterations: int = 2_000_000) -> float:
    """Seconds this machine takes now for a fixed pure-Python loop (best of 3).

    CPU figures are CPU seconds of work; the same work costs more CPU seconds when the host is
    slower (other guests on the same cores, their caches). Printed with each run so that CPU
    figures of different runs or days can be compared in proportion.
    """
    best = math.inf
    for _ in range(3):
        t0, total = time.perf_counter(), 0
        for i in range(iterations):
            total += i
        best = min(best, time.perf_counter() - t0)
    return best


def start_floor(seconds: float) -> subprocess.Popen[str]:
    """The bare 1 kHz loop of lubrig_testkit.wakeup for `seconds`, one priority below the plant's."""
    priority = max(0, contract.DEFAULT_REALTIME_PRIORITY - 1)
    return subprocess.Popen(
        [sys.executable, "-m", "lubrig_testkit.wakeup", f"{seconds:g}", "--priority", str(priority)],
        stdout=subprocess.PIPE,
        text=True,
    )


def finish_floor(proc: subprocess.Popen[str]) -> dict[str, Any] | None:
    """The floor loop's figures (None if it failed)."""
    try:
        out, _ = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        return None
    with contextlib.suppress(ValueError):
        data: dict[str, Any] = json.loads(out.strip().splitlines()[-1])
        return data
    return None


def run_once(args: argparse.Namespace, run_dir: Path) -> RunResult:
    """One rig run with its steady window; the rig is stopped whatever happens."""
    result = RunResult(hogs=args.hogs, load_start=load_average(), speed_s=python_speed())
    lease = DomainLease()
    rig: Rig | None = None
    sub: Subscriber | None = None
    me = psutil.Process()
    try:
        env = ros_env(lease.domain)
        start = time.monotonic()
        rig_duration = args.startup_timeout + args.duration + 30.0  # the bench stops it first
        rig = Rig(run_dir, rig_duration, args.case, args.namespace, env)
        sub = Subscriber(lease.domain, args.namespace)
        r, s = rig, sub
        wait(r.nodes_up, args.startup_timeout, r, "node processes", every=0.2)
        wait(lambda: s.states > 0, args.startup_timeout, r, f"states on {args.namespace}/state")
        wait(lambda: s.analysis_seen, args.startup_timeout, r, "a status of the analysis")
        result.first = next_timing(s, r, 10.0, "the plant's timing status")
        cpu0, own0 = cpu_snapshot(r), sum(me.cpu_times()[:2])
        floor = start_floor(args.duration)
        s.open_window()
        result.startup_s = cpu0.wall - start
        end = cpu0.wall + args.duration
        while time.monotonic() < end:
            if not r.running():
                raise RuntimeError(f"the launcher exited with status {r.popen.returncode} in the window")
            time.sleep(0.1)
        result.last = next_timing(s, r, 10.0, "the plant's timing status at the end")
        cpu1, own1 = cpu_snapshot(r), sum(me.cpu_times()[:2])
        s.close_window()
        now_ns = time.time_ns()  # ROS time of a realtime node = system time
        if s.newest_stamp_ns is not None:
            result.probe_lag_s = (now_ns - s.newest_stamp_ns) * 1e-9
        result.probe_due_lag_s = s.newest_due_lag_s(now_ns)
        result.window_s = cpu1.wall - cpu0.wall
        result.states = state_figures(s, result.window_s)
        skipped = result.delta("skipped_samples")  # older messages: from the plant's status
        if result.states.skipped is None and skipped is not None:
            result.states.skipped, result.states.skipped_from = round(skipped), "the plant's status"
        result.cpu, result.cpu_count, result.vanished = cpu_per_role(cpu0, cpu1)
        result.own_cpu = (own1 - own0) / result.window_s
        result.floor = finish_floor(floor)
        if result.floor is not None:
            result.explained = explained_by_floor(s.late_due_ns, result.floor["late_ticks"])
            result.plant_late = len(s.late_due_ns)
    except RuntimeError as exc:
        result.error = str(exc) + ("\n" + rig.log_tails() if rig is not None else "")
    finally:
        try:
            if sub is not None:
                sub.close()
        finally:
            if rig is not None:
                result.launcher_status = rig.stop()
            lease.close()
            result.load_end = load_average()
    return result


def print_run(k: int, repeat: int, args: argparse.Namespace, res: RunResult) -> None:
    """The figures of one run with the targets beside them."""
    hogs = f"{res.hogs} CPU hog(s)" if res.hogs else "quiet (no CPU hog)"
    label = {0: "quiet", 1: "one hog"}.get(res.hogs, "two hogs" if res.hogs == 2 else f"{res.hogs} hogs")
    print(f"run {k}/{repeat}: realtime 1 kHz, case {args.case}, rig with recording, {hogs}")
    print(f"  load average (1/5/15 min) at start {res.load_start}, at end {res.load_end}")
    print(f"  machine speed: a 2,000,000-iteration Python loop took {1e3 * res.speed_s:.0f} ms (best of 3)")
    if res.error:
        print(f"  run failed: {res.error}")
        print(f"  launcher exit status {res.launcher_status}")
        return
    print(f"  steady window {res.window_s:.2f} s, opened {res.startup_s:.1f} s after the launcher started")
    ticks, misses = res.delta("samples"), res.delta("deadline_misses")
    share = res.miss_share
    target = MISS_TARGET_PERCENT[min(res.hogs, 2)]
    ok = None if share is None else 100 * share < target
    print(
        f"  deadline misses in the window: {fmt(misses, digits=0)} of {fmt(ticks, digits=0)} ticks"
        f" = {fmt(share, 100, 3, '%')}   target < {target:g} % ({label}): {verdict(ok)}"
    )
    print(f"  {floor_text(res.floor)}")
    if res.floor is not None:
        print(
            f"    of the window's {res.plant_late} samples later than one period, {res.explained} were due"
            " while the bare loop was late too (the host's stalls); the rest are the rig's own"
        )
    samples, total = number(res.last, "samples"), number(res.last, "deadline_misses")
    whole = None if not samples or total is None else total / samples
    print(
        f"  deadline misses, whole run incl. start-up: {fmt(total, digits=0)} of {fmt(samples, digits=0)}"
        f" = {fmt(whole, 100, 3, '%')}; tick overruns {res.last.get('tick_overruns', 'n/a')}"
    )
    st = res.states
    if st is not None and st.block_samples:
        print(
            f"  lateness of the window's samples (the plant's state blocks), p50 / p99 / max:"
            f" {_ms3(st.block_late_s)}; later than one period {st.block_over_period} of {st.block_samples}"
            f" = {100 * st.block_over_period / st.block_samples:.3f} %"
        )
    print(f"  worst lateness (plant, whole run): {fmt(number(res.last, 'max_lateness_s'), 1e3, 2, 'ms')}")
    print(
        f"  band -> state latency in the plant: p50 {fmt(number(res.last, 'latency_p50_s'), 1e3, 3, 'ms')},"
        f" p99 {fmt(number(res.last, 'latency_p99_s'), 1e3, 3, 'ms')}"
    )
    lag = number(res.last, "lag_s")
    lag_ok = None if lag is None else lag < LAG_TARGET_S
    print(
        f"  lag of rig time behind wall time at the end (plant lag_s): {fmt(lag, 1e3, 2, 'ms')}"
        f"   target < {LAG_TARGET_S * 1e3:g} ms (two hogs): {verdict(lag_ok)}"
    )
    print(
        f"    max_lag_s {fmt(number(res.last, 'max_lag_s'), 1e3, 2, 'ms')}, lag_bound_s"
        f" {fmt(number(res.last, 'lag_bound_s'), 1e3, 2, 'ms')},"
        f" lag_policy {res.last.get('lag_policy', 'n/a')},"
        f" skipped_samples {res.last.get('skipped_samples', 'n/a')}"
        f" (in the window {fmt(res.delta('skipped_samples'), digits=0)})"
    )
    print(
        f"    cross-check at the subscriber: now - due time of the newest state"
        f" {fmt(res.probe_due_lag_s, 1e3, 2, 'ms')}; now - its stamp {fmt(res.probe_lag_s, 1e3, 2, 'ms')}"
    )
    if st is not None:
        rec_ok = None if st.received_share is None else 100 * st.received_share >= RECEIVED_TARGET_PERCENT
        print(
            f"  separate subscriber: {st.received} states in {st.seconds:.2f} s = {st.rate:.1f} states/s"
            f" (window x 1 kHz = {st.seconds * SAMPLE_RATE_HZ:.0f})"
        )
        print(
            f"    received {st.received} of {st.published} published = {fmt(st.received_share, 100, 3, '%')}"
            f"   target >= {RECEIVED_TARGET_PERCENT:g} % (one hog): {verdict(rec_ok)}"
        )
        skipped = "n/a" if st.skipped is None else str(st.skipped)
        print(
            f"    (published = the window's sample_index span {st.expected} less {skipped} skipped by the"
            f" plant, from {st.skipped_from}; of the span: {fmt(st.span_share, 100, 3, '%')})"
        )
        gap_ok = None if st.gap_share is None else 100 * st.gap_share <= GAP_TARGET_PERCENT
        print(
            f"  consecutive state stamps > {GAP_S * 1e3:g} ms apart: {st.gaps} of {st.pairs}"
            f" = {fmt(st.gap_share, 100, 3, '%')}, worst {fmt(st.worst_gap_s, 1e3, 2, 'ms')},"
            f" not increasing {st.backwards}   target <= {GAP_TARGET_PERCENT:g} %: {verdict(gap_ok)}"
        )
        print(
            f"    states at the subscriber, p50 / p99 / max: computed after their due time (stamp - due)"
            f" {_ms3(st.late_s)}; delivered after computed (receipt - stamp) {_ms3(st.delivery_s)}"
        )
    parts = [f"{role} {res.cpu.get(role, 0.0):.3f}" for role in ROLES if role != "recorder"]
    parts.append(
        f"recorder ({res.cpu_count.get('recorder', 0)} processes) {res.cpu.get('recorder', 0.0):.3f}"
    )
    print(
        f"  CPU s per wall s: {', '.join(parts)}; total {res.total_cpu:.3f} cores"
        f"   target <= {CPU_TARGET_CORES:g}: {verdict(res.total_cpu <= CPU_TARGET_CORES)}"
    )
    others = [f"{role} {v:.3f}" for role, v in sorted(res.cpu.items()) if role not in ROLES]
    print(
        f"    not in the total: {', '.join(others) or 'nothing else'}; this subscriber {res.own_cpu:.3f}"
        + (f"; {res.vanished} process(es) ended inside the window (not counted)" if res.vanished else "")
    )
    print(f"  rig stopped (SIGINT to the launcher): exit status {res.launcher_status}")


def floor_text(floor: dict[str, Any] | None) -> str:
    """One line: the bare loop's late wake-ups and the host's steal time in the window."""
    if floor is None:
        return "machine floor: not measured (lubrig_testkit.wakeup failed)"
    late, ticks = floor["late"], floor["ticks"]
    steal = floor.get("steal_share")
    how = ("SCHED_FIFO" if floor["fifo"] else "normal scheduling") + (
        ", latency request" if floor["latency_request"] else ""
    )
    return (
        f"machine floor in the window: a bare 1 kHz loop ({how}) woke > 1 period late {late} of {ticks}"
        f" = {100 * late / ticks:.3f} %, worst {1e3 * floor['worst_s']:.2f} ms;"
        f" host steal {fmt(steal, 100, 3, '%')} of CPU time"
    )


def print_summary(results: list[RunResult]) -> None:
    """One line per run: the headline figures."""
    print(
        "summary (window misses %, end lag ms: plant / subscriber (due time), received %, gaps %,"
        " CPU cores of the four nodes, the bare loop's late wake-ups %):"
    )
    for k, res in enumerate(results, 1):
        if res.error:
            print(f"  run {k}: failed")
            continue
        st = res.states
        received = fmt(st.received_share if st else None, 100, 3)
        gaps = fmt(st.gap_share if st else None, 100, 3)
        print(
            f"  run {k}: misses {fmt(res.miss_share, 100, 3)}  lag {fmt(number(res.last, 'lag_s'), 1e3, 2)}"
            f" / {fmt(res.probe_due_lag_s, 1e3, 2)}  received {received}  gaps {gaps}"
            f"  CPU {res.total_cpu:.3f}  floor {floor_share(res.floor)}"
            f"  load {res.load_start} -> {res.load_end}"
        )


def floor_share(floor: dict[str, Any] | None) -> str:
    """The bare loop's late share in percent (n/a if not measured)."""
    return "n/a" if floor is None else f"{100 * floor['late'] / floor['ticks']:.3f}"


def rig_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of the rig a bench runs (shared with bench_soak)."""
    parser.add_argument("--hogs", type=int, default=0, help="CPU hogs beside the rig (default 0)")
    parser.add_argument("--case", type=int, default=1, help="study case (default 1)")
    parser.add_argument("--namespace", default=contract.DEFAULT_NAMESPACE, help="rig namespace")
    parser.add_argument(
        "--startup-timeout", type=float, default=120.0, help="limit for the rig's start-up, s (default 120)"
    )
    parser.add_argument("--keep", type=Path, help="keep the run folders under this directory")


def main() -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--duration", type=float, default=60.0, help="steady window, s (default 60)")
    parser.add_argument("--repeat", type=int, default=1, help="runs (default 1)")
    rig_arguments(parser)
    args = parser.parse_args()
    if args.duration <= 0 or args.hogs < 0 or args.repeat < 1:
        parser.error("expected --duration > 0, --hogs >= 0, --repeat >= 1")
    stop_on_signals()
    results: list[RunResult] = []
    with contextlib.ExitStack() as stack:
        if args.keep is not None:
            base = args.keep.resolve()
            base.mkdir(parents=True, exist_ok=True)
        else:
            base = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="bench_realtime_")))
        stack.enter_context(cpu_hogs(args.hogs))
        for k in range(1, args.repeat + 1):
            res = run_once(args, base / f"run{k}")
            results.append(res)
            print_run(k, args.repeat, args, res)
        if args.repeat > 1:
            print_summary(results)
        if args.keep is not None:
            print(f"run folders in {base}")
    return 0 if any(not r.error for r in results) else 1


if __name__ == "__main__":
    try:
        sys.exit(main())
    except KeyboardInterrupt:
        print("bench: interrupted; rig and hogs stopped", file=sys.stderr)
        sys.exit(130)
