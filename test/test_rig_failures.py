"""`lubrig rig` names the process that failed and why, in the phase it failed in; no temporary file left.

Real processes: a plant killed (SIGKILL) while the launcher waits for the recorder is named at
once as the plant (not the recorder, not after a timeout); a recorder whose bag cannot grow
(RLIMIT_FSIZE: write() fails with EFBIG, the path a full disk takes) is named with its error
line. Both end `lubrig rig` with EXIT_FAILED and leave no temporary file in the run folder. The
launcher's own escalation of a node that ignores SIGINT is said at every step.
"""

from __future__ import annotations

import contextlib
import os
import resource
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import psutil
import pytest

from lubrig_ros.cli.rig import EXIT_FAILED
from lubrig_ros.cli.rig_supervisor import first_error_line, stop_all

LIMIT = 150_000  # bytes per file: logs and run_config fit, a 10 s sim bag (~800 kB) does not


def _temporaries(run: Path) -> list[Path]:
    return [p for p in run.rglob("*") if p.name.endswith(".tmp")]


def _rig(env: dict[str, str], run: Path, *extra: str, preexec_fn=None) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "lubrig_ros.cli.main",
            "rig",
            "--case",
            "1",
            "--run-dir",
            str(run),
            "--no-report",
            *extra,
        ],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=preexec_fn,
    )


def _plant_of(launcher: subprocess.Popen[str]) -> psutil.Process | None:
    """The plant process among the launcher's children (.venv/bin/plant --ros-args ...)."""
    for child in psutil.Process(launcher.pid).children(recursive=True):
        with contextlib.suppress(psutil.Error):
            if any(Path(arg).name == "plant" for arg in child.cmdline()[:2]):
                return child
    return None


@pytest.mark.ros
def test_a_plant_killed_during_start_up_is_named_as_the_plant(ros_env, tmp_path):
    run = tmp_path / "run"
    launcher = _rig(ros_env, run, "--duration", "5")
    try:
        plant = None
        deadline = time.monotonic() + 120
        while plant is None:
            assert launcher.poll() is None, launcher.communicate()
            assert time.monotonic() < deadline, "no plant process started"
            plant = _plant_of(launcher)
            time.sleep(0.02)
        plant.kill()  # SIGKILL while it starts (the launcher is waiting for the recorder then)
        out, err = launcher.communicate(timeout=180)
    finally:
        if launcher.poll() is None:
            os.killpg(launcher.pid, signal.SIGKILL)
    assert launcher.returncode == EXIT_FAILED, (out, err)
    line = err.strip().splitlines()[-1]
    assert line.startswith("lubrig rig: error: plant was killed by SIGKILL during start-up"), err
    assert "not ready" not in err and "recorder" not in line, err
    assert "failed before the run ended" in out, out
    assert not _temporaries(run), _temporaries(run)


def _file_size_cap() -> None:
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, LIMIT))
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # EFBIG instead of being killed (inherited)


@pytest.mark.ros
@pytest.mark.slow  # a whole recorded sim run
def test_a_recorder_that_cannot_write_is_named_with_its_error_line(ros_env, tmp_path):
    run = tmp_path / "run"
    launcher = _rig(ros_env, run, "--duration", "10", preexec_fn=_file_size_cap)
    try:
        out, err = launcher.communicate(timeout=300)
    finally:
        if launcher.poll() is None:
            os.killpg(launcher.pid, signal.SIGKILL)
    assert launcher.returncode == EXIT_FAILED, (out, err)
    line = err.strip().splitlines()[-1]
    assert line.startswith("lubrig rig: error: recorder exited with status 1 during "), err
    assert "recorder: error: " in line and "File too large" in line and "recording stopped" in line, line
    assert "process(es)" not in err
    assert not _temporaries(run), _temporaries(run)


def test_an_atomic_write_that_fails_leaves_no_temporary_file(tmp_path):
    """write_text_atomic on a full disk (EFBIG under RLIMIT_FSIZE): the old file stays, no .tmp."""
    target = tmp_path / "accounting.json"
    target.write_text("old\n")
    code = textwrap.dedent(
        f"""
        import resource, signal, sys
        from pathlib import Path
        from lubrig_ros.app.fileio import write_text_atomic
        resource.setrlimit(resource.RLIMIT_FSIZE, (1000, 1000))
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        try:
            write_text_atomic(Path({str(target)!r}), "x" * 100_000)
        except OSError as exc:
            print(exc.strerror)
            sys.exit(0)
        sys.exit(1)
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=False
    )
    assert done.returncode == 0 and "File too large" in done.stdout, done.stdout + done.stderr
    assert target.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["accounting.json"]


def test_the_first_error_line_prefers_the_nodes_own(tmp_path):
    log = tmp_path / "recorder.log"
    log.write_text(
        "recorder: recording 9 topics\n"
        "2026-01-01 [RTPS_TRANSPORT_SHM Error] Failed init_port\n"
        "recorder: error: [Errno 27] File too large: bag.mcap; recording stopped\n"
        "recorder: error: a later one\n"
    )
    assert first_error_line(log) == "recorder: error: [Errno 27] File too large: bag.mcap; recording stopped"
    log.write_text("plant: mode=sim\n")
    assert first_error_line(log) is None
    assert first_error_line(tmp_path / "missing.log") is None


def test_a_node_deaf_to_sigint_and_sigterm_is_killed_and_each_step_said(tmp_path, capsys):
    deaf = textwrap.dedent(
        """
        import faulthandler, signal, time
        faulthandler.register(signal.SIGUSR1, all_threads=True)  # as nodes.entry does
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        print("ready", flush=True)
        while True:
            time.sleep(1)
        """
    )
    log = tmp_path / "analysis.log"
    with log.open("w") as out:
        proc = subprocess.Popen([sys.executable, "-c", deaf], stdout=out, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + 60
        while log.read_text() != "ready\n":
            assert time.monotonic() < deadline
            time.sleep(0.05)
        escalated: dict[str, str] = {}
        codes = stop_all({"analysis": proc}, grace=0.5, escalated=escalated)
    assert codes == {"analysis": -signal.SIGKILL}
    err = capsys.readouterr().err
    assert "analysis did not stop within 0.5 s of SIGINT" in err
    assert "analysis did not stop within 5 s of SIGTERM either; SIGKILL" in err
    assert escalated["analysis"].endswith("(SIGKILL)"), escalated
