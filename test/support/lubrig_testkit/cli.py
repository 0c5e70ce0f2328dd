"""`lubrig` in the test process: the same main() the console script runs, output captured.

Starting the real script costs seconds of CPU per call (it imports every subcommand); the tests
that prove the console script itself (exit status, a single stderr line from a fresh interpreter)
run it as a process, the many others call ``lubrig(...)`` here and assert the same things.
"""

from __future__ import annotations

import contextlib
import io
import subprocess
from pathlib import Path


def lubrig(*args: str) -> subprocess.CompletedProcess[str]:
    """Run ``lubrig args`` in-process; returncode, stdout and stderr as a process would give them."""
    from lubrig_ros.cli.main import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(list(args))
        except SystemExit as exc:  # argparse errors and --help
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    return subprocess.CompletedProcess(["lubrig", *args], code, out.getvalue(), err.getvalue())


#: Rig seconds of `start_long_rig`'s run (see its docstring).
LONG_RIG_S = 36_000.0


def start_long_rig(env: dict[str, str], run: Path, new_session: bool = False) -> subprocess.Popen[str]:
    """`lubrig rig --case 1 --duration LONG_RIG_S --run-dir run --no-report` as a process (pipes for output).

    LONG_RIG_S of rig time lasts minutes of wall time even at a recorded sim's full rate (about
    250 x real time on this project's 2-core machines), so the run is still going when the test acts.

    Returns once the plant has started (its log says so); AssertionError if the launcher ends or
    nothing starts within 180 s (a guard against a hang).
    """
    import sys
    import time

    launcher = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "lubrig_ros.cli.main",
            "rig",
            "--case",
            "1",
            "--duration",
            f"{LONG_RIG_S:g}",
            "--run-dir",
            str(run),
            "--no-report",
        ],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=new_session,
    )
    plant_log = run / "logs" / "plant.log"
    deadline = time.monotonic() + 180
    while not (plant_log.exists() and "plant: mode=sim" in plant_log.read_text()):
        assert launcher.poll() is None, launcher.communicate()
        assert time.monotonic() < deadline, "the plant did not start"
        time.sleep(0.2)
    return launcher
