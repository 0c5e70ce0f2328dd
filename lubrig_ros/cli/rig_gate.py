"""`lubrig rig`'s start gate: the node processes import while the launcher checks the namespace.

Start-up is CPU-bound (four processes importing rclpy, numpy, numba and the session layers on
two cores), and the namespace check (cli/rig_ros.py) watches the ROS graph for GRAPH_SETTLE_S
of discovery, mostly asleep. So the launcher starts the first processes at once, each held at
the gate (nodes/entry.py: after its imports, before it builds anything or joins the graph), runs
the check meanwhile, and only then opens the gate:

- the namespace is free: the run folder is put in place (`StagedRunDir.place`: the staged
  run_config.yaml and logs move into it) and each held process gets its byte;
- it is taken: the gate is closed (each held process reads end of file and exits 0 without
  having joined the graph), the staged folder is removed, and the refusal is raised; nothing was
  written where the run would have gone and no node of this rig was ever on the graph.

The staging folder lies in the run folder's nearest existing ancestor (the run folder itself
when it exists), on the file system the run folder will be on, so that the logs the held
processes already write to can be moved by rename.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from ..app.processes.startup_trace import mark
from ..nodes.entry import GATE_VARIABLE
from .main import CommandError
from .rig_ros import LauncherPresence, namespace_taken


class StartGate:
    """A pipe the held processes read one byte from (nodes/entry.py `pass_start_gate`)."""

    def __init__(self) -> None:
        self.read, self.write = os.pipe()
        self.held = 0
        self.done = False

    def child_env(self, env: dict[str, str]) -> dict[str, str]:
        """`env` for a process started while the gate is shut (counted as held)."""
        self.held += 1
        return {**env, GATE_VARIABLE: str(self.read)}

    def open(self) -> None:
        """Let every held process go on."""
        self._end(b"1" * self.held)

    def shut(self) -> None:
        """Every held process reads end of file and exits without starting."""
        self._end(b"")

    def _end(self, data: bytes) -> None:
        if self.done:
            return
        self.done = True
        if data:
            os.write(self.write, data)  # a few bytes: never more than the pipe holds
        os.close(self.write)
        os.close(self.read)


class StagedRunDir:
    """Where run_config.yaml and the logs are written until the namespace check has passed."""

    def __init__(self, run_dir: Path) -> None:
        self.run_dir = run_dir
        anchor = run_dir
        while not anchor.is_dir():
            anchor = anchor.parent
        self.path = anchor / f".lubrig-rig-starting-{os.getpid()}"
        self.path.mkdir()
        (self.path / "logs").mkdir()
        self.placed = False

    def place(self) -> None:
        """Move the staged files into the run folder (created, with logs/), remove the staging."""
        (self.run_dir / "logs").mkdir(parents=True, exist_ok=True)
        for staged in sorted(self.path.rglob("*")):
            if staged.is_file():
                os.replace(staged, self.run_dir / staged.relative_to(self.path))
        shutil.rmtree(self.path)
        self.placed = True

    def discard(self) -> None:
        """Remove the staging folder and what is in it."""
        shutil.rmtree(self.path, ignore_errors=True)


def set_aside(bag_dir: Path) -> None:
    """Keep the previous recording of this DIR as bag.previous (the recorder needs a new path)."""
    if not bag_dir.exists():
        return
    previous = bag_dir.with_name(bag_dir.name + ".previous")
    if previous.exists():
        shutil.rmtree(previous)
    bag_dir.rename(previous)
    print(f"lubrig rig: previous bag moved to {previous}")


def admit_run(presence: LauncherPresence, gate: StartGate, staged: StagedRunDir, recorded: bool) -> Path:
    """The namespace check, while the held processes import; then the gate opens (or shuts).

    Taken: the held processes end without starting, nothing is left in the run folder's place,
    CommandError naming the rig there. Free: the run folder in place, the logs' folder returned.
    The presence stays on the graph either way (the caller closes it).
    """
    mark("launcher", "namespace check begins")
    try:
        taken = namespace_taken(presence)
    except BaseException:
        gate.shut()
        staged.discard()
        raise
    mark("launcher", "namespace check ends")
    if taken:
        gate.shut()
        staged.discard()
        raise CommandError(taken)
    if recorded:
        set_aside(staged.run_dir / "bag")
    staged.place()
    gate.open()
    return staged.run_dir / "logs"
