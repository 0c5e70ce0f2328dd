"""A sim run that cannot progress ends `lubrig rig` non-zero with the plant's stall line (issue 11).

The recorder of a real `lubrig rig` run is frozen (SIGSTOP): alive, subscribed, but it takes no
more blocks, so belt_drive (which paces on the recorder's flow_progress) sends nothing and the
plant reports the run stalled (timing ERROR within about a second, also in its log). The launcher
gives up after STALL_GIVE_UP_S of stall and exits 2 with that line; the recorder is let go again
(SIGCONT) once the launcher has given up, so it stops on the launcher's SIGINT and the bag is kept.
"""

from __future__ import annotations

import signal
import subprocess
import time

import psutil
import pytest
from lubrig_testkit.cli import start_long_rig

from lubrig_ros.cli.rig import STALL_GIVE_UP_S

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def _recorder(launcher: subprocess.Popen, bag: str) -> psutil.Process | None:
    for child in psutil.Process(launcher.pid).children(recursive=True):
        try:
            cmd = " ".join(child.cmdline())
        except psutil.Error:
            continue
        if "recorder" in cmd and bag in cmd and "spawn_main" not in cmd:
            return child
    return None


def test_a_stalled_sim_run_ends_lubrig_rig_with_the_stall_line(ros_env, tmp_path):
    run = tmp_path / "run"
    launcher = start_long_rig(ros_env, run)
    try:
        plant_log = run / "logs" / "plant.log"
        deadline = time.monotonic() + 180
        recorder = None
        while time.monotonic() < deadline and recorder is None:
            recorder = _recorder(launcher, str(run / "bag"))
            time.sleep(0.2)
        assert recorder is not None
        time.sleep(3.0)  # let some blocks flow first: a stall of a started run
        recorder.send_signal(signal.SIGSTOP)
        while time.monotonic() < deadline and "stalled: no band sample" not in plant_log.read_text():
            time.sleep(0.2)
        assert "stalled: no band sample" in plant_log.read_text()  # the plant's log says so too
        # the launcher gives up STALL_GIVE_UP_S after the first stall report it saw
        time.sleep(STALL_GIVE_UP_S + 10.0)
        recorder.send_signal(signal.SIGCONT)
        out, err = launcher.communicate(timeout=240)
    finally:
        if launcher.poll() is None:
            launcher.kill()
    assert launcher.returncode == 2, (out, err)
    assert f"sim run stalled for {STALL_GIVE_UP_S:g} s: /lubrig/plant: timing: stalled: no band sample" in err
    assert "Traceback" not in err
