"""The import graph of lubrig_ros follows the tiers of docs/architecture.md, read with ast.

Tiers: core 0, app 1, bag + figures 2, nodes + report + sweep + fit 3, study 4, cli 5 (modules
directly in lubrig_ros/, e.g. its __init__ with __version__, count as tier 0). A module may import
its own subpackage and lower tiers, never a higher tier and never a same-tier sibling package; no
import cycle between modules; core, app and study (with every subpackage of theirs) import no ROS
package. Every import counts, also those inside functions (a lazy import still ties the two
modules together). app/ holds at its top level only its subpackages by purpose and the modules
named in APP_MODULES. No module holds more than MAX_MODULE_LINES lines.
"""

from __future__ import annotations

import ast
import re
from functools import cache
from pathlib import Path

import pytest

PACKAGE = "lubrig_ros"
ROOT = Path(__file__).resolve().parents[1] / PACKAGE
TIERS = {
    "core": 0,
    "app": 1,
    "bag": 2,
    "figures": 2,
    "nodes": 3,
    "report": 3,
    "sweep": 3,
    "fit": 3,
    "study": 4,
    "cli": 5,
}
ROS_FREE = ("core", "app", "study")
#: Top-level modules of ROS 2 (not rosbags, mcap: those are plain Python libraries).
ROS_MODULE = re.compile(
    r"^(rclpy|rcl_\w+|rcutils|rmw\w*|rosidl\w*|ament_\w+|launch|launch_ros|rpyutils|tracetools"
    r"|\w+_msgs|\w+_srvs|\w+_interfaces)$"
)
#: Violations in files other helpers are changing in parallel (issue 10); the lead removes an
#: entry when its fix is merged. Each entry is (importer, imported).
EXPECTED_ELSEWHERE: set[tuple[str, str]] = set()


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


@cache
def modules() -> dict[str, Path]:
    """Every module of the package by dotted name."""
    return {_module_name(p): p for p in sorted(ROOT.rglob("*.py"))}


def _resolve(importer: str, is_package: bool, node: ast.ImportFrom) -> str:
    if node.level == 0:
        return node.module or ""
    base = importer.split(".") if is_package else importer.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


@cache
def imports() -> dict[str, set[str]]:
    """Module → the modules it imports (package-internal ones resolved to modules; others by top name)."""
    known = modules()
    graph: dict[str, set[str]] = {}
    for name, path in known.items():
        targets: set[str] = set()
        tree = ast.parse(path.read_text(), filename=str(path))
        is_package = path.name == "__init__.py"
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                targets.update(alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = _resolve(name, is_package, node)
                for alias in node.names:  # `from ..app import rundir` imports the module app.rundir
                    sub = f"{base}.{alias.name}"
                    targets.add(sub if sub in known else base)
        graph[name] = targets
    return graph


def _internal(target: str) -> str | None:
    """The package module a dotted import name refers to (its longest known prefix)."""
    if target != PACKAGE and not target.startswith(PACKAGE + "."):
        return None
    parts = target.split(".")
    while parts and ".".join(parts) not in modules():
        parts.pop()
    return ".".join(parts) if parts else None


def _subpackage(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[1] in TIERS else None


def tier_violations() -> set[tuple[str, str]]:
    """(importer, imported) pairs that go up a tier or sideways to a same-tier sibling package."""
    bad = set()
    for importer, targets in imports().items():
        own = _subpackage(importer)
        if own is None:
            continue
        for target in targets:
            module = _internal(target)
            other = _subpackage(module) if module else None
            if other is None or other == own:
                continue
            if TIERS[other] >= TIERS[own]:
                bad.add((importer, module))
    return bad


def internal_graph() -> dict[str, set[str]]:
    """Module → package modules it imports (no implicit parent-package edges)."""
    graph = {}
    for importer, targets in imports().items():
        graph[importer] = {m for t in targets if (m := _internal(t)) and m != importer}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def ros_imports(graph: dict[str, set[str]] | None = None) -> set[tuple[str, str]]:
    """(module, ROS module) for every ROS import in core/, app/ and study/, subpackages included."""
    bad = set()
    for importer, targets in (imports() if graph is None else graph).items():
        if _subpackage(importer) in ROS_FREE:
            bad.update((importer, t) for t in targets if ROS_MODULE.match(t.split(".")[0]))
    return bad


def test_the_walk_sees_the_package() -> None:
    graph = internal_graph()
    assert {"lubrig_ros.core.run", "lubrig_ros.app.selection", "lubrig_ros.cli.main"} <= set(graph)
    assert "lubrig_ros.core.integrator" in graph["lubrig_ros.core.run"]  # from .integrator import …
    assert "lubrig_ros.app.rundir" in graph["lubrig_ros.cli.simulate"]  # from ..app import rundir
    assert "lubrig_ros.core.presets" in graph["lubrig_ros.app.selection"]  # relative, two dots
    assert "lubrig_ros.app.interface.contract" in graph["lubrig_ros.app.plant.config"]  # ..interface
    assert "lubrig_ros.core.presets" in graph["lubrig_ros.app.plant.config"]  # relative, three dots
    assert "lubrig_ros.app.plant.modes" in graph["lubrig_ros.app.plant.session"]  # same subpackage
    assert "lubrig_ros.sweep.engine" in graph["lubrig_ros.study.scan"]  # the study on the sweep engine
    assert ROS_MODULE.match("rclpy") and ROS_MODULE.match("std_msgs") and not ROS_MODULE.match("rosbags")


def test_checks_catch_what_they_are_meant_to() -> None:
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []
    nested = {"lubrig_ros.app.plant.session": {"rclpy.node", "numpy"}, "lubrig_ros.nodes.plant": {"rclpy"}}
    assert ros_imports(nested) == {("lubrig_ros.app.plant.session", "rclpy.node")}


def test_no_import_cycle() -> None:
    assert cycles(internal_graph()) == []


def test_no_import_breaks_the_tiers() -> None:
    unexpected = tier_violations() - EXPECTED_ELSEWHERE
    assert not unexpected, "\n".join(f"{a} imports {b}" for a, b in sorted(unexpected))


@pytest.mark.xfail(bool(EXPECTED_ELSEWHERE), reason="tier violations in files other helpers own", strict=True)
def test_no_expected_violation_left() -> None:
    assert not (tier_violations() & EXPECTED_ELSEWHERE)


def test_core_app_and_study_are_ros_free() -> None:
    assert not ros_imports(), sorted(ros_imports())


#: app/'s subpackages, one purpose each (docs/architecture.md).
APP_SUBPACKAGES = {"analysis", "interface", "plant", "processes", "recording", "view"}
#: The modules directly in app/: each a purpose of its own.
APP_MODULES = {"belt_session", "fileio", "flow", "rundir", "selection", "timing"}


def test_app_top_level_holds_its_subpackages_and_named_modules() -> None:
    app = ROOT / "app"
    entries = {p.name for p in app.iterdir() if p.suffix == ".py" or (p.is_dir() and p.name != "__pycache__")}
    assert entries == {"__init__.py", *APP_SUBPACKAGES, *(f"{m}.py" for m in APP_MODULES)}
    assert all((app / sub / "__init__.py").is_file() for sub in APP_SUBPACKAGES)


#: Lines a module of the package may hold: past this it holds more than one job.
MAX_MODULE_LINES = 500


def test_no_module_over_the_size_limit() -> None:
    """Every module of the package stays within MAX_MODULE_LINES lines."""
    sizes = {path.relative_to(ROOT): len(path.read_text().splitlines()) for path in ROOT.rglob("*.py")}
    assert sizes, ROOT
    over = {str(path): n for path, n in sorted(sizes.items()) if n > MAX_MODULE_LINES}
    assert not over, f"modules over {MAX_MODULE_LINES} lines: {over}"
