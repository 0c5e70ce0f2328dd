"""Processes that end when they must: with their parent, and at a deadline whatever holds the GIL.

`die_with_parent` uses Linux's parent-death signal (prctl PR_SET_PDEATHSIG). A helper process
(the recorder's fork server and workers, the launcher's nodes) calls it first thing: when the
process that started it ends, for whatever reason (SIGKILL included, which no handler sees), the
kernel sends it SIGKILL, and so on down the chain. On a system without prctl it does nothing and
says so (returns False).

The signal follows the parent *thread*: call it in a process started from a thread that lives
as long as its process (the main thread, the fork server's loop).

`ExitTimer` ends the process with a given status after a delay, from a thread that runs no
Python: a POSIX timer (timer_create, SIGEV_THREAD) whose notify function is libc's `_exit`,
called with the status as its sigval. A Python timer thread cannot do this while another
thread blocks in C holding the GIL (rclpy destroying a DDS participant was seen to).
"""

from __future__ import annotations

import ctypes
import os
import signal

PR_SET_PDEATHSIG = 1
CLOCK_MONOTONIC = 1
SIGEV_THREAD = 2


class _SigEvent(ctypes.Structure):
    """struct sigevent (Linux, 64 bytes) with SIGEV_THREAD's function and attributes."""

    _fields_ = [
        ("value", ctypes.c_void_p),  # union sigval: sival_int in its low bytes
        ("signo", ctypes.c_int),
        ("notify", ctypes.c_int),
        ("function", ctypes.c_void_p),
        ("attributes", ctypes.c_void_p),
        ("pad", ctypes.c_int * 8),
    ]


class _TimeSpec(ctypes.Structure):
    _fields_ = [("sec", ctypes.c_long), ("nsec", ctypes.c_long)]


class _ITimerSpec(ctypes.Structure):
    _fields_ = [("interval", _TimeSpec), ("value", _TimeSpec)]


def die_with_parent(sig: int = signal.SIGKILL) -> bool:
    """Have the kernel send `sig` to this process when its parent ends; False where it cannot.

    If the parent has already ended (the process was reparented before the call), the signal is
    sent at once.
    """
    parent = os.getppid()
    try:
        # the process's own symbols (libc's among them): find_library would run ldconfig in a
        # subprocess, which a preexec_fn (between fork and exec) must not do
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(PR_SET_PDEATHSIG, int(sig), 0, 0, 0) != 0:
            return False
    except (OSError, AttributeError):
        return False
    if os.getppid() != parent or parent == 1:  # the parent ended before the call
        os.kill(os.getpid(), sig)
    return True


class ExitTimer:
    """`_exit(status)` after `seconds` unless cancelled, needing no GIL (see the module docstring).

    `armed` is False where the timer could not be set (no such libc call): then nothing happens.
    """

    def __init__(self, seconds: float, status: int) -> None:
        self._timer = ctypes.c_void_p()
        self.armed = False
        try:
            self._libc = ctypes.CDLL(None, use_errno=True)
            exit_now = ctypes.cast(self._libc._exit, ctypes.c_void_p).value
            event = _SigEvent(value=status & 0xFF, notify=SIGEV_THREAD, function=exit_now)
            if self._libc.timer_create(CLOCK_MONOTONIC, ctypes.byref(event), ctypes.byref(self._timer)) != 0:
                return
            whole = int(seconds)
            spec = _ITimerSpec(value=_TimeSpec(whole, int((seconds - whole) * 1e9)))
            if self._libc.timer_settime(self._timer, 0, ctypes.byref(spec), None) != 0:
                self._libc.timer_delete(self._timer)
                return
        except (OSError, AttributeError):
            return
        self.armed = True

    def cancel(self) -> None:
        """Disarm and delete the timer (once)."""
        if self.armed:
            self.armed = False
            self._libc.timer_delete(self._timer)
