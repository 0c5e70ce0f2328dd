"""Shared pieces of the lubrig_ros nodes: topic names, QoS profiles, parameter and run helpers.

The topic contract lives in docs/topics.md; every name here is relative to the `topic_namespace`
parameter (default /lubrig), except /clock and /diagnostics.
"""

from __future__ import annotations

import gc
import math
import os
import time
from collections.abc import Callable, Iterable

import numpy as np
import rclpy
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

from ..app import contract
from ..app.contract import DEFAULT_NAMESPACE, DEFAULT_REALTIME_PRIORITY, MODES
from ..app.selection import base_config
from ..core.params import ParameterError
from ..core.presets import RunConfig
from .interfaces import qos_profile

# Topic names relative to the namespace (the contract with types and QoS: app/contract.py).
BAND_VELOCITY = "band_velocity"
DISPLACEMENT = "displacement"
VELOCITY = "velocity"
FRICTION_COEFFICIENT = "friction_coefficient"
STATE = "state"
RUN_CONFIG = "run_config"
RUN_COMPLETE = "run_complete"
DOMINANT_FREQUENCY = "dominant_frequency"
WAVELET_POWER = "wavelet_power"
WAVELET_IMAGE = "wavelet_image"
LINEAR_ZONE = "linear_zone"
CRITICAL_DAMPING_RATIO = "critical_damping_ratio"
OSCILLATION_GROWING = "oscillation_growing"
RESET_SERVICE = "plant/reset"
PAUSE_SERVICE = "plant/pause"
CLOCK = "/clock"
DIAGNOSTICS = "/diagnostics"

#: rclpy QoS profiles of the contract's plain-data QoS (app/contract.py).
STREAM_QOS = qos_profile(contract.STREAM_QOS)
ANALYSIS_QOS = qos_profile(contract.ANALYSIS_QOS)
LATCHED_QOS = qos_profile(contract.LATCHED_QOS)


def topic(namespace: str, name: str) -> str:
    """Absolute topic name under the namespace (names starting with '/' are kept)."""
    return contract.resolve(namespace, name)


def check_namespace(value: str) -> str:
    """Validate a topic namespace such as /lubrig (ROS 2's rules: app.contract.validate_namespace)."""
    return contract.validate_namespace(value, "topic_namespace")


def check_mode(value: str) -> str:
    """Validate the mode parameter."""
    if value not in MODES:
        raise ParameterError(f"mode={value!r} is not valid; expected one of {list(MODES)}")
    return value


def descriptor(
    text: str,
    *,
    read_only: bool = False,
    low: float | None = None,
    high: float | None = None,
    dynamic_typing: bool = False,
) -> ParameterDescriptor:
    """Parameter descriptor with a description and optional float range."""
    desc = ParameterDescriptor(description=text, read_only=read_only, dynamic_typing=dynamic_typing)
    if low is not None and high is not None:
        desc.floating_point_range = [FloatingPointRange(from_value=low, to_value=high, step=0.0)]
    return desc


def declare_run_selection(node: Node) -> RunConfig:
    """Declare `case`, `config_file` and `topic_namespace`; return the selected run configuration.

    case in 1..10 loads a study case, else config_file if not empty, else the built-in default
    (config/rig.yaml). Raises ParameterError with the offending value.
    """
    case = node.declare_parameter(
        "case", 0, descriptor("study case 1..10 (0: use config_file or the default)", read_only=True)
    ).value
    config_file = node.declare_parameter(
        "config_file", "", descriptor("run configuration YAML (empty: default)", read_only=True)
    ).value
    node.declare_parameter(
        "topic_namespace", DEFAULT_NAMESPACE, descriptor("namespace of all topics", read_only=True)
    )
    check_namespace(node.get_parameter("topic_namespace").value)
    return base_config(case, config_file)


def declare_wait_for_subscriber(node: Node) -> str:
    """Parameter `wait_for_subscriber`: node-name prefix that must subscribe before sim data flows."""
    return str(
        node.declare_parameter(
            "wait_for_subscriber",
            "",
            descriptor(
                "sim: hold the run until a node whose name starts with this (e.g. the recorder, "
                "'lubrig_recorder') subscribes to every output topic; empty = do not wait",
                read_only=True,
            ),
        ).value
    )


def declare_realtime_priority(node: Node) -> int:
    """Parameter `realtime_priority`: SCHED_FIFO priority of the real-time loop thread (0 = off)."""
    value = int(
        node.declare_parameter(
            "realtime_priority",
            DEFAULT_REALTIME_PRIORITY,
            descriptor(
                "realtime: SCHED_FIFO priority 1..99 of the loop thread so other processes cannot "
                "delay its ticks; 0 keeps normal scheduling",
                read_only=True,
            ),
        ).value
    )
    if not 0 <= value <= 99:
        raise ParameterError(f"realtime_priority={value!r} is not valid; expected 0..99")
    return value


def enter_realtime(priority: int, node: Node) -> None:
    """Put every thread of this process under SCHED_FIFO; without the privilege, warn and go on.

    All threads, not only the loop: the loop needs the GIL, and a normal-priority thread that
    holds it while preempted by another process would delay the loop by a whole time slice
    (priority inversion; measured up to 18 ms late ticks). Threads started later inherit it.
    """
    if priority <= 0:
        return
    try:
        for tid in os.listdir("/proc/self/task"):
            os.sched_setscheduler(int(tid), os.SCHED_FIFO, os.sched_param(priority))
    except (PermissionError, OSError, AttributeError) as exc:
        node.get_logger().warning(
            f"realtime_priority={priority}: SCHED_FIFO not available ({exc}); ticks may be late "
            "under load (grant CAP_SYS_NICE or an rtprio limit, or set realtime_priority:=0)"
        )
        return
    gc.freeze()  # objects made so far are never scanned again: shorter collector pauses


def subscribed_by(node: Node, topics: Iterable[str], prefix: str) -> bool:
    """True when every topic has a discovered subscription from a node named prefix*."""
    if not prefix:
        return True
    return all(
        any(info.node_name.startswith(prefix) for info in node.get_subscriptions_info_by_topic(t))
        for t in topics
    )


def finite(value: float) -> bool:
    """True for a finite float."""
    return isinstance(value, float | int) and math.isfinite(value)


class LatencyHistogram:
    """Latencies in fixed 10 µs bins up to 50 ms (plus an overflow bin).

    Adding is O(1) and a percentile costs one pass over 5,000 bins, whatever the run length: a
    list of every sample made each diagnostics report hold the GIL for ~11 ms after 200 s at 1 kHz,
    long enough to make the real-time loop miss ~11 deadlines.
    """

    BIN_S = 1e-5
    BINS = 5000

    def __init__(self) -> None:
        self.counts = np.zeros(self.BINS + 1, dtype=np.int64)
        self.count = 0

    def add(self, seconds: float) -> None:
        """Record one latency (negative values count as 0)."""
        self.counts[min(max(int(seconds / self.BIN_S), 0), self.BINS)] += 1
        self.count += 1

    def percentiles(self, qs: tuple[float, ...] = (50.0, 99.0)) -> list[float]:
        """Upper bin edges at the given percentiles, s (0.0 each when empty)."""
        if self.count == 0:
            return [0.0 for _ in qs]
        cumulative = np.cumsum(self.counts)
        return [
            float((np.searchsorted(cumulative, q / 100.0 * self.count) + 1) * self.BIN_S) for q in qs
        ]


class DeadlineLoop:
    """Absolute-deadline periodic loop: sleep most of the period, spin the last few 100 µs."""

    SPIN_S = 0.0003

    def __init__(self, period: float) -> None:
        self.period = period
        self.start = time.perf_counter()
        self.ticks = 0

    def deadline(self, k: int) -> float:
        """perf_counter time of tick k."""
        return self.start + k * self.period

    def wait(self, k: int) -> float:
        """Block until tick k is due; return how late (s) we are for it (≥ 0)."""
        due = self.deadline(k)
        while True:
            now = time.perf_counter()
            remaining = due - now
            if remaining <= 0.0:
                return -remaining
            if remaining > self.SPIN_S:
                time.sleep(remaining - self.SPIN_S)
            else:
                time.sleep(0)


def spin_node(make_node: Callable[[], Node], args: list[str] | None = None) -> int:
    """rclpy.init, build the node, spin until SIGINT/SIGTERM, destroy, shut down; exit status."""
    rclpy.init(args=args)
    node: Node | None = None
    status = 0
    try:
        node = make_node()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        executor.spin()
    except (ParameterError, ParameterException) as exc:
        # ParameterException: e.g. `-p duration:=20` (an integer) for a double parameter
        (node.get_logger() if node else rclpy.logging.get_logger("lubrig")).fatal(str(exc))
        status = 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RuntimeError:
        # After SIGINT/SIGTERM rclpy shuts the context down under a running executor; a take on a
        # subscription whose handle is already gone then raises a RuntimeError ("Unable to convert
        # call argument"), which is part of stopping, not a failure. Anything else is re-raised.
        if rclpy.ok():
            raise
    finally:
        if node is not None:
            close = getattr(node, "close", None)
            if close is not None:
                close()
            node.destroy_node()
        rclpy.try_shutdown()
    return status


__all__ = [
    "ANALYSIS_QOS",
    "LATCHED_QOS",
    "STREAM_QOS",
    "DeadlineLoop",
    "declare_run_selection",
    "spin_node",
    "topic",
]
