"""Sweep specifications: a base run configuration, axes over dotted parameter paths, a design.

A spec is validated completely before any work starts: every axis path must name an existing
parameter of the base configuration, every range must be non-empty, and every point's full run
configuration is built (so a negative damping ratio or an invalid band fails here, naming the
point and its parameter values).
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from lubrig_ros.core.errors import LubrigError

from ..app.selection import RunSelection
from ..core.params import ParameterError
from ..core.presets import RunConfig, copy_tree, deep_merge, from_mapping, read_yaml

SPEC_KEYS = ("name", "description", "base", "base_case", "design", "samples", "seed", "wavelet", "axes")
DESIGNS = ("grid", "random", "lhs")
GRID_KINDS = ("values", "linspace", "logspace")
SAMPLED_KINDS = ("uniform", "loguniform")
#: Paths that are not numbers or choices one can sweep (identity of the run, not physics; a band
#: kind's or friction law's fields mean nothing to another kind or law).
NOT_SWEEPABLE = ("name", "description", "band.kind", "band.source", "rig.friction.law")
MAX_POINTS = 1_000_000


class SpecError(LubrigError, ValueError):
    """An invalid sweep specification; the message names the bad value and what is valid."""


@dataclass(frozen=True)
class Axis:
    """One swept parameter: its dotted path and the values (grid) or range (sampled) it takes."""

    parameter: str
    kind: str  # values | linspace | logspace | uniform | loguniform
    values: tuple[Any, ...] = ()  # grid axes
    low: float = math.nan  # sampled axes
    high: float = math.nan

    @property
    def log(self) -> bool:
        """Whether the axis is drawn on a log scale: log-spaced, or positive values over >= 20x."""
        if self.kind in ("logspace", "loguniform"):
            return True
        numbers = [v for v in self.values if isinstance(v, (int, float)) and not isinstance(v, bool)]
        return (
            self.kind == "values"
            and len(numbers) == len(self.values) > 2
            and min(numbers) > 0
            and max(numbers) >= 20 * min(numbers)
        )


@dataclass(frozen=True)
class Point:
    """One sweep point: its index, id, axis values and the full run configuration mapping."""

    index: int
    point_id: str
    values: dict[str, Any]
    config: dict[str, Any]  # RunConfig.to_dict() without the version (from_mapping input)
    wavelet: bool


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep: the spec as given, its axes and its expanded points."""

    name: str
    description: str
    design: str
    axes: tuple[Axis, ...]
    points: tuple[Point, ...]
    source: dict[str, Any]  # the spec mapping as given (re-parseable)

    @property
    def fingerprint(self) -> str:
        """Hash of the spec and of every point's full configuration: one results directory, one sweep."""
        return _digest({"spec": self.source, "points": [p.point_id for p in self.points]})

    def to_yaml(self) -> str:
        """The spec as given, as YAML (written to DIR/spec.yaml and into the Parquet metadata)."""
        return yaml.safe_dump(self.source, sort_keys=False)

    def axes_metadata(self) -> list[dict[str, Any]]:
        """Axis descriptions for the table metadata and the figures."""
        return [
            {
                "parameter": a.parameter,
                "kind": a.kind,
                "log": a.log,
                "values": list(a.values),
                "low": None if math.isnan(a.low) else a.low,
                "high": None if math.isnan(a.high) else a.high,
            }
            for a in self.axes
        ]


def _digest(data: Any) -> str:
    text = json.dumps(data, sort_keys=True, separators=(",", ":"), allow_nan=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _number(where: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SpecError(f"{where}={value!r} is not a number; expected a finite number")
    if not math.isfinite(float(value)):
        raise SpecError(f"{where}={value!r} is not finite; expected a finite number")
    return float(value)


def _count(where: str, value: Any, low: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise SpecError(f"{where}={value!r} is not valid; expected an integer >= {low}")
    return value


def _leaf_paths(mapping: dict[str, Any], prefix: str = "") -> list[str]:
    paths = []
    for key, value in mapping.items():
        path = f"{prefix}{key}"
        if isinstance(value, dict):
            paths.extend(_leaf_paths(value, path + "."))
        else:
            paths.append(path)
    return paths


def base_mapping(spec: dict[str, Any], base_dir: Path | None = None) -> dict[str, Any]:
    """Full run mapping of the spec's base (base_case, then base merged over it, over rig.yaml)."""
    start: dict[str, Any] = {}
    if spec.get("base_case") is not None:
        try:
            start = RunSelection(case=spec["base_case"]).base().to_dict()
        except ParameterError as exc:
            raise SpecError(f"base_case: {exc}") from None
    base = spec.get("base") or {}
    if not isinstance(base, dict):
        raise SpecError(f"base={base!r} is not valid; expected a run configuration mapping")
    merged = deep_merge(start, base)
    try:
        config = from_mapping(merged, base_dir=base_dir)
    except ParameterError as exc:
        raise SpecError(f"base: {exc}") from None
    return _config_mapping(config)


def _config_mapping(config: RunConfig) -> dict[str, Any]:
    data = config.to_dict()
    data.pop("lubrig_ros_version", None)
    return data


def _set_path(mapping: dict[str, Any], path: str, value: Any) -> None:
    keys = path.split(".")
    node = mapping
    for key in keys[:-1]:
        node = node[key]
    node[keys[-1]] = value


def _parse_axis(index: int, raw: Any, design: str, valid_paths: list[str]) -> Axis:
    where = f"axes[{index}]"
    if not isinstance(raw, dict):
        raise SpecError(f"{where}={raw!r} is not valid; expected a mapping with 'parameter' and a range")
    parameter = raw.get("parameter")
    if not isinstance(parameter, str) or not parameter:
        raise SpecError(
            f"{where}.parameter={parameter!r} is not valid; expected a dotted path like rig.damping_ratio"
        )
    if parameter not in valid_paths:
        raise SpecError(
            f"{where}.parameter={parameter!r} is not a parameter of the base configuration; "
            f"valid: {valid_paths}"
        )
    kinds = GRID_KINDS if design == "grid" else SAMPLED_KINDS
    given = [key for key in raw if key != "parameter"]
    unknown = [key for key in given if key not in kinds]
    if unknown or len(given) != 1:
        raise SpecError(
            f"{where} ({parameter}) has {given or 'no range'}; "
            f"a {design} design needs exactly one of {list(kinds)}"
        )
    kind = given[0]
    return _AXIS_KINDS[kind](where, parameter, kind, raw[kind])


def _values_axis(where: str, parameter: str, kind: str, body: Any) -> Axis:
    """values: [v, ...] (each once)."""
    if not isinstance(body, list) or not body:
        raise SpecError(f"{where} ({parameter}) values={body!r} is empty or not a list; expected >= 1 value")
    values = tuple(body)
    if len(set(map(repr, values))) != len(values):
        raise SpecError(f"{where} ({parameter}) values={body!r} repeats a value; each value once")
    return Axis(parameter, kind, values=values)


def _keys(where: str, parameter: str, kind: str, body: Any, keys: set[str]) -> dict[str, Any]:
    if not isinstance(body, dict):
        raise SpecError(f"{where} ({parameter}) {kind}={body!r} is not valid; expected a mapping")
    if set(body) != keys:
        raise SpecError(
            f"{where} ({parameter}) {kind}={body!r} is not valid; expected keys {', '.join(sorted(keys))}"
        )
    return body


def _spaced_axis(where: str, parameter: str, kind: str, body: Any) -> Axis:
    """Linspace / logspace: {start, stop, num} (logspace: values > 0, not exponents)."""
    body = _keys(where, parameter, kind, body, {"start", "stop", "num"})
    start = _number(f"{where}.{kind}.start", body["start"])
    stop = _number(f"{where}.{kind}.stop", body["stop"])
    num = _count(f"{where}.{kind}.num", body["num"])
    if num > 1 and start == stop:
        raise SpecError(f"{where} ({parameter}) {kind} start = stop = {start!r} with num={num}: empty range")
    if kind == "logspace" and (start <= 0 or stop <= 0):
        raise SpecError(
            f"{where} ({parameter}) logspace start={start!r}, stop={stop!r}: "
            "both must be > 0 (they are values, not exponents)"
        )
    grid = np.geomspace(start, stop, num) if kind == "logspace" else np.linspace(start, stop, num)
    return Axis(parameter, kind, values=tuple(float(v) for v in grid))


def _range_axis(where: str, parameter: str, kind: str, body: Any) -> Axis:
    """Uniform / loguniform: {low, high}, low < high (loguniform: low > 0)."""
    body = _keys(where, parameter, kind, body, {"low", "high"})
    low = _number(f"{where}.{kind}.low", body["low"])
    high = _number(f"{where}.{kind}.high", body["high"])
    if not low < high:
        raise SpecError(
            f"{where} ({parameter}) {kind} low={low!r} >= high={high!r}: empty range; need low < high"
        )
    if kind == "loguniform" and low <= 0:
        raise SpecError(f"{where} ({parameter}) loguniform low={low!r} must be > 0")
    return Axis(parameter, kind, low=low, high=high)


#: How each kind of axis range is read (GRID_KINDS and SAMPLED_KINDS say which design takes it).
_AXIS_KINDS: dict[str, Callable[[str, str, str, Any], Axis]] = {
    "values": _values_axis,
    "linspace": _spaced_axis,
    "logspace": _spaced_axis,
    "uniform": _range_axis,
    "loguniform": _range_axis,
}


def _axis_size(raw: Any) -> int:
    """Values a grid axis will take, read from the spec without building them.

    1 for a malformed axis: its own check names what is wrong.
    """
    if not isinstance(raw, dict):
        return 1
    body = next((raw[kind] for kind in GRID_KINDS if kind in raw), None)
    if isinstance(body, list):
        return max(len(body), 1)
    num = body.get("num") if isinstance(body, dict) else None
    return num if isinstance(num, int) and not isinstance(num, bool) and num > 1 else 1


def _count_text(n: int) -> str:
    """A count as digits, or as its power of ten when that would be long (10**400 has no str)."""
    return str(n) if n < 10**15 else f"~1e{int(n.bit_length() * math.log10(2))}"


def _check_grid_size(raw_axes: list[Any]) -> None:
    """Refuse a grid of more than MAX_POINTS points before any axis or point is built.

    The count is the product of the axis sizes the spec states (a `num` of 10**12 would
    otherwise be expanded, in memory, before it could be counted).
    """
    sizes = [_axis_size(raw) for raw in raw_axes]
    total = math.prod(sizes)
    if total > MAX_POINTS:
        raise SpecError(
            f"the grid has {_count_text(total)} points ({' x '.join(map(_count_text, sizes))}); "
            f"at most {MAX_POINTS} are allowed"
        )


def _design_values(spec: dict[str, Any], design: str, axes: list[Axis]) -> list[tuple[Any, ...]]:
    if design == "grid":
        if spec.get("samples") is not None or spec.get("seed") is not None:
            raise SpecError(
                "samples and seed apply to random and lhs designs only; remove them for design=grid"
            )
        return list(itertools.product(*(axis.values for axis in axes)))  # size: _check_grid_size
    samples = _count("samples", spec.get("samples"))
    if samples > MAX_POINTS:
        raise SpecError(f"samples={samples} is too many; at most {MAX_POINTS}")
    seed = _count("seed", spec.get("seed"), low=0)
    if design == "random":
        unit = np.random.default_rng(seed).random((samples, len(axes)))
    else:
        from scipy.stats import qmc

        unit = qmc.LatinHypercube(d=len(axes), seed=np.random.default_rng(seed)).random(samples)
    columns = []
    for j, axis in enumerate(axes):
        u = unit[:, j]
        if axis.kind == "loguniform":
            column = np.exp(math.log(axis.low) + u * (math.log(axis.high) - math.log(axis.low)))
        else:
            column = axis.low + u * (axis.high - axis.low)
        columns.append([float(v) for v in column])
    return list(zip(*columns, strict=True))


def parse_spec(data: Any, base_dir: Path | None = None) -> SweepSpec:
    """Validate a spec mapping and expand its points (raises SpecError before any work)."""
    if not isinstance(data, dict):
        raise SpecError(f"a sweep spec must be a mapping, not {type(data).__name__}")
    unknown = sorted(set(data) - set(SPEC_KEYS))
    if unknown:
        raise SpecError(f"unknown spec key(s) {unknown}; valid: {list(SPEC_KEYS)}")
    design = data.get("design", "grid")
    if design not in DESIGNS:
        raise SpecError(f"design={design!r} is not valid; expected one of {list(DESIGNS)}")
    wavelet = data.get("wavelet", True)
    if not isinstance(wavelet, bool):
        raise SpecError(f"wavelet={wavelet!r} is not valid; expected true or false")
    base = base_mapping(data, base_dir)
    valid_paths = [p for p in _leaf_paths(base) if p not in NOT_SWEEPABLE]
    raw_axes = data.get("axes")
    if not isinstance(raw_axes, list) or not raw_axes:
        raise SpecError(f"axes={raw_axes!r} is not valid; expected a non-empty list of axes")
    if design == "grid":
        _check_grid_size(raw_axes)
    axes = [_parse_axis(i, raw, design, valid_paths) for i, raw in enumerate(raw_axes)]
    seen: set[str] = set()
    for axis in axes:
        if axis.parameter in seen:
            raise SpecError(f"duplicate axis {axis.parameter!r}: each parameter may appear on one axis only")
        seen.add(axis.parameter)
    rows = _design_values(data, design, axes)
    name = str(data.get("name", "sweep"))
    points = []
    for index, row in enumerate(rows):
        values = {axis.parameter: value for axis, value in zip(axes, row, strict=True)}
        mapping: dict[str, Any] = copy_tree(base)
        for path, value in values.items():
            _set_path(mapping, path, value)
        mapping["name"] = f"{name}#{index}"
        try:
            config = from_mapping(mapping, base_dir=base_dir)
        except (ParameterError, TypeError) as exc:
            shown = ", ".join(f"{k}={v!r}" for k, v in values.items())
            raise SpecError(f"point {index} ({shown}): {exc}") from None
        full = _config_mapping(config)
        points.append(Point(index, f"p{index:06d}-{_digest(full)[:8]}", values, full, wavelet))
    normalized = copy.deepcopy(data)
    return SweepSpec(name, str(data.get("description", "")), design, tuple(axes), tuple(points), normalized)


def load_spec(path: str | Path) -> SweepSpec:
    """Read and validate a sweep spec YAML file."""
    path = Path(path)
    data = read_yaml(path, "sweep spec", SpecError)
    try:
        return parse_spec(data, base_dir=path.parent)
    except SpecError as exc:
        raise SpecError(f"{path}: {exc}") from None
