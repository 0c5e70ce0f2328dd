"""Progress of long commands: a status line on a terminal (real pty), nothing when not a terminal."""

from __future__ import annotations

import os
import pty
import subprocess
import sys
import time

from lubrig_ros.cli.progress import Progress

SCRIPT = (
    "import time\n"
    "from lubrig_ros.cli.progress import Progress\n"
    "bar = Progress('lubrig paper', 10.0, interval_s=0.0)\n"
    "for k in range(1, 6):\n"
    "    time.sleep(0.02)\n"
    "    bar.update(2.0 * k, f'case{k:02d}')\n"
    "bar.finish()\n"
    "print('done')\n"
)


def _read_all(fd: int) -> bytes:
    data = b""
    while True:
        try:
            chunk = os.read(fd, 4096)
        except OSError:  # EIO once the child closed the pty
            break
        if not chunk:
            break
        data += chunk
    return data


def test_status_line_on_a_pty() -> None:
    master, slave = pty.openpty()
    proc = subprocess.Popen([sys.executable, "-c", SCRIPT], stdout=slave, stderr=slave, stdin=slave)
    os.close(slave)
    output = _read_all(master).decode()
    os.close(master)
    assert proc.wait(timeout=60) == 0
    assert "\r" in output
    lines = [line for line in output.replace("\r\n", "\n").split("\r") if "rig time" in line]
    assert len(lines) == 5
    assert "lubrig paper: rig time 10.0 / 10 s" in lines[-1] and "case05" in lines[-1]
    assert "× real time" in lines[0] and "left" in lines[0]
    assert output.rstrip().endswith("done")


def test_silent_when_not_a_terminal() -> None:
    res = subprocess.run(
        [sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=60, check=False
    )
    assert res.returncode == 0
    assert res.stdout == "done\n" and res.stderr == ""


def test_line_reports_rate_and_time_left() -> None:
    read, write = os.pipe()
    with os.fdopen(write, "w") as stream:
        bar = Progress("lubrig rig", 20.0, stream=stream)
        assert not bar.enabled  # a pipe is not a terminal
        bar.started = time.monotonic() - 2.0  # 5 rig s in 2 wall s
        text = bar.line(5.0)
        bar.update(5.0)
        bar.finish()
    assert os.read(read, 100) == b""
    os.close(read)
    assert text.startswith("lubrig rig: rig time 5.0 / 20 s, 2.5× real time, ")
    seconds_left = float(text.split(", ")[2].split(" s left")[0])
    assert 5.0 < seconds_left <= 6.0  # 15 rig s left at 2.5×
