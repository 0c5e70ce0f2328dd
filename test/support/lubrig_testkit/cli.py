"""`lubrig` in the test process: the same main() the console script runs, output captured.

Starting the real script costs seconds of CPU per call (it imports every subcommand); the tests
that prove the console script itself (exit status, a single stderr line from a fresh interpreter)
run it as a process, the many others call ``lubrig(...)`` here and assert the same things.
"""

from __future__ import annotations

import contextlib
import io
import subprocess


def lubrig(*args: str) -> subprocess.CompletedProcess[str]:
    """Run ``lubrig args`` in-process; returncode, stdout and stderr as a process would give them."""
    from lubrig_ros.cli.main import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(list(args))
        except SystemExit as exc:  # argparse errors and --help
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    return subprocess.CompletedProcess(["lubrig", *args], code, out.getvalue(), err.getvalue())
