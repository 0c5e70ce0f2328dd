"""Ctrl-C in a terminal during `lubrig rig`: SIGINT to the whole process group (issue 11).

Every process of the rig gets the signal at once, as from a terminal. Asserted: no traceback
anywhere (launcher output and every node log), the launcher says it was interrupted (no "nan s")
and exits 130, and the bag it leaves is readable with every recorded sample in order.
"""

from __future__ import annotations

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
    assert launcher.returncode == 130, (out, err)
    assert "interrupted before the run ended" in out and "nan" not in out, out
    assert "Traceback" not in out + err, (out, err)
    for log in (run / "logs").glob("*.log"):
        assert "Traceback" not in log.read_text(), (log.name, log.read_text()[-2000:])
    result = verify_bag(run / "bag")
    assert not result.structural, result.problems
    assert not result.problems, result.problems  # gap-free, in order
