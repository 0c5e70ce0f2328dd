"""Run configurations: YAML files in config/ merged over the study's rig (config/rig.yaml).

The same files drive the `lubrig` command line and the ROS nodes.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import yaml

from .. import __version__
from .friction_laws import DEFAULT_LAW
from .params import ParameterError, RigParameters, check_rig_ranges
from .profiles import BandProfile, profile_from_dict, profile_to_dict
from .schema import (
    CONVENTION,
    MAX_SAMPLES,
    MIN_SAMPLES_PER_PERIOD,
    RIG_OVERRIDES,
    SIMULATION_FIELDS,
    number_text,
)

SECTIONS = ("name", "description", "rig", "band", "simulation")
SIMULATION_KEYS: tuple[str, ...] = tuple(SIMULATION_FIELDS)
CASE_NUMBERS = range(1, 11)


_SOURCE_CONFIG = Path(__file__).resolve().parents[2] / "config"


def config_dir() -> Path:
    """Where the shipped YAML presets live: the source tree, else an install's share directory.

    Installed, they are in <prefix>/share/lubrig_ros/config for a prefix on AMENT_PREFIX_PATH
    (colcon / ament install, what ament_index_python would find) or sys.prefix (pip); looked up
    here without importing a ROS package, so core stays ROS-free.
    """
    here = _SOURCE_CONFIG
    if (here / "rig.yaml").is_file():
        return here
    import os
    import sys

    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    for prefix in [*prefixes, sys.prefix]:
        candidate = Path(prefix) / "share" / "lubrig_ros" / "config"
        if (candidate / "rig.yaml").is_file():
            return candidate
    return Path(sys.prefix) / "share" / "lubrig_ros" / "config"


@dataclass(frozen=True)
class RunConfig:
    """Everything that defines a run: rig, band profile and integration settings."""

    name: str
    description: str
    rig: RigParameters
    band: BandProfile
    duration: float  # s
    sample_rate: float  # Hz
    rtol: float
    initial_perturbation: float

    def __post_init__(self) -> None:
        for name, spec in SIMULATION_FIELDS.items():
            object.__setattr__(self, name, spec.check(getattr(self, name)))
        check_rig_ranges(self.rig)
        f0 = self.rig.natural_frequency
        if self.sample_rate < MIN_SAMPLES_PER_PERIOD * f0:
            raise ParameterError(
                f"sample_rate={self.sample_rate:g} Hz is too low for natural_frequency={f0:g} Hz: "
                f"expected at least {MIN_SAMPLES_PER_PERIOD} samples per period "
                f"(sample_rate >= {MIN_SAMPLES_PER_PERIOD * f0:g} Hz, or natural_frequency <= "
                f"{self.sample_rate / MIN_SAMPLES_PER_PERIOD:g} Hz)"
            )
        self._check_samples()
        band_hz = self.band.fundamental_hz
        if band_hz is not None and band_hz > self.sample_rate / 2.0:
            raise ParameterError(
                f"the band's frequency {band_hz:g} Hz is above half the sample rate "
                f"({self.sample_rate:g} Hz / 2): the samples cannot resolve it; keep it <= "
                f"{self.sample_rate / 2.0:g} Hz or raise sample_rate"
            )

    def _check_samples(self) -> None:
        """At least one output sample, at most MAX_SAMPLES (duration × sample_rate)."""
        samples = self.duration * self.sample_rate
        if round(samples) < 1:
            raise ParameterError(
                f"duration={self.duration!r} s holds no sample at sample_rate={self.sample_rate:g} Hz; "
                f"expected duration >= {1.0 / self.sample_rate:g} s (one sample period)"
            )
        if samples > MAX_SAMPLES:
            raise ParameterError(
                f"duration={self.duration:g} s at sample_rate={self.sample_rate:g} Hz is "
                f"{samples:.3g} samples; at most {number_text(MAX_SAMPLES)} (duration <= "
                f"{MAX_SAMPLES / self.sample_rate:g} s)"
            )

    @property
    def samples(self) -> int:
        """Number of output samples after t = 0."""
        return round(self.duration * self.sample_rate)

    def to_dict(self) -> dict[str, Any]:
        """YAML/JSON-ready mapping that from_mapping turns back into an equal config."""
        return {
            "name": self.name,
            "description": self.description,
            "rig": self.rig.to_dict(),
            "band": profile_to_dict(self.band),
            "simulation": {key: getattr(self, key) for key in SIMULATION_KEYS},
            "lubrig_ros_version": __version__,
        }

    def to_yaml(self) -> str:
        """The full configuration as YAML text (stored with every run)."""
        text: str = yaml.safe_dump(self.to_dict(), sort_keys=False)
        return text

    def with_overrides(self, **changes: Any) -> RunConfig:
        """Copy with rig fields (convention, damping_ratio, ...) or run fields replaced."""
        rig_fields = set(RIG_OVERRIDES)
        rig_changes = {k: v for k, v in changes.items() if k in rig_fields and v is not None}
        if CONVENTION in rig_changes and "velocity_coupling" not in rig_changes:
            rig_changes["velocity_coupling"] = None  # a named convention replaces an explicit γ
        run_changes = {k: v for k, v in changes.items() if k not in rig_fields and v is not None}
        return replace(self, rig=replace(self.rig, **rig_changes), **run_changes)


def _replaces_whole(key: str, base: dict[str, Any], over: dict[str, Any]) -> bool:
    """A 'band' section replaces whole; so does a 'friction' section naming another law."""
    if key == "band":
        return True
    return key == "friction" and over.get("law", DEFAULT_LAW) != base.get("law", DEFAULT_LAW)


_SCALARS = frozenset({str, int, float, bool, type(None)})


def copy_tree(data: Any) -> Any:
    """A copy of parsed YAML/JSON data: new dicts and lists, the same immutable scalars.

    What copy.deepcopy gives such data at a fifth of its cost (a sweep copies a mapping per
    point); any other object is deep-copied.
    """
    if type(data) in _SCALARS:
        return data
    if isinstance(data, dict):
        return {k: v if type(v) in _SCALARS else copy_tree(v) for k, v in data.items()}
    if isinstance(data, list):
        return [v if type(v) in _SCALARS else copy_tree(v) for v in data]
    return copy.deepcopy(data)


def deep_merge(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    """Copy of base with over merged in, mapping by mapping.

    A 'band' section replaces whole (one kind's fields mean nothing to another), and so does a
    'friction' section whose `law` differs from the base's.
    """
    merged: dict[str, Any] = copy_tree(base)
    for key, value in over.items():
        if (
            isinstance(value, dict)
            and isinstance(merged.get(key), dict)
            and not _replaces_whole(key, merged[key], value)
        ):
            merged[key] = deep_merge(merged[key], value)
        else:
            merged[key] = copy_tree(value)
    return merged


def _yaml_problem(exc: yaml.YAMLError) -> str:
    """A YAML error in one line: the problem and where (the parser's own text spans lines)."""
    problem = getattr(exc, "problem", None)
    mark = getattr(exc, "problem_mark", None)
    if problem and mark is not None:
        return f"{problem} at line {mark.line + 1}, column {mark.column + 1}"
    return " ".join(str(exc).split())


def read_yaml(path: Path, what: str = "config file", error: type[Exception] = ParameterError) -> Any:
    """Parse a YAML file; an unreadable or malformed file raises `error` naming the file."""
    try:
        return yaml.safe_load(path.read_text())
    except OSError as exc:
        raise error(f"{what} {str(path)!r} cannot be read: {exc.strerror}") from None
    except yaml.YAMLError as exc:
        raise error(f"{what} {str(path)!r} is not valid YAML: {_yaml_problem(exc)}") from None


def _read_yaml(path: Path) -> dict[str, Any]:
    data = read_yaml(path)
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ParameterError(f"config file {str(path)!r} must hold a mapping, not {type(data).__name__}")
    return data


_DEFAULTS: dict[tuple[str, int, int], dict[str, Any]] = {}


def defaults() -> dict[str, Any]:
    """The study's rig as a mapping (config/rig.yaml; a copy: parsed once per version of the file).

    A sweep builds one configuration per point over these defaults: parsing the file for each
    would take about 5 ms a point, most of the validation of a large grid.
    """
    copied: dict[str, Any] = copy_tree(_parsed_defaults())
    return copied


def _parsed_defaults() -> dict[str, Any]:
    """config/rig.yaml as parsed once per version of the file (not to be changed: shared)."""
    path = config_dir() / "rig.yaml"
    try:
        stat = path.stat()
    except OSError:
        return _read_yaml(path)  # names the file and why it cannot be read
    key = (str(path), stat.st_mtime_ns, stat.st_size)
    if key not in _DEFAULTS:
        _DEFAULTS.clear()
        _DEFAULTS[key] = _read_yaml(path)
    return _DEFAULTS[key]


def from_mapping(data: dict[str, Any], base_dir: Path | None = None) -> RunConfig:
    """Build a RunConfig from a mapping merged over the defaults; unknown keys are errors."""
    data = {k: v for k, v in data.items() if k != "lubrig_ros_version"}
    unknown = set(data) - set(SECTIONS)
    if unknown:
        raise ParameterError(f"unknown config section(s) {sorted(unknown)}; valid: {list(SECTIONS)}")
    merged = deep_merge(_parsed_defaults(), data)  # a copy: the parsed defaults stay as they are
    simulation = dict(merged.get("simulation") or {})
    unknown = set(simulation) - set(SIMULATION_KEYS)
    if unknown:
        raise ParameterError(
            f"unknown simulation setting(s) {sorted(unknown)}; valid: {list(SIMULATION_KEYS)}"
        )
    return RunConfig(
        name=str(merged.get("name", "run")),
        description=str(merged.get("description", "")),
        rig=RigParameters.from_dict(merged.get("rig") or {}),
        band=profile_from_dict(merged.get("band") or {}, base_dir=base_dir),
        **simulation,
    )


def load_config(path: str | Path) -> RunConfig:
    """Read a run configuration file (YAML) merged over the study's rig."""
    path = Path(path)
    return from_mapping(_read_yaml(path), base_dir=path.parent)


def load_case(number: int | str) -> RunConfig:
    """One of the study's Table 1 cases (1–10), paper convention."""
    try:
        n = int(number)
    except (TypeError, ValueError):
        n = -1
    if n not in CASE_NUMBERS:
        raise ParameterError(
            f"case={number!r} is not a study case; valid: {CASE_NUMBERS.start}..{CASE_NUMBERS.stop - 1}"
        )
    return load_config(config_dir() / "cases" / f"case{n:02d}.yaml")


def default_config() -> RunConfig:
    """The built-in default run (config/rig.yaml alone)."""
    return from_mapping({})
