"""Shared helpers for tests that start real ROS 2 processes.

Small API (all processes get their own session, so a whole process tree can be stopped):

- ``env = ros_env()`` — a copy of os.environ with a fresh ROS_DOMAIN_ID (100-200, chosen from
  pid and randomness) and ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, so parallel test runs never
  hear each other. Pass the same env to every process of one test.
- ``proc = start_module("lubrig_ros.nodes.recorder", "-o", str(bag), env=env)`` — start
  ``python -m module args`` (``start_script("recorder", ...)`` for a console script in the
  venv); stdout/stderr go to log files, readable with ``proc.output()``.
- ``proc.wait_for_output("recording", timeout=20)`` — wait until a line appears (raises with
  the log on timeout or if the process exits first).
- ``wait_for_topics(env, ["/lubrig/state"], timeout=10)`` — wait until topics appear in the
  ROS graph (checked from a separate helper process).
- ``proc.stop(signal.SIGINT, timeout=10)`` — clean stop, returns the exit status; kills the
  process group if it does not stop in time. ``proc.kill()`` sends SIGKILL (crash test).
- ``run_module(module, *args, env=env, timeout=30)`` — run to completion, CompletedProcess.

Use ``with start_module(...) as proc:`` so that the process is always killed at the end.
"""

from __future__ import annotations

import contextlib
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

PYTHON = sys.executable
BIN = Path(PYTHON).parent


def ros_env(domain_id: int | None = None) -> dict[str, str]:
    """Environment for an isolated ROS 2 test: own domain id, localhost discovery."""
    env = dict(os.environ)
    if domain_id is None:
        domain_id = 100 + (os.getpid() * 7 + random.randrange(1000)) % 101
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["PYTHONUNBUFFERED"] = "1"
    return env


class RosProcess:
    """A started process with logs in files and clean-stop helpers."""

    def __init__(
        self,
        argv: list[str],
        env: dict[str, str],
        cwd: str | Path | None = None,
        preexec_fn: Callable[[], None] | None = None,
    ) -> None:
        self.argv = argv
        self._dir = Path(tempfile.mkdtemp(prefix="ros_harness_"))
        self.stdout_path = self._dir / "stdout.log"
        self.stderr_path = self._dir / "stderr.log"
        with open(self.stdout_path, "wb") as out, open(self.stderr_path, "wb") as err:
            self.popen = subprocess.Popen(
                argv, env=env, cwd=cwd, stdout=out, stderr=err, start_new_session=True,
                preexec_fn=preexec_fn,
            )

    @property
    def pid(self) -> int:
        """Process id."""
        return self.popen.pid

    def output(self) -> str:
        """stdout so far."""
        return self.stdout_path.read_text(errors="replace")

    def errors(self) -> str:
        """stderr so far."""
        return self.stderr_path.read_text(errors="replace")

    def wait_for_output(self, text: str, timeout: float = 20.0) -> None:
        """Wait until text appears in stdout; AssertionError with the logs otherwise."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if text in self.output():
                return
            if self.popen.poll() is not None:
                break
            time.sleep(0.05)
        raise AssertionError(
            f"{text!r} not printed by {self.argv} (exit {self.popen.poll()}):\n"
            f"{self.output()}\n{self.errors()}"
        )

    def wait(self, timeout: float = 30.0) -> int:
        """Wait for exit and return the status (kills the group on timeout)."""
        try:
            return self.popen.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.kill()
            raise

    def stop(self, sig: int = signal.SIGINT, timeout: float = 10.0) -> int:
        """Send sig to the process, wait up to timeout, kill the group if needed."""
        if self.popen.poll() is None:
            self.popen.send_signal(sig)
        try:
            return self.popen.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.kill()
            raise AssertionError(f"{self.argv} did not stop within {timeout} s") from None

    def kill(self) -> None:
        """SIGKILL the whole process group (the process and its children)."""
        with contextlib.suppress(ProcessLookupError):
            os.killpg(self.popen.pid, signal.SIGKILL)
        self.popen.wait(timeout=10)

    def __enter__(self) -> RosProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        # the group may outlive the leader (e.g. worker processes after SIGKILL)
        with contextlib.suppress(ProcessLookupError):
            os.killpg(self.popen.pid, signal.SIGKILL)
        self.popen.wait(timeout=10)


def start_module(module: str, *args: str, env: dict[str, str], cwd: str | Path | None = None) -> RosProcess:
    """Start ``python -m module args`` with env."""
    return RosProcess([PYTHON, "-m", module, *args], env, cwd)


def start_script(script: str, *args: str, env: dict[str, str], cwd: str | Path | None = None) -> RosProcess:
    """Start a console script installed in the test interpreter's bin directory."""
    return RosProcess([str(BIN / script), *args], env, cwd)


def run_module(
    module: str, *args: str, env: dict[str, str] | None = None, timeout: float = 30.0
) -> subprocess.CompletedProcess[str]:
    """Run ``python -m module args`` to completion and capture its output."""
    return subprocess.run(
        [PYTHON, "-m", module, *args], env=env, capture_output=True, text=True, timeout=timeout,
        check=False,
    )


_GRAPH_PROBE = """
import sys, time, rclpy
rclpy.init(args=[]); node = rclpy.create_node("ros_harness_probe")
want = set(sys.argv[1:]); end = time.monotonic() + {timeout}
while time.monotonic() < end:
    if want <= {{n for n, _ in node.get_topic_names_and_types()}}: sys.exit(0)
    time.sleep(0.1)
sys.exit(1)
"""


def wait_for_topics(env: dict[str, str], topics: list[str], timeout: float = 10.0) -> None:
    """Wait until all topics exist in the ROS graph of env's domain; AssertionError otherwise."""
    code = _GRAPH_PROBE.format(timeout=float(timeout))
    res = subprocess.run(
        [PYTHON, "-c", code, *topics], env=env, capture_output=True, text=True,
        timeout=timeout + 20, check=False,
    )
    if res.returncode != 0:
        raise AssertionError(f"topics {topics} not in the graph within {timeout} s: {res.stderr}")
