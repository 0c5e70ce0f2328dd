"""Markdown tables of the contract (app/interface/contract.py, core/schema.py) for README.md and docs/.

The documents hold generated blocks between ``<!-- contract:NAME -->`` and
``<!-- /contract:NAME -->``; ``python -m lubrig_ros.app.interface.contract_docs`` rewrites them from the
contract and ``--check`` fails (exit 1, naming the file and block) when one is out of date
(test/test_contract.py runs the check).
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Callable
from pathlib import Path

from ...core.schema import SAMPLE_FIELDS, unit_column
from . import contract
from .contract import DEFAULT_NAMESPACE, NodeParameter


def _type(msgtype: str) -> str:
    pkg, _kind, name = msgtype.split("/")
    return f"{pkg}/{name}"


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def topic_table(namespace: str = DEFAULT_NAMESPACE) -> str:
    """Every topic: name, type, publisher, rate, unit, content, QoS."""
    rows = ["| topic | type | publisher | rate | unit | content | QoS |", "|---|---|---|---|---|---|---|"]
    for t in contract.TOPICS:
        rows.append(
            f"| `{contract.resolve(namespace, t.name)}` | {_type(t.msgtype)} | {_cell(t.publisher)} | "
            f"{_cell(t.rate)} | {_cell(t.unit)} | {_cell(t.description)} | {t.qos.describe()} |"
        )
    return "\n".join(rows)


def readme_topic_table(namespace: str = DEFAULT_NAMESPACE) -> str:
    """Short topic table for the README: name, type, unit, content."""
    rows = ["| topic | type | unit | content |", "|---|---|---|---|"]
    for t in contract.TOPICS:
        rows.append(
            f"| `{contract.resolve(namespace, t.name)}` | {_type(t.msgtype)} | {_cell(t.unit)} | "
            f"{_cell(t.description)} |"
        )
    return "\n".join(rows)


def service_table(namespace: str = DEFAULT_NAMESPACE) -> str:
    """Every service: name, type, server, what it does."""
    rows = ["| service | type | server | does |", "|---|---|---|---|"]
    for s in contract.SERVICES:
        rows.append(
            f"| `{contract.resolve(namespace, s.name)}` | {_type(s.srvtype)} | {s.server} | "
            f"{_cell(s.description)} |"
        )
    return "\n".join(rows)


def _default(p: NodeParameter) -> str:
    if p.default is None:
        return f"run configuration (`{p.from_config}`)"
    return f"`{p.default!r}`" if isinstance(p.default, str) else f"`{p.default}`"


def _valid(p: NodeParameter) -> str:
    if p.type == "string" and not p.choices:
        return "string"
    return p.expected()


def parameter_table(node: str) -> str:
    """The parameters of `node`: name, type, default, valid values, when settable, meaning."""
    rows = [
        "| parameter | type | default | valid | set | description |",
        "|---|---|---|---|---|---|",
    ]
    for p in contract.NODE_PARAMETERS[node]:
        unit = f" [{p.unit}]" if p.unit and p.unit not in ("1", "SI") else ""
        rows.append(
            f"| `{p.name}` | {p.type} | {_cell(_default(p))} | {_cell(_valid(p))} | "
            f"{'start' if p.read_only else 'run time'} | {_cell(p.description)}{unit} |"
        )
    return "\n".join(rows)


def friction_law_table() -> str:
    """The plant's friction.<field> parameters of every built-in friction law, with defaults."""
    from dataclasses import fields

    from ...core.friction_laws import BUILTIN_LAWS, law_parameters

    rows = ["| `friction.law` | `friction.<field>` parameters (default) |", "|---|---|"]
    for law in BUILTIN_LAWS:
        kind = law_parameters(law)
        defaults = {f.name: f.default for f in fields(kind)}
        cells = []
        for p in contract.friction_parameters(law):
            field = p.name.removeprefix("friction.")
            unit = f" {p.unit}" if p.unit and p.unit not in ("1", "SI") else ""
            cells.append(f"`{p.name}` ({defaults[field]:g}{unit})")
        rows.append(f"| `{law}` | {_cell(', '.join(cells))} |")
    return "\n".join(rows)


def sample_field_table() -> str:
    """The plant's per-sample output fields (core.schema.SAMPLE_FIELDS): column, unit, how computed."""
    rows = [
        "| field | table column | unit | symbol | meaning | computed as |",
        "|---|---|---|---|---|---|",
    ]
    for f in SAMPLE_FIELDS:
        rows.append(
            f"| `{f.name}` | `{unit_column(f.name, f.unit)}` | {f.unit} | {_cell(f.symbol)} | "
            f"{_cell(f.meaning)} | `{_cell(f.formula)}` |"
        )
    return "\n".join(rows)


def _parameters(node: str) -> Callable[[], str]:
    return lambda: parameter_table(node)


#: Generated blocks: name → text.
BLOCKS: dict[str, Callable[[], str]] = {
    "topics": topic_table,
    "readme-topics": readme_topic_table,
    "services": service_table,
    **{f"parameters-{node}": _parameters(node) for node in contract.NODE_PARAMETERS},
    "friction-laws": friction_law_table,
    "sample-fields": sample_field_table,
}
#: Documents (relative to the repository root) and the blocks each must hold.
DOCUMENTS: dict[str, tuple[str, ...]] = {
    "README.md": ("readme-topics",),
    "docs/topics.md": ("topics", "services", "sample-fields"),
    "docs/data.md": ("sample-fields",),
    "docs/nodes.md": ("services", *(f"parameters-{n}" for n in contract.NODE_PARAMETERS), "friction-laws"),
}
_BLOCK = re.compile(r"(<!-- contract:([a-z_-]+) -->\n)(.*?)(<!-- /contract:\2 -->)", re.S)


def render(text: str) -> str:
    """`text` with every generated block rewritten from the contract."""

    def fill(m: re.Match[str]) -> str:
        name = m.group(2)
        if name not in BLOCKS:
            raise KeyError(f"unknown contract block {name!r}; valid: {sorted(BLOCKS)}")
        return f"{m.group(1)}{BLOCKS[name]()}\n{m.group(4)}"

    return _BLOCK.sub(fill, text)


def problems(root: Path) -> list[str]:
    """What is out of date in the documents under `root` (empty: all in sync)."""
    found = []
    for name, blocks in DOCUMENTS.items():
        text = (root / name).read_text(encoding="utf-8")
        present = {m.group(2) for m in _BLOCK.finditer(text)}
        found += [f"{name}: block 'contract:{b}' missing" for b in blocks if b not in present]
        if render(text) != text:
            found.append(f"{name}: generated tables differ from app/interface/contract.py")
    return found


def main(argv: list[str] | None = None) -> int:
    """Rewrite (or --check) the generated tables of the documents."""
    parser = argparse.ArgumentParser(
        prog="python -m lubrig_ros.app.interface.contract_docs", description=__doc__
    )
    parser.add_argument("root", nargs="?", type=Path, default=Path.cwd(), help="repository root")
    parser.add_argument("--check", action="store_true", help="only report what is out of date")
    args = parser.parse_args(argv)
    if args.check:
        found = problems(args.root)
        for line in found:
            print(line, file=sys.stderr)
        return 1 if found else 0
    for name in DOCUMENTS:
        path = args.root / name
        text = path.read_text(encoding="utf-8")
        new = render(text)
        if new != text:
            path.write_text(new, encoding="utf-8")
            print(f"updated {name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
