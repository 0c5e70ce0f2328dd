"""Scheduling of a node's real-time loop: SCHED_FIFO for its threads, the CPU wake-up latency request.

`enter_realtime` puts a loop thread under SCHED_FIFO (and holds the wake-up latency request);
`serve_realtime` puts the node's executor thread one priority below it, so that the callbacks
holding the GIL the loop needs cannot be preempted by other processes.
"""

from __future__ import annotations

import gc
import os
import sys

from rclpy.node import Node


def enter_realtime(priority: int, node: Node) -> bool:
    """Put the calling thread (a real-time loop) under SCHED_FIFO `priority`; True if it took.

    Only that thread (and, through `serve_realtime`, the executor thread one priority below):
    every other process keeps normal scheduling, so a busy node cannot starve the machine.
    Without the privilege (CAP_SYS_NICE or an rtprio limit) it says so and goes on with normal
    scheduling. 0: normal scheduling, nothing said.
    """
    if priority <= 0:
        return False
    problem = _fifo(priority)
    if problem:
        node.get_logger().warning(
            f"realtime_priority={priority}: SCHED_FIFO not available ({problem}); the loop thread runs "
            "with normal scheduling (grant CAP_SYS_NICE or an rtprio limit, or set realtime_priority:=0)"
        )
        return False
    held = hold_cpu_wakeup_latency()
    node.get_logger().info(
        f"realtime_priority={priority}: loop thread under SCHED_FIFO; "
        + (
            "CPU wake-up latency 0 requested (/dev/cpu_dma_latency)"
            if held
            else "no CPU wake-up latency request (/dev/cpu_dma_latency not writable)"
        )
    )
    gc.freeze()  # objects made so far are never scanned again: shorter collector pauses
    return True


def serve_realtime(priority: int) -> bool:
    """Put the calling thread (the node's executor) under SCHED_FIFO one below a loop's `priority`.

    The executor thread's callbacks hold the GIL (and the session lock) that the loop thread
    needs on every tick. Under normal scheduling any other process could preempt the executor
    while it holds them, and the loop, though under SCHED_FIFO, would wait until it runs again
    (a priority inversion: at 1 kHz, late samples a few ms after each band block). One priority
    below the loop, it still yields the CPU to it. Silent: `enter_realtime` on the loop thread
    says whether SCHED_FIFO is available. Returns True if it took; 0: nothing done.
    """
    return priority > 0 and not _fifo(max(1, priority - 1))


def _fifo(priority: int) -> str:
    """SCHED_FIFO `priority` for the calling thread; why not ("" when it took)."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (PermissionError, OSError, AttributeError) as exc:
        return str(exc)
    return ""


_LATENCY_REQUEST: list[int] = []  # the open /dev/cpu_dma_latency descriptor (held for the process)


def hold_cpu_wakeup_latency() -> bool:
    """Ask the kernel for a CPU wake-up latency of 0 µs while this process lives; True if held.

    The PM QoS request real-time tools make (rt-tests' cyclictest): idle CPUs stay out of deep idle
    states, so a sleeping loop wakes on time. On this project's VMs a quiet machine's idle vCPUs
    otherwise wake the 1 kHz loop late more often than a loaded one's (docs/benchmarks.md). The
    request lasts as long as the descriptor is open (until the process ends).
    """
    if _LATENCY_REQUEST:
        return True
    try:
        fd = os.open("/dev/cpu_dma_latency", os.O_WRONLY)
    except OSError:
        return False
    try:
        os.write(fd, (0).to_bytes(4, sys.byteorder))
    except OSError:
        os.close(fd)
        return False
    _LATENCY_REQUEST.append(fd)
    return True
