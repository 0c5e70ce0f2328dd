"""`lubrig rig`'s processes: start them, wait for their start lines, watch them, stop them.

Whatever phase a process fails in — start-up, the run, shutdown — the supervisor names it and
says why: its exit status (or the signal that killed it) and the first error line of its log
(`first_error_line`). It watches every process while it waits for any one of them, so a plant
killed while the launcher waits for the recorder is named at once as the plant.

Stopping is bounded: SIGINT, then after `grace` s SIGUSR1 (the node writes its Python stacks to
its log: nodes/entry.py) and SIGTERM, then after TERM_GRACE_S SIGKILL; each escalation is said on
stderr and the process is reported as not having stopped.
"""

from __future__ import annotations

import contextlib
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from ..app.processes.lifetime import die_with_parent
from ..app.processes.rig_plan import CLEAN_EXITS, READY_LINES

if TYPE_CHECKING:
    from .rig_gate import StartGate

#: Set by the launcher's SIGINT handler (catch_ctrl_c) before it raises KeyboardInterrupt.
CTRL_C = threading.Event()


def catch_ctrl_c() -> None:
    """SIGINT sets CTRL_C, then raises KeyboardInterrupt (main thread only; else nothing changes).

    The exception alone can be lost: raised while the main thread waits inside rclpy's executor,
    it may be cleared there, and the launcher would go on and take the nodes, which had the same
    Ctrl-C from the terminal and ended cleanly, for failed processes. The event stays set.
    """

    def handler(_signum: int, _frame: object) -> None:
        CTRL_C.set()
        raise KeyboardInterrupt

    CTRL_C.clear()
    with contextlib.suppress(ValueError):
        signal.signal(signal.SIGINT, handler)


#: s a node gets after SIGINT before SIGTERM.
GRACE_S = 10.0
#: s a node gets after SIGTERM before SIGKILL.
TERM_GRACE_S = 5.0
#: Longest wait for a process's start line (a guard against a hang, not an expected duration).
READY_S = 60.0
#: How an error shows in a node log, most telling first: the node's own fatal or error line
#: (rclpy's "[FATAL]", a script's "prog: error: …"), then rclpy's and the middleware's errors.
ERROR_MARKERS: tuple[tuple[str, ...], ...] = (
    ("[FATAL]", ": error:"),
    ("[ERROR]", "Traceback", "Error"),
    ("error",),
)


class RigProcessError(Exception):
    """A process of the rig failed; the message names it, how and why (one line)."""


@dataclass(frozen=True)
class Exit:
    """A process that ended: its name, exit status, the phase it ended in, its stop escalation."""

    name: str
    status: int
    phase: str
    escalated: str = ""


def first_error_line(log: Path) -> str | None:
    """The first line of `log` that shows an error (ERROR_MARKERS, most telling kind first)."""
    lines = log.read_text(errors="replace").splitlines() if log.is_file() else []
    for markers in ERROR_MARKERS:
        for line in lines:
            if any(m in line for m in markers):
                return line.strip()
    return None


def describe_status(status: int) -> str:
    """'exited with status 1' or 'was killed by SIGKILL'."""
    if status < 0:
        with contextlib.suppress(ValueError):
            return f"was killed by {signal.Signals(-status).name}"
    return f"exited with status {status}"


def _die_with_launcher() -> None:
    """In a node process before exec: SIGTERM when the launcher ends, however it ends.

    SIGTERM, not SIGKILL: the node stops as on `lubrig rig`'s own stop (the recorder finalizes
    the bag); the recorder's helpers are killed with the recorder (nodes/recorder_forkserver.py).
    """
    die_with_parent(signal.SIGTERM)


def _dump_stacks(name: str, proc: subprocess.Popen, grace: float) -> None:
    """A node that ignored SIGINT: SIGUSR1 makes it write its threads' stacks to its log."""
    print(
        f"lubrig rig: {name} did not stop within {grace:g} s of SIGINT; its Python stacks go to "
        "its log (SIGUSR1), then SIGTERM",
        file=sys.stderr,
    )
    try:
        proc.send_signal(signal.SIGUSR1)  # nodes.entry registers faulthandler for it
        proc.wait(timeout=0.5)
    except (subprocess.TimeoutExpired, ProcessLookupError):
        pass


def stop_all(
    procs: dict[str, subprocess.Popen], grace: float = GRACE_S, escalated: dict[str, str] | None = None
) -> dict[str, int]:
    """SIGINT every running process, wait, then SIGTERM (and SIGKILL) what is left; exit statuses.

    `escalated` (if given) gets, per process that had to be escalated, what it took.
    """
    for proc in procs.values():
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
    codes: dict[str, int] = {}
    end = time.monotonic() + grace
    for name, proc in procs.items():
        try:
            codes[name] = proc.wait(timeout=max(0.1, end - time.monotonic()))
            continue
        except subprocess.TimeoutExpired:
            _dump_stacks(name, proc, grace)
        proc.terminate()
        how = f"did not stop within {grace:g} s of SIGINT (SIGTERM)"
        try:
            codes[name] = proc.wait(timeout=TERM_GRACE_S)
        except subprocess.TimeoutExpired:
            print(
                f"lubrig rig: {name} did not stop within {TERM_GRACE_S:g} s of SIGTERM either; SIGKILL",
                file=sys.stderr,
            )
            proc.kill()
            codes[name] = proc.wait()
            how = f"did not stop within {grace:g} s of SIGINT nor {TERM_GRACE_S:g} s of SIGTERM (SIGKILL)"
        if escalated is not None:
            escalated[name] = how
    return codes


class Supervisor:
    """The rig's processes, each with its log in `logs`/<name>.log (see module docstring)."""

    def __init__(
        self,
        logs: Path,
        env: dict[str, str],
        gate: StartGate | None = None,
        admit: Callable[[], Path] | None = None,
    ) -> None:
        """Processes in `logs`, with `env`; a start gate if `gate` and `admit` are given.

        Processes started before the first wait are held at `gate` (cli/rig_gate.py); that wait
        calls `admit` first, which opens it (or raises) and returns where the logs are from then on.
        """
        self.logs, self.env = logs, env
        self.gate, self.admit = gate, admit
        self.procs: dict[str, subprocess.Popen] = {}
        self.exits: dict[str, Exit] = {}
        self.phase = "start-up"

    def log(self, name: str) -> Path:
        """The log file of process `name`."""
        return self.logs / f"{name}.log"

    def start(self, name: str, argv: list[str]) -> None:
        """Start `argv` as process `name`, output to its log; it dies with the launcher."""
        env = self.env
        fds: tuple[int, ...] = ()
        if self.gate is not None and not self.gate.done:
            env, fds = self.gate.child_env(self.env), (self.gate.read,)
        with open(self.log(name), "w") as log:
            self.procs[name] = subprocess.Popen(
                argv,
                env=env,
                stdout=log,
                stderr=subprocess.STDOUT,
                preexec_fn=_die_with_launcher,
                pass_fds=fds,
            )

    def open_gate(self) -> None:
        """Admit the held processes (once; see __init__)."""
        if self.admit is not None:
            admit, self.admit = self.admit, None
            self.logs = admit()

    def ended(self) -> list[Exit]:
        """Processes that have ended (first seen ending first); each is recorded with its phase."""
        for name, proc in self.procs.items():
            status = proc.poll()
            if status is not None and name not in self.exits:
                self.exits[name] = Exit(name, status, self.phase)
        return list(self.exits.values())

    def failure(self, gone: Exit) -> str:
        """One line: which process failed, in which phase, how, and why (its first error line)."""
        log = self.log(gone.name)
        said = first_error_line(log)
        why = f": {said}" if said else f"; no error line in its log {log}"
        how = gone.escalated or describe_status(gone.status)
        return f"{gone.name} {how} during {gone.phase}{why}"

    def check(self, allowed: Callable[[Exit], bool] = lambda _e: False) -> None:
        """RigProcessError naming the first process that has ended, unless `allowed` says it may."""
        for gone in self.ended():
            if not allowed(gone):
                raise RigProcessError(self.failure(gone))

    def wait_ready(self, name: str, limit: float = READY_S) -> None:
        """Wait for process `name`'s start line (READY_LINES) while watching every process.

        RigProcessError naming the process that ended meanwhile (whichever it is), or `name` if its
        line has not come within `limit` s.
        """
        self.open_gate()
        key = "plant" if name == "plant_loop" else name
        end = time.monotonic() + limit
        while READY_LINES[name] not in self.log(key).read_text(errors="replace"):
            self.check()
            if time.monotonic() > end:
                raise RigProcessError(
                    f"{key} not ready after {limit:g} s (no {READY_LINES[name]!r} line); see {self.log(key)}"
                )
            time.sleep(0.05)

    def stop(self, names: list[str], grace: float) -> None:
        """Stop processes `names` (those still running); their exits recorded as of the shutdown."""
        self.ended()
        running = {n: self.procs[n] for n in names if n in self.procs and n not in self.exits}
        escalated: dict[str, str] = {}
        codes = stop_all(running, grace, escalated)
        for name, status in codes.items():
            self.exits[name] = Exit(name, status, "shutdown", escalated.get(name, ""))

    def failures_at_shutdown(self, allowed: Callable[[Exit], bool]) -> list[str]:
        """One line per process that did not stop cleanly on the launcher's stop."""
        return [
            self.failure(e)
            for e in self.exits.values()
            if e.phase == "shutdown" and (e.escalated or e.status not in CLEAN_EXITS) and not allowed(e)
        ]
