"""Register lubrig_ros in an ament prefix as colcon's ament_python build installs it (`make setup`).

`pip install -e .` installs the package's console scripts in PREFIX/bin and none of setup.py's
`data_files`, so neither `ros2 run lubrig_ros plant` nor `ros2 launch lubrig_ros rig.launch.py`
would find the package. This puts into PREFIX what a colcon build installs, read from setup.py
itself (run with `setuptools.setup` replaced, so its lists have one home):

* every data file at its place: the marker share/ament_index/resource_index/packages/lubrig_ros,
  share/lubrig_ros/package.xml, share/lubrig_ros/launch/*.py, share/lubrig_ros/config/...;
* PREFIX/lib/lubrig_ros/NAME for every console script (where setup.cfg's script_dir puts them in
  a colcon build, and where `ros2 run` looks), next to PREFIX/bin/NAME.

Each entry is a symlink, as `colcon build --symlink-install` makes them: the editable install
runs the work tree's code, and with links the launch file and the YAML files it reads are the
work tree's too (a copy would go stale at the first edit until the next `make setup`). A data
file links to the work tree's file, an executable to pip's script PREFIX/bin/NAME (its shebang is
the venv's interpreter). Rerunning is cheap and safe while something reads the index: a link is
replaced (atomically, os.replace) only when it points elsewhere, and entries of
share/lubrig_ros and lib/lubrig_ros that setup.py no longer lists are removed.

    python -m lubrig_ros.app.processes.ament_install [--prefix PREFIX] [--source DIR] [--check]

`--check` changes nothing and exits 1 naming what is missing or stale.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import runpy
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

PACKAGE = "lubrig_ros"


@dataclass(frozen=True)
class Entry:
    """One link of the install: PREFIX-relative `path` → absolute `target`."""

    path: Path
    target: Path


def setup_arguments(source: Path) -> dict[str, Any]:
    """The keyword arguments setup.py in `source` passes to setuptools.setup (nothing is built)."""
    setuptools: Any = importlib.import_module("setuptools")  # no type information installed
    captured: dict[str, Any] = {}
    original = setuptools.setup

    def capture(**kwargs: Any) -> None:
        captured.update(kwargs)

    setuptools.setup = capture
    try:
        with contextlib.chdir(source):  # setup.py's globs and find_packages are relative to it
            runpy.run_path(str(source / "setup.py"), run_name="__main__")
    finally:
        setuptools.setup = original
    if not captured:
        raise RuntimeError(f"{source / 'setup.py'} did not call setuptools.setup")
    return captured


def console_scripts(arguments: dict[str, Any]) -> list[str]:
    """Names of the console scripts of setup.py's entry_points."""
    scripts = arguments.get("entry_points", {}).get("console_scripts", [])
    return [spec.split("=", 1)[0].strip() for spec in scripts]


def entries(source: Path, prefix: Path) -> list[Entry]:
    """Every link the install makes, from setup.py in `source`, for `prefix`."""
    source = source.resolve()
    arguments = setup_arguments(source)
    package = arguments.get("name", PACKAGE)
    found: list[Entry] = []
    for directory, files in arguments.get("data_files", []):
        for name in files:
            found.append(Entry(Path(directory) / Path(name).name, source / name))
    for script in console_scripts(arguments):
        found.append(Entry(Path("lib") / package / script, prefix.absolute() / "bin" / script))
    return found


def _managed(prefix: Path, package: str) -> list[Path]:
    """The folders that belong to the package alone (stale entries there are removed)."""
    return [prefix / "share" / package, prefix / "lib" / package]


def _stale(prefix: Path, package: str, wanted: set[Path]) -> list[Path]:
    out: list[Path] = []
    for root in _managed(prefix, package):
        if root.is_dir():
            files = (p for p in sorted(root.rglob("*")) if p.is_symlink() or p.is_file())
            out.extend(p for p in files if p not in wanted)
    return out


def problems(source: Path, prefix: Path, package: str = PACKAGE) -> list[str]:
    """What is missing, wrong or stale in `prefix` (empty: the install is current)."""
    found: list[str] = []
    listed = entries(source, prefix)
    for entry in listed:
        path = prefix / entry.path
        if not entry.target.exists():
            found.append(f"{entry.target} (for {path}) does not exist")
        elif not (path.is_symlink() and Path(os.readlink(path)) == entry.target):
            found.append(f"{path} is not a link to {entry.target}")
    stale = _stale(prefix, package, {prefix / e.path for e in listed})
    found += [f"{p} is not listed by setup.py" for p in stale]
    return found


def install(source: Path, prefix: Path, package: str = PACKAGE) -> list[str]:
    """Make every link (only those that are not yet right), remove stale ones; what changed."""
    changed: list[str] = []
    listed = entries(source, prefix)
    missing = [e.target for e in listed if not e.target.exists()]
    if missing:
        raise FileNotFoundError(
            f"not found: {', '.join(map(str, missing))} (the console scripts come from "
            "`pip install -e .` into the prefix: run make setup)"
        )
    for entry in listed:
        path = prefix / entry.path
        if path.is_symlink() and Path(os.readlink(path)) == entry.target:
            continue
        path.parent.mkdir(parents=True, exist_ok=True)
        if path.is_dir() and not path.is_symlink():
            raise IsADirectoryError(f"{path} is a folder; expected a link to {entry.target}")
        temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        temporary.unlink(missing_ok=True)
        temporary.symlink_to(entry.target)
        os.replace(temporary, path)  # readers see the old entry or the new one, never none
        changed.append(f"{path} -> {entry.target}")
    for stale in _stale(prefix, package, {prefix / e.path for e in listed}):
        stale.unlink()
        changed.append(f"{stale} removed (not listed by setup.py)")
    for root in _managed(prefix, package):  # folders left empty by removals
        for folder in sorted((p for p in root.rglob("*") if p.is_dir()), reverse=True):
            with contextlib.suppress(OSError):
                folder.rmdir()
    return changed


def main(argv: list[str] | None = None) -> int:
    """Command line: install (default) or --check."""
    parser = argparse.ArgumentParser(
        prog="python -m lubrig_ros.app.processes.ament_install",
        description="Register lubrig_ros in an ament prefix (share/, lib/lubrig_ros) as a colcon "
        "ament_python build with --symlink-install does.",
    )
    parser.add_argument(
        "--prefix",
        type=Path,
        default=Path(sys.prefix),
        help="the ament prefix (default: this interpreter's prefix, the venv)",
    )
    parser.add_argument(
        "--source", type=Path, default=Path.cwd(), help="the folder of setup.py (default: the current folder)"
    )
    parser.add_argument("--check", action="store_true", help="change nothing; exit 1 if not current")
    args = parser.parse_args(argv)
    prefix = args.prefix.absolute()
    if args.check:
        found = problems(args.source, prefix)
        for line in found:
            print(f"ament index: {line}", file=sys.stderr)
        return 1 if found else 0
    try:
        changed = install(args.source, prefix)
    except (OSError, RuntimeError) as exc:
        print(f"ament index: error: {exc}", file=sys.stderr)
        return 1
    if changed:
        print(
            f"ament index: {PACKAGE} registered in {prefix} ({len(changed)} entries changed; "
            f"ros2 run / ros2 launch with AMENT_PREFIX_PATH={prefix})"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
