"""Start-up steps of `lubrig rig`'s processes, printed when LUBRIG_STARTUP_TRACE is set (no ROS).

bench/bench_rig_startup.py sets the variable and reads the lines from the launcher's output and
the node logs to draw the timeline of one start (imports done, namespace check, node created).
Without the variable `mark` prints nothing. A line: `startup-trace WHO EPOCH_SECONDS WHAT`.
"""

from __future__ import annotations

import os
import sys
import time

VARIABLE = "LUBRIG_STARTUP_TRACE"


def mark(who: str, what: str) -> None:
    """Print one trace line to stderr (the node log, the launcher's output) if tracing is on."""
    if os.environ.get(VARIABLE):
        print(f"startup-trace {who} {time.time():.6f} {what}", file=sys.stderr, flush=True)
