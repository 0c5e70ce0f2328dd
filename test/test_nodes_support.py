"""Helpers of the node tests: isolated ROS domain, node processes, an in-test probe node.

(Temporary: to be replaced by test/ros_harness.py once it exists.)
"""

from __future__ import annotations

import contextlib
import os
import random
import signal
import subprocess
import sys
import threading
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from lubrig_ros.nodes import common

BIN = Path(sys.executable).parent


def ros_env(domain: int) -> dict[str, str]:
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(domain)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["PYTHONUNBUFFERED"] = "1"
    env["RCUTILS_LOGGING_BUFFERED_STREAM"] = "0"
    return env


def new_domain() -> int:
    return random.randint(100, 230)


class Procs:
    """Node processes started with `name --ros-args -p k:=v ...`; stopped by SIGINT then SIGTERM."""

    def __init__(self, domain: int, tmp: Path) -> None:
        self.domain, self.tmp = domain, tmp
        self.procs: dict[str, subprocess.Popen] = {}

    def start(self, name: str, **params: Any) -> subprocess.Popen:
        args = [str(BIN / name), "--ros-args"]
        for key, value in params.items():
            args += ["-p", f"{key}:={value}"]
        log = open(self.tmp / f"{name}.log", "w")  # noqa: SIM115
        proc = subprocess.Popen(args, env=ros_env(self.domain), stdout=log, stderr=subprocess.STDOUT)
        self.procs[name] = proc
        return proc

    def log(self, name: str) -> str:
        return (self.tmp / f"{name}.log").read_text()

    def stop(self) -> dict[str, int]:
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        codes = {}
        for name, proc in self.procs.items():
            try:
                codes[name] = proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.terminate()
                codes[name] = proc.wait(timeout=5)
        return codes


class Probe:
    """A node in its own context on the test's domain, spun in a background thread."""

    def __init__(self, domain: int) -> None:
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = Node("probe", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.messages: dict[str, list] = defaultdict(list)
        self.times: dict[str, list] = defaultdict(list)
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        with contextlib.suppress(Exception):
            self.executor.spin()

    def subscribe(self, name: str, msg_type: type, qos=common.STREAM_QOS) -> None:
        def callback(msg: Any) -> None:
            self.messages[name].append(msg)
            self.times[name].append(time.monotonic())

        self.node.create_subscription(msg_type, name, callback, qos)

    def wait_for(self, predicate, timeout: float) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if predicate():
                return True
            time.sleep(0.05)
        return predicate()

    def rate(self, name: str, seconds: float) -> float:
        """Messages per second on `name` over the last `seconds` (waits that long)."""
        start = len(self.times[name])
        t0 = time.monotonic()
        time.sleep(seconds)
        return (len(self.times[name]) - start) / (time.monotonic() - t0)

    def stamped_rate(self, name: str, seconds: float) -> tuple[float, float]:
        """(messages per stamped second, stamped seconds per wall second) of header-stamped
        messages received during the next `seconds`: the publisher's own rate and its pacing
        against the wall clock, insensitive to delivery bursts at the window's edges."""
        start = len(self.messages[name])
        t0 = time.monotonic()
        time.sleep(seconds)
        wall = time.monotonic() - t0
        msgs = self.messages[name][start:]
        stamps = [m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in msgs]
        if len(stamps) < 2 or stamps[-1] <= stamps[0]:
            return 0.0, 0.0
        span = stamps[-1] - stamps[0]
        return (len(stamps) - 1) / span, span / wall

    def set_parameter(self, node: str, name: str, value: Any) -> Any:
        """SetParameters on /<node>; returns the SetParametersResult."""
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter

        request = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
        return self.call(SetParameters, f"/{node}/set_parameters", request).results[0]

    def topics(self) -> dict[str, list[str]]:
        return dict(self.node.get_topic_names_and_types())

    def call(self, srv_type: type, name: str, request: Any, timeout: float = 10.0) -> Any:
        client = self.node.create_client(srv_type, name)
        assert client.wait_for_service(timeout_sec=timeout), f"service {name} not available"
        future = client.call_async(request)
        assert self.wait_for(future.done, timeout), f"service {name} did not answer"
        return future.result()

    def close(self) -> None:
        self.context.try_shutdown()
        self._thread.join(timeout=2)
        self.node.destroy_node()
