"""A test run killed outright (SIGKILL, no teardown) leaves none of the processes it started."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

PARENT = textwrap.dedent(
    """
    import sys, time
    from pathlib import Path
    from lubrig_testkit.harness import Processes
    procs = Processes(dict(__import__("os").environ), Path(sys.argv[1]))
    child = procs.command("sleeper", [sys.executable, "-c", "import time; time.sleep(600)"])
    print(child.pid, flush=True)
    time.sleep(600)
    """
)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    stat = Path(f"/proc/{pid}/stat")
    return not (stat.exists() and stat.read_text().split(") ")[1].startswith("Z"))


def test_a_child_of_procs_ends_when_the_test_process_is_killed(tmp_path: Path) -> None:
    parent = subprocess.Popen(
        [sys.executable, "-c", PARENT, str(tmp_path / "logs")], stdout=subprocess.PIPE, text=True
    )
    child = 0
    try:
        assert parent.stdout is not None
        child = int(parent.stdout.readline())
        assert _alive(child)
        parent.send_signal(signal.SIGKILL)
        parent.wait(timeout=60)
        deadline = time.monotonic() + 60  # a guard against a hang, not a speed
        while _alive(child) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not _alive(child), f"process {child} outlived the process that started it"
    finally:
        parent.kill()
        parent.wait()
        if child and _alive(child):
            os.kill(child, signal.SIGKILL)


IGNORES_SIGINT = textwrap.dedent(
    """
    import faulthandler, signal, time
    faulthandler.register(signal.SIGUSR1)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    print("ready", flush=True)
    time.sleep(600)
    """
)


def test_a_process_that_does_not_stop_is_killed_with_its_stacks_shown(tmp_path: Path, capsys) -> None:
    """stop_all: a process ignoring SIGINT ends as -9, its signal state and stacks on stderr."""
    from lubrig_testkit.harness import Processes

    procs = Processes(dict(os.environ), tmp_path)
    stubborn = procs.command("stubborn", [sys.executable, "-c", IGNORES_SIGINT])
    stubborn.wait_for_output("ready", 60)
    assert procs.stop_all(timeout=1.0) == {"stubborn": -signal.SIGKILL}
    err = capsys.readouterr().err
    assert "stubborn did not stop within 1 s of SIGINT (SigQ:" in err
    assert "SigIgn:" in err and 'File "<string>", line 6' in err  # its Python stack (faulthandler)
    assert not _alive(stubborn.pid)
