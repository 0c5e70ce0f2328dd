"""Run the whole suite with every ROS test file in a pytest process of its own.

Why: in one long pytest process, the in-process probe (an rclpy context per test) started to miss
messages after several earlier ROS test files had run (test_nodes_sim and test_nodes_namespace
failed in the full suite and passed alone, on a quiet machine; docs/testing.md). Until that is
understood, each ROS file gets a fresh interpreter, which is also how ROS 2 launch tests run.

Usage: python -m lubrig_testkit.suite [pytest options] — runs `-m "not ros"` once over test/,
then `-m ros` for each file that has ROS tests; prints one closing line
"N passed, N failed, N skipped" and exits 1 if anything failed or errored.
"""

from __future__ import annotations

import re
import subprocess
import sys

SUMMARY = re.compile(r"(\d+) (passed|failed|error|errors|skipped|xfailed|xpassed)")


def _pytest(args: list[str]) -> tuple[int, dict[str, int]]:
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", *args],
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        check=False,
    )
    sys.stdout.write(proc.stdout)
    sys.stdout.flush()
    counts: dict[str, int] = {}
    lines = [line for line in proc.stdout.splitlines() if line.strip()]
    for number, word in SUMMARY.findall(lines[-1] if lines else ""):
        key = "error" if word.startswith("error") else word
        counts[key] = counts.get(key, 0) + int(number)
    return proc.returncode, counts


def ros_files(extra: list[str]) -> list[str]:
    """Test files that hold at least one test marked ros."""
    command = [sys.executable, "-m", "pytest", "--collect-only", "-q", "-m", "ros", *extra, "test"]
    proc = subprocess.run(command, text=True, capture_output=True, check=False)
    return sorted({line.split("::")[0] for line in proc.stdout.splitlines() if "::" in line})


def main(argv: list[str] | None = None) -> int:
    extra = list(sys.argv[1:] if argv is None else argv)
    total: dict[str, int] = {}
    failed = False
    runs = [["-m", "not ros", *extra, "test"]] + [["-m", "ros", *extra, f] for f in ros_files(extra)]
    for args in runs:
        code, counts = _pytest(args)
        failed |= code not in (0, 5)
        for key, value in counts.items():
            total[key] = total.get(key, 0) + value
    if not total.get("passed"):
        failed = True
    failed |= bool(total.get("failed") or total.get("error"))
    print(
        f"{total.get('passed', 0)} passed, {total.get('failed', 0) + total.get('error', 0)} failed, "
        f"{total.get('skipped', 0)} skipped"
    )
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
