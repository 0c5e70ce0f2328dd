"""`lubrig rig`'s start gate and staged run folder (cli/rig_gate.py), with real child processes.

A process started at the gate waits there (after its imports) until the launcher opens it, and
ends with status 0 without going on when the launcher shuts it (the namespace is taken); the
run folder appears only when the staged files are placed, and the logs a held process already
writes to move with it.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

from lubrig_ros.cli.rig_gate import StagedRunDir, StartGate

# a stand-in for a node's entry point: says it is held, passes the gate or not, says so
CHILD = """
import sys
from lubrig_ros.nodes.entry import pass_start_gate
print("held", flush=True)
went_on = pass_start_gate()
print("went on" if went_on else "stopped at the gate", flush=True)
"""


def _held(gate: StartGate, log: Path) -> subprocess.Popen:
    with open(log, "w") as out:
        env = gate.child_env({"PATH": "/usr/bin:/bin"})
        argv = [sys.executable, "-c", CHILD]
        return subprocess.Popen(argv, env=env, stdout=out, stderr=subprocess.STDOUT, pass_fds=(gate.read,))


def _wait_for(log: Path, text: str) -> None:
    end = time.monotonic() + 60
    while text not in log.read_text():
        assert time.monotonic() < end, log.read_text()
        time.sleep(0.05)


def test_held_processes_go_on_once_the_gate_opens_and_their_logs_move_with_the_run_folder(tmp_path):
    run_dir = tmp_path / "runs" / "one"  # neither it nor its parent exists yet
    staged = StagedRunDir(run_dir)
    assert staged.path.parent == tmp_path and not run_dir.exists()
    (staged.path / "run_config.yaml").write_text("name: x\n")
    gate = StartGate()
    procs = [_held(gate, staged.path / "logs" / f"p{i}.log") for i in range(3)]
    for i in range(3):
        _wait_for(staged.path / "logs" / f"p{i}.log", "held")
    time.sleep(0.3)
    assert all(p.poll() is None for p in procs)  # waiting at the gate
    staged.place()
    gate.open()
    assert [p.wait(timeout=60) for p in procs] == [0, 0, 0]
    assert not staged.path.exists() and (run_dir / "run_config.yaml").read_text() == "name: x\n"
    for i in range(3):  # written after the move, into the moved file
        assert (run_dir / "logs" / f"p{i}.log").read_text().split() == ["held", "went", "on"]


def test_a_shut_gate_stops_the_held_processes_and_leaves_nothing(tmp_path):
    run_dir = tmp_path / "taken"
    staged = StagedRunDir(run_dir)
    gate = StartGate()
    proc = _held(gate, staged.path / "logs" / "p.log")
    _wait_for(staged.path / "logs" / "p.log", "held")
    gate.shut()
    staged.discard()
    assert proc.wait(timeout=60) == 0
    assert list(tmp_path.iterdir()) == []


def test_an_existing_run_folder_keeps_its_files_and_gets_the_staged_ones(tmp_path):
    (tmp_path / "logs").mkdir()
    (tmp_path / "logs" / "old.log").write_text("old")
    (tmp_path / "notes.txt").write_text("mine")
    staged = StagedRunDir(tmp_path)
    assert staged.path.parent == tmp_path  # inside the folder: the same file system
    (staged.path / "logs" / "plant.log").write_text("new")
    staged.place()
    names = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*"))
    assert names == ["logs", "logs/old.log", "logs/plant.log", "notes.txt"]
