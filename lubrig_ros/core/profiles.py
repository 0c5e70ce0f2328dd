"""Band velocity profiles v_band(t) in m/s, registered by kind: constant, cycle, sine, table (CSV).

Every kind is a small frozen dataclass decorated with :func:`register_profile`; it has a class
attribute ``kind`` (its name in YAML ``band: {kind: ...}`` and in the belt_drive node's
``profile.kind``), is callable as v_band(t), and says its ``fundamental_hz`` (None if not periodic)
and the band velocities at which a steady linear verdict is taken (``verdict_velocities``). The
node, the sweep and the CLI ask the registry (:func:`profile_from_dict`, :func:`profile_kinds`,
:class:`ProfileParameters`) and never branch on a kind's name. A new kind is one class here or in
its own module plus its tests (docs/extending.md).
"""

from __future__ import annotations

import csv
import importlib
import math
from collections.abc import Callable, Mapping
from dataclasses import MISSING, asdict, dataclass, field, fields
from pathlib import Path
from typing import Any, ClassVar, Protocol, TypeVar

import numpy as np

from lubrig_ros.core.errors import InputError

from .schema import BAND_FIELDS, BAND_VELOCITY_LIMIT, band_field
from .validation import ParameterError


def _checked(kind: str, name: str, value: Any) -> float:
    """A profile field's value inside its physical range (core/schema.py BAND_FIELDS)."""
    return BAND_FIELDS[kind][name].check(value)


class BandProfile(Protocol):
    """What every registered profile kind provides."""

    kind: ClassVar[str]

    @property
    def fundamental_hz(self) -> float | None:
        """Frequency of the periodic forcing in Hz, None if the profile is not periodic."""
        ...

    def __call__(self, time: np.typing.ArrayLike) -> np.ndarray:
        """v_band(t) in m/s for t in s."""
        ...

    def verdict_velocities(self) -> tuple[float, ...]:
        """Band velocities (m/s) at which a steady linear verdict judges this profile."""
        ...


_KINDS: dict[str, type[Any]] = {}
_P = TypeVar("_P", bound=type)

#: Modules holding further kinds (each registers its class with @register_profile), imported on
#: the first registry lookup. A new kind in a module of its own is listed here (its registration).
PROFILE_MODULES: tuple[str, ...] = ()


def _load_modules() -> None:
    for module in PROFILE_MODULES:
        importlib.import_module(module)


def register_profile(cls: _P) -> _P:
    """Class decorator: register a profile dataclass under its class attribute `kind`."""
    kind = getattr(cls, "kind", None)
    if not isinstance(kind, str) or not kind:
        raise InputError(f"{cls.__name__} needs a class attribute kind (a non-empty string)")
    if kind in _KINDS and _KINDS[kind] is not cls:
        raise InputError(f"band profile kind {kind!r} is already registered ({_KINDS[kind].__name__})")
    _KINDS[kind] = cls
    return cls


def unregister_profile(kind: str) -> None:
    """Remove a kind added by register_profile (for tests of extension kinds)."""
    _KINDS.pop(kind, None)


def profile_kinds() -> list[str]:
    """Every registered kind, in registration order."""
    _load_modules()
    return list(_KINDS)


def profile_class(kind: Any) -> type[Any]:
    """The class registered for `kind`; ParameterError naming the valid kinds otherwise."""
    _load_modules()
    try:
        return _KINDS[kind]
    except (KeyError, TypeError):
        raise ParameterError(f"band kind={kind!r} is not valid; expected one of {profile_kinds()}") from None


@register_profile
@dataclass(frozen=True)
class ConstantBand:
    """Constant band velocity."""

    velocity: float = 1e-7

    kind: ClassVar[str] = "constant"

    def __post_init__(self) -> None:
        object.__setattr__(self, "velocity", _checked(self.kind, "velocity", self.velocity))

    @property
    def fundamental_hz(self) -> float | None:
        """No periodic forcing."""
        return None

    def __call__(self, time: np.typing.ArrayLike) -> np.ndarray:
        """v_band(t) in m/s for t in s."""
        return np.full(np.shape(time), self.velocity, dtype=float)

    def verdict_velocities(self) -> tuple[float, ...]:
        """Its velocity, whatever its sign (0 has no sliding equilibrium: the verdict says so)."""
        return (self.velocity,)


@register_profile
@dataclass(frozen=True)
class RegularCycle:
    """The study's band cycle between V1 (zone 2) and V2 (zone 3), period T_ramp + T_c.

    Ramp up V1 → V2 in T_ramp/2, plateau V2 for T_c/2, ramp down in T_ramp/2, plateau V1 for T_c/2,
    starting at V1 at t = 0.
    """

    low_velocity: float = 1e-7  # V1
    high_velocity: float = 2e-7  # V2
    plateau_time: float = 0.01  # T_c (both plateaus together)
    ramp_time: float = 0.2  # T_ramp (both ramps together)

    kind: ClassVar[str] = "cycle"

    def __post_init__(self) -> None:
        low = _checked(self.kind, "low_velocity", self.low_velocity)
        high = _checked(self.kind, "high_velocity", self.high_velocity)
        if high <= low:
            raise ParameterError(
                f"high_velocity={self.high_velocity!r} must be greater than "
                f"low_velocity={self.low_velocity!r} (V2 > V1)"
            )
        plateau = _checked(self.kind, "plateau_time", self.plateau_time)
        ramp = _checked(self.kind, "ramp_time", self.ramp_time)
        for name, value in (
            ("low_velocity", low),
            ("high_velocity", high),
            ("plateau_time", plateau),
            ("ramp_time", ramp),
        ):
            object.__setattr__(self, name, value)

    @property
    def period(self) -> float:
        """T_belt = T_ramp + T_c in s."""
        return self.ramp_time + self.plateau_time

    @property
    def fundamental_hz(self) -> float:
        """1 / T_belt."""
        return 1.0 / self.period

    def __call__(self, time: np.typing.ArrayLike) -> np.ndarray:
        """v_band(t) in m/s for t in s."""
        t = np.mod(np.asarray(time, dtype=float), self.period)
        half_ramp, half_plateau = self.ramp_time / 2.0, self.plateau_time / 2.0
        rise_end = half_ramp
        top_end = rise_end + half_plateau
        fall_end = top_end + half_ramp
        span = self.high_velocity - self.low_velocity
        with np.errstate(divide="ignore", invalid="ignore"):
            rising = self.low_velocity + span * t / half_ramp
            falling = self.high_velocity - span * (t - top_end) / half_ramp
        return np.select(
            [t < rise_end, t < top_end, t < fall_end],
            [rising, np.full_like(t, self.high_velocity), falling],
            default=self.low_velocity,
        )

    def verdict_velocities(self) -> tuple[float, ...]:
        """Both plateaus, V1 and V2, those > 0 (the cycle is stable only if both are)."""
        return tuple(v for v in (self.low_velocity, self.high_velocity) if v > 0.0)


@register_profile
@dataclass(frozen=True)
class SinusoidalBand:
    """v_band = mean + amplitude · sin(2π f t + phase)."""

    mean_velocity: float = 1.5e-7
    amplitude: float = 5e-8
    frequency: float = 1.0  # Hz
    phase: float = 0.0  # rad

    kind: ClassVar[str] = "sine"

    def __post_init__(self) -> None:
        for name in ("mean_velocity", "amplitude", "frequency", "phase"):
            object.__setattr__(self, name, _checked(self.kind, name, getattr(self, name)))
        reach = abs(self.mean_velocity) + self.amplitude
        if reach > BAND_VELOCITY_LIMIT:
            raise ParameterError(
                f"mean_velocity={self.mean_velocity!r} with amplitude={self.amplitude!r} reaches "
                f"|v_band| = {reach:g} m/s; keep |mean_velocity| + amplitude <= "
                f"{BAND_VELOCITY_LIMIT:g} m/s"
            )

    @property
    def fundamental_hz(self) -> float:
        """The sine's own frequency."""
        return self.frequency

    def __call__(self, time: np.typing.ArrayLike) -> np.ndarray:
        """v_band(t) in m/s for t in s."""
        t = np.asarray(time, dtype=float)
        return self.mean_velocity + self.amplitude * np.sin(2.0 * math.pi * self.frequency * t + self.phase)

    def verdict_velocities(self) -> tuple[float, ...]:
        """The mean velocity if > 0."""
        return (self.mean_velocity,) if self.mean_velocity > 0.0 else ()


@register_profile
@dataclass(frozen=True)
class TableBand:
    """Piecewise-linear band velocity through (time, velocity) points; holds the end values."""

    times: tuple[float, ...] = field(default=(0.0, 1.0))
    velocities: tuple[float, ...] = field(default=(1e-7, 1e-7))
    source: str | None = None  # CSV path it came from, for the record

    kind: ClassVar[str] = "table"
    #: node parameters: a table is given to the belt_drive node by its CSV path
    node_fields: ClassVar[dict[str, Any]] = {"path": ""}

    def __post_init__(self) -> None:
        times = np.asarray(self.times, dtype=float)
        velocities = np.asarray(self.velocities, dtype=float)
        where = self.source or "table"
        if times.ndim != 1 or times.size < 2 or times.shape != velocities.shape:
            raise ParameterError(
                f"{where}: need at least 2 (time, velocity) rows of equal length, "
                f"got {times.size} times and {velocities.size} velocities"
            )
        bad = ~np.isfinite(times) | ~np.isfinite(velocities)
        if bad.any():
            row = int(np.argmax(bad))
            raise ParameterError(
                f"{where}: row {row + 1} has a non-finite value "
                f"(time={times[row]!r}, velocity={velocities[row]!r}); expected finite numbers"
            )
        limit = BAND_FIELDS[self.kind]["velocities"]
        outside = ~(np.abs(velocities) <= limit.high)
        if outside.any():
            row = int(np.argmax(outside))
            raise ParameterError(
                f"{where}: row {row + 1} has velocity={float(velocities[row])!r}, outside the physical "
                f"range {limit.range_text()}"
            )
        steps = np.diff(times)
        if (steps <= 0).any():
            row = int(np.argmax(steps <= 0)) + 1
            raise ParameterError(
                f"{where}: time={times[row]!r} at row {row + 1} does not increase; "
                "times must be strictly increasing"
            )
        object.__setattr__(self, "times", tuple(times.tolist()))
        object.__setattr__(self, "velocities", tuple(velocities.tolist()))

    @property
    def fundamental_hz(self) -> float | None:
        """Unknown for an arbitrary table."""
        return None

    def __call__(self, time: np.typing.ArrayLike) -> np.ndarray:
        """v_band(t) in m/s for t in s."""
        velocity: np.ndarray = np.interp(np.asarray(time, dtype=float), self.times, self.velocities)
        return velocity

    def verdict_velocities(self) -> tuple[float, ...]:
        """The lowest table velocity > 0 (a profile starting from rest has 0 among them)."""
        positive = [v for v in self.velocities if v > 0.0]
        return (min(positive),) if positive else ()

    @classmethod
    def from_mapping(cls, data: dict[str, Any], base_dir: Path | None = None) -> TableBand:
        """{path: CSV} (relative to base_dir) or {times: [...], velocities: [...], source: ...}."""
        if "path" not in data:
            table: TableBand = _from_fields(cls, data)
            return table
        data = dict(data)
        path = Path(data.pop("path"))
        if base_dir is not None and not path.is_absolute():
            path = base_dir / path
        if data:
            raise ParameterError(f"unknown table band parameter(s) {sorted(data)}; valid: ['path']")
        return cls.from_csv(path)

    @classmethod
    def from_node_values(cls, values: dict[str, Any], initial: Any) -> TableBand:
        """profile.path (a CSV); without one, the run configuration's table if it is one."""
        if values.get("path"):
            return cls.from_mapping({"path": values["path"]})
        if isinstance(initial, cls):
            return initial
        raise ParameterError("profile.kind='table' needs profile.path (a CSV of time_s,band_velocity_m_s)")

    def node_values(self) -> dict[str, Any]:
        """profile.path: the CSV it came from ('' for an inline table)."""
        return {"path": self.source or ""}

    @classmethod
    def from_csv(cls, path: str | Path) -> TableBand:
        """Read 'time_s, band_velocity_m_s' rows; a non-numeric first row is taken as header."""
        path = Path(path)
        try:
            text = path.read_text()
        except OSError as exc:
            raise ParameterError(f"profile CSV {str(path)!r} cannot be read: {exc.strerror}") from None
        rows = [row for row in csv.reader(text.splitlines()) if row and not row[0].startswith("#")]
        times: list[float] = []
        velocities: list[float] = []
        for number, row in enumerate(rows, start=1):
            if len(row) < 2:
                raise ParameterError(
                    f"{path}: row {number} has {len(row)} column(s); expected time_s,band_velocity_m_s"
                )
            try:
                times.append(float(row[0]))
                velocities.append(float(row[1]))
            except ValueError:
                if number == 1 and not times:
                    continue  # header
                raise ParameterError(
                    f"{path}: row {number} ({','.join(row)!r}) is not numeric; "
                    "expected time_s,band_velocity_m_s"
                ) from None
        return cls(times=tuple(times), velocities=tuple(velocities), source=str(path))


def _from_fields(cls: type[Any], data: Mapping[str, Any]) -> Any:
    valid = [f.name for f in fields(cls)]
    unknown = set(data) - set(valid)
    if unknown:
        raise ParameterError(f"unknown {cls.kind} band parameter(s) {sorted(unknown)}; valid: {valid}")
    return cls(**data)


def profile_from_dict(data: dict[str, Any], base_dir: Path | None = None) -> BandProfile:
    """Build a profile from a mapping such as a YAML 'band' section ({kind: ..., ...}).

    A kind may read its mapping itself (classmethod from_mapping(data, base_dir), as the table
    does for a CSV path); otherwise the mapping holds its dataclass fields.
    """
    data = dict(data)
    cls = profile_class(data.pop("kind", None))
    reader: Callable[..., Any] | None = getattr(cls, "from_mapping", None)
    if reader is not None:
        read: BandProfile = reader(data, base_dir=base_dir)
        return read
    built: BandProfile = _from_fields(cls, data)
    return built


def profile_to_dict(profile: BandProfile) -> dict[str, Any]:
    """Mapping that profile_from_dict turns back into an equal profile (tuples as lists)."""
    data = {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(profile).items()}  # type: ignore[call-overload]
    if isinstance(profile, TableBand) and data.get("source") is None:
        data.pop("source", None)
    return {"kind": profile.kind, **data}


def _node_fields(cls: type[Any]) -> dict[str, Any]:
    """A kind's belt_drive parameters and defaults: its dataclass fields, or its node_fields."""
    declared = getattr(cls, "node_fields", None)
    if declared is not None:
        return dict(declared)
    out: dict[str, Any] = {}
    for f in fields(cls):
        if f.default is MISSING:
            raise InputError(f"{cls.__name__}.{f.name} needs a default to be a node parameter")
        out[f.name] = f.default
    return out


def _node_values(profile: Any) -> dict[str, Any]:
    reader = getattr(profile, "node_values", None)
    if reader is not None:
        return dict(reader())
    return {name: getattr(profile, name) for name in _node_fields(type(profile))}


def _from_node_values(cls: type[Any], values: dict[str, Any], initial: Any) -> Any:
    reader = getattr(cls, "from_node_values", None)
    if reader is not None:
        return reader(values, initial)
    return _from_fields(cls, values)


class ProfileParameters:
    """The flat ``profile.<field>`` parameters of every registered kind, as belt_drive exposes them.

    Parameter names are the kinds' field names (profile.velocity, profile.frequency, …), so a field
    name used by two kinds is one parameter. Each kind keeps its own values, though: a field set
    for one kind applies to that kind only, and switching kind restores the new kind's own values
    (its last ones, else the run configuration's or its defaults) instead of carrying over another
    kind's value of a shared field. ROS-free; the node calls ``completed`` before validation (to set
    the new kind's fields along with the kind) and ``apply`` to validate and switch.
    """

    def __init__(self, initial: BandProfile) -> None:
        self.initial = initial
        self.kind: str = initial.kind
        #: field name → kinds that have it, in registration order
        self.owners: dict[str, tuple[str, ...]] = {}
        self._values: dict[str, dict[str, Any]] = {}
        for kind in profile_kinds():
            defaults = _node_fields(profile_class(kind))
            self._values[kind] = defaults
            for name in defaults:
                self.owners[name] = (*self.owners.get(name, ()), kind)
        self._values[self.kind] = {**self._values[self.kind], **_node_values(initial)}
        self.profile: BandProfile = initial

    def values(self, kind: str | None = None) -> dict[str, Any]:
        """The values of one kind's fields (default: the active kind)."""
        return dict(self._values[kind or self.kind])

    def flat(self) -> dict[str, Any]:
        """One value per parameter name: the active kind's for its fields, else the first owner's."""
        out = {name: self._values[kinds[0]][name] for name, kinds in self.owners.items()}
        out.update(self._values[self.kind])
        return out

    def completed(self, updates: Mapping[str, Any]) -> dict[str, Any]:
        """Updates plus, when they switch kind, the new kind's own values of fields not given."""
        out = dict(updates)
        kind = out.get("kind", self.kind)
        if kind != self.kind and kind in self._values:
            for name, value in self._values[kind].items():
                out.setdefault(name, value)
        return out

    def apply(self, updates: Mapping[str, Any]) -> BandProfile:
        """Validate updates (kind and/or fields) and switch to the profile they give.

        A field of the (new) active kind goes to it; a field of other kinds only is kept for those
        kinds. Raises ParameterError (nothing changed) for an invalid kind, field or value.
        """
        kind = updates.get("kind", self.kind)
        cls = profile_class(kind)
        staged = {k: dict(v) for k, v in self._values.items()}
        for name, value in updates.items():
            if name == "kind":
                continue
            if name not in self.owners:
                raise ParameterError(
                    f"profile.{name} is not a band profile parameter; valid: {sorted(self.owners)}"
                )
            spec = band_field(name)
            if spec is not None:  # a field of an inactive kind is checked too: it is kept
                spec.check(value, f"profile.{name}")
            targets = (kind,) if kind in self.owners[name] else self.owners[name]
            for owner in targets:
                staged[owner][name] = value
        profile: BandProfile = _from_node_values(cls, staged[kind], self.initial)
        self._values, self.kind, self.profile = staged, kind, profile
        return profile


def band_range_problem(
    band: Callable[[np.ndarray], np.ndarray], sample_rate: float, duration: float, limit: float
) -> str | None:
    """Why a band profile cannot run on a plant accepting |v_band| <= limit, or None if it can.

    The profile is evaluated at every sample time k / sample_rate of the run (k = 0 … N; at most
    10^6 evenly spread times for very long runs): a non-finite or too large value would be
    rejected by the plant sample after sample (sim: the run stalls). The reason names the
    largest |v_band|, when it occurs and the limit.
    """
    n = max(1, min(round(duration * sample_rate), 1_000_000))
    times = np.linspace(0.0, duration, n + 1)
    values = np.asarray(band(times), dtype=float)
    bad = ~np.isfinite(values)
    if bad.any():
        t = float(times[np.argmax(bad)])
        return f"the profile gives a non-finite band velocity at t = {t:g} s"
    i = int(np.argmax(np.abs(values)))
    if abs(values[i]) > limit:
        return (
            f"the profile reaches |v_band| = {abs(values[i]):g} m/s at t = {float(times[i]):g} s, above "
            f"the plant's band_velocity_limit {limit:g} m/s (the plant would reject those samples "
            f"and the run would stall); keep |v_band| <= {limit:g} m/s"
        )
    return None
