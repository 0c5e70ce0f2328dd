"""A node process can neither hang for good in its middleware teardown nor hide where it hangs.

Fast DDS's participant deletion was seen to block for good at the end of short `lubrig rig` runs
(the plant or the recorder in Node.destroy_node until the launcher's SIGKILL, exit -9; 3 of 28
runs). Two guards, tested here with plain processes that block the same way (in a call Python
cannot interrupt): bounded_teardown ends the process after its time with the node's own exit
status and one line saying why, and the launcher's stop_all asks a node that ignores SIGINT for
its Python stacks (SIGUSR1, faulthandler registered by nodes.entry) before SIGTERM.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

from lubrig_ros.cli.rig import stop_all

BLOCKED_TEARDOWN = textwrap.dedent(
    """
    import sys, threading
    from lubrig_ros.nodes.script import bounded_teardown
    print("work done", flush=True)
    with bounded_teardown("plant", lambda: {status}, seconds=0.5):
        threading.Event().wait()  # never returns, as a hung participant deletion
    print("not reached", flush=True)
    """
)


def _python(code: str) -> subprocess.CompletedProcess:
    """`code` run by this interpreter in a process of its own, its output captured."""
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False
    )


def test_a_hung_teardown_ends_the_process_with_the_node_status() -> None:
    for status in (0, 3):
        done = _python(BLOCKED_TEARDOWN.format(status=status))
        assert done.returncode == status
        assert done.stdout == "work done\n"
        assert done.stderr.splitlines() == [
            "plant: middleware teardown did not finish within 0.5 s (a known Fast DDS "
            "participant-deletion hang); exiting without it"
        ]


def test_a_teardown_that_blocks_holding_the_gil_still_ends_with_the_node_status() -> None:
    """As rclpy's C++ handles can: libc sleep called through PyDLL keeps the GIL for its duration."""
    code = textwrap.dedent(
        """
        import ctypes
        from lubrig_ros.nodes.script import bounded_teardown
        print("work done", flush=True)
        def destroy_handle_holding_the_gil():
            ctypes.PyDLL(None).sleep(600)
        with bounded_teardown("plant", lambda: {status}, seconds=0.3):
            destroy_handle_holding_the_gil()
        print("not reached", flush=True)
        """
    )
    for status in (0, 3):
        start = time.monotonic()
        done = _python(code.format(status=status))
        assert time.monotonic() - start < 60  # not the 600 s of the blocked call
        assert done.returncode == status, done.stderr
        assert done.stdout == "work done\n"
        assert "destroy_handle_holding_the_gil" in done.stderr, done.stderr  # where it hung


def test_a_teardown_that_finishes_is_not_touched() -> None:
    code = textwrap.dedent(
        """
        import time
        from lubrig_ros.nodes.script import bounded_teardown
        with bounded_teardown("plant", lambda: 5, seconds=0.5):
            pass
        time.sleep(1.0)  # past the limit: the timer was cancelled
        print("exited normally", flush=True)
        """
    )
    done = _python(code)
    assert (done.returncode, done.stdout, done.stderr) == (0, "exited normally\n", "")


def test_the_launcher_gets_the_stacks_of_a_node_that_ignores_sigint(tmp_path: Path, capsys) -> None:
    wedged = textwrap.dedent(
        """
        import faulthandler, signal, threading
        faulthandler.register(signal.SIGUSR1, all_threads=True)  # as nodes.entry does
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        print("ready", flush=True)
        def stuck_in_destroy_node():
            threading.Event().wait()
        stuck_in_destroy_node()
        """
    )
    log = tmp_path / "plant.log"
    with log.open("w") as out:
        proc = subprocess.Popen([sys.executable, "-c", wedged], stdout=out, stderr=subprocess.STDOUT)
        for _ in range(600):
            if log.read_text() == "ready\n":
                break
            time.sleep(0.05)
        codes = stop_all({"plant": proc}, grace=0.5)
    assert codes == {"plant": -signal.SIGTERM}
    text = log.read_text()
    assert "most recent call first" in text and "stuck_in_destroy_node" in text
    assert "plant did not stop within 0.5 s of SIGINT" in capsys.readouterr().err
