"""Ctrl-C in a terminal during `lubrig rig`: SIGINT to the whole process group (issue 11).

Every process of the rig gets the signal at once, as from a terminal. Asserted: no traceback
anywhere (launcher output and every node log), the launcher says it was interrupted (no "nan s")
and exits 130, and the bag it leaves is readable with every recorded sample in order.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from lubrig_ros.bag.verify import verify_bag

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def test_ctrl_c_stops_the_rig_cleanly(ros_env, tmp_path):
    run = tmp_path / "run"
    launcher = subprocess.Popen(
        [sys.executable, "-m", "lubrig_ros.cli.main", "rig", "--case", "1", "--duration", "600",
         "--run-dir", str(run), "--no-report"],
        env=ros_env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
    )
    try:
        plant_log = run / "logs" / "plant.log"
        deadline = time.monotonic() + 180
        while time.monotonic() < deadline and not (
            plant_log.exists() and "plant: mode=sim" in plant_log.read_text()
        ):
            assert launcher.poll() is None, launcher.communicate()
            time.sleep(0.2)
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
