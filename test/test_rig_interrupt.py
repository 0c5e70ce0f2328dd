"""Ctrl-C in a terminal during `lubrig rig`: SIGINT to the whole process group (issue 11).

Every process of the rig gets the signal at once, as from a terminal. Asserted: no traceback
anywhere (launcher output and every node log), the launcher says it was interrupted (no "nan s")
and exits 130, and the bag it leaves is readable with every recorded sample in order.
"""

from __future__ import annotations

import contextlib
import os
import signal
import time

import pytest
from lubrig_testkit.cli import start_long_rig

from lubrig_ros.bag.verify import verify_bag

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def test_ctrl_c_stops_the_rig_cleanly(ros_env, tmp_path):
    run = tmp_path / "run"
    launcher = start_long_rig(ros_env, run, new_session=True)
    try:
        time.sleep(4.0)  # samples flowing
        os.killpg(launcher.pid, signal.SIGINT)  # the terminal's Ctrl-C: the whole group
        out, err = launcher.communicate(timeout=120)
    finally:
        if launcher.poll() is None:
            os.killpg(launcher.pid, signal.SIGKILL)
    assert launcher.returncode == 130, f"exit status {launcher.returncode}\nstdout:\n{out}\nstderr:\n{err}"
    assert "interrupted before the run ended" in out and "nan" not in out, out
    assert "Traceback" not in out + err, (out, err)
    for log in (run / "logs").glob("*.log"):
        assert "Traceback" not in log.read_text(), (log.name, log.read_text()[-2000:])
    result = verify_bag(run / "bag")
    assert not result.structural, result.problems
    assert not result.problems, result.problems  # gap-free, in order


def test_sigkill_of_the_launcher_takes_every_rig_process_with_it(ros_env, tmp_path):
    """No process of the rig outlives `lubrig rig`, even killed by a signal it cannot handle."""
    import psutil

    launcher = start_long_rig(ros_env, tmp_path / "run", new_session=True)
    try:
        time.sleep(2.0)  # samples flowing
        rig = psutil.Process(launcher.pid).children(recursive=True)
        names = {" ".join(p.cmdline()[:3]) for p in rig}
        assert len(rig) >= 5, names  # belt_drive, analysis, plant, the recorder and its helpers
        os.kill(launcher.pid, signal.SIGKILL)  # the launcher only, not its process group
        launcher.communicate(timeout=30)
        _gone, alive = psutil.wait_procs(rig, timeout=30)
        assert not alive, [" ".join(p.cmdline()[:3]) for p in alive]
        # each node stopped as on a clean stop: the recorder finalized what it had
        result = verify_bag(tmp_path / "run" / "bag")
        assert not result.structural, result.problems
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(launcher.pid, signal.SIGKILL)
