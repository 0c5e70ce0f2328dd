"""A SIGINT at any moment of a node's start-up ends it without a traceback (issue 11).

The node executables enter through lubrig_ros.nodes.entry, which handles SIGINT before the
node module's imports (rclpy, numpy, the sessions: half a second or more) and ends the process
of the signal, as the default action would, instead of raising KeyboardInterrupt inside an import
(which printed a traceback, and once numpy's "PyCapsule_Import could not import module
datetime"). Once the node is set up, rclpy's handling stops it cleanly (exit 0). The moments are
spread over the whole start-up; whichever phase a signal lands in, the outcome must be clean.
Except the interpreter's own start-up (its site module), which no code of ours precedes: the
moments start at twice the time a bare `python -c pass` takes on this machine now.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest
from lubrig_testkit.harness import BIN

pytestmark = [pytest.mark.ros]

NODES = ("belt_drive", "plant", "analysis", "recorder", "replay", "view")


def test_every_node_executable_enters_through_the_entry_module() -> None:
    for name in NODES:
        text = (BIN / name).read_text()
        assert f"from lubrig_ros.nodes.entry import {name}" in text, text


@pytest.mark.parametrize("delay", [0.0, 0.1, 0.25, 0.5, 0.8, 1.5])
def test_sigint_during_start_up_leaves_no_traceback(ros_env: dict[str, str], delay: float) -> None:
    start = time.monotonic()
    subprocess.run([sys.executable, "-c", "pass"], check=True)
    delay += 2 * (time.monotonic() - start)
    node = subprocess.Popen(
        [str(BIN / "analysis"), "--ros-args", "-r", "__ns:=/lubrig", "-p", "case:=1"],
        env=ros_env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    time.sleep(delay)
    node.send_signal(signal.SIGINT)
    out, _ = node.communicate(timeout=60)
    assert node.returncode in (0, -signal.SIGINT), out
    assert "Traceback" not in out and "KeyboardInterrupt" not in out, out


@pytest.mark.parametrize("name", ["plant", "analysis"])
def test_sigint_to_a_running_node_is_a_clean_stop(ros_env: dict[str, str], name: str) -> None:
    """Once the node runs, SIGINT is the clean stop of rclpy's handling: exit status 0."""
    node = subprocess.Popen(
        [str(BIN / name), "--ros-args", "-r", "__ns:=/lubrig", "-p", "case:=1"],
        env=ros_env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    lines: list[str] = []
    assert node.stdout is not None
    for line in node.stdout:  # the node's first log line: it is set up and spinning soon after
        lines.append(line)
        if f"[lubrig.{name}]" in line:
            break
    time.sleep(1.0)
    node.send_signal(signal.SIGINT)
    out, _ = node.communicate(timeout=60)
    text = "".join(lines) + out
    assert node.returncode == 0, text
    assert "Traceback" not in text, text
