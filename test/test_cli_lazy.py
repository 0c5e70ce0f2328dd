"""`lubrig SUBCOMMAND` imports that subcommand's module only (cli/main.py)."""

from __future__ import annotations

import subprocess
import sys

from lubrig_ros.cli.main import SUBCOMMAND_MODULES, _subcommand

PROBE = (
    "import sys\n"
    "from lubrig_ros.cli.main import main\n"
    "try:\n"
    "    main(sys.argv[1:])\n"
    "except SystemExit:\n"
    "    pass\n"
    "heavy = sorted(m for m in ('numba', 'scipy.signal', 'matplotlib', 'rclpy', 'lubrig_ros.cli.rig')"
    " if m in sys.modules)\n"
    "print('HEAVY', ','.join(heavy))\n"
)


def _heavy_modules(*argv: str) -> list[str]:
    out = subprocess.run(
        [sys.executable, "-c", PROBE, *argv], capture_output=True, text=True, timeout=120, check=True
    ).stdout
    line = next(x for x in out.splitlines() if x.startswith("HEAVY"))
    return [m for m in line.split(" ", 1)[1].split(",") if m]


def test_the_subcommand_is_the_first_word_only():
    assert _subcommand(["friction", "--case", "1"]) == "friction"
    assert _subcommand(["--help"]) is None
    assert _subcommand([]) is None
    assert _subcommand(["frictoin"]) is None
    assert _subcommand(["--verbose", "friction"]) is None  # not the first word: full parser decides


def test_friction_help_imports_neither_the_rig_nor_the_kernels():
    assert _heavy_modules("friction", "--help") == []


def test_full_help_still_lists_every_subcommand():
    out = subprocess.run(
        [sys.executable, "-m", "lubrig_ros.cli.main", "--help"],
        capture_output=True,
        text=True,
        timeout=120,
    ).stdout
    for name in SUBCOMMAND_MODULES:
        assert name in out
