"""Processes that do not outlive their parent: Linux's parent-death signal (prctl PR_SET_PDEATHSIG).

A helper process (the recorder's fork server and workers, the launcher's nodes) calls
`die_with_parent` first thing: when the process that started it ends, for whatever reason
(SIGKILL included, which no handler sees), the kernel sends it SIGKILL, and so on down the
chain. On a system without prctl it does nothing and says so (returns False).

The signal follows the parent *thread*: call it in a process started from a thread that lives
as long as its process (the main thread, the fork server's loop).
"""

from __future__ import annotations

import ctypes
import os
import signal

PR_SET_PDEATHSIG = 1


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
