"""Band velocity profiles v_band(t) in m/s: constant, the study's regular cycle, sine, table (CSV)."""

from __future__ import annotations

import csv
import math
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from .params import ParameterError, _check_finite, _check_positive


@dataclass(frozen=True)
class ConstantBand:
    """Constant band velocity."""

    velocity: float = 1e-7

    kind = "constant"

    def __post_init__(self) -> None:
        object.__setattr__(self, "velocity", _check_finite("velocity", self.velocity))

    @property
    def fundamental_hz(self) -> float | None:
        """No periodic forcing."""
        return None

    def __call__(self, time: np.typing.ArrayLike) -> np.ndarray:
        """v_band(t) in m/s for t in s."""
        return np.full(np.shape(time), self.velocity, dtype=float)


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

    kind = "cycle"

    def __post_init__(self) -> None:
        low = _check_finite("low_velocity", self.low_velocity)
        high = _check_finite("high_velocity", self.high_velocity)
        if high <= low:
            raise ParameterError(
                f"high_velocity={self.high_velocity!r} must be greater than "
                f"low_velocity={self.low_velocity!r} (V2 > V1)"
            )
        plateau = _check_finite("plateau_time", self.plateau_time)
        if plateau < 0.0:
            raise ParameterError(f"plateau_time={self.plateau_time!r} must be >= 0 s")
        ramp = _check_finite("ramp_time", self.ramp_time)
        if ramp < 0.0 or ramp + plateau <= 0.0:
            raise ParameterError(
                f"ramp_time={self.ramp_time!r} must be >= 0 s with ramp_time + plateau_time > 0"
            )
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


@dataclass(frozen=True)
class SinusoidalBand:
    """v_band = mean + amplitude · sin(2π f t + phase)."""

    mean_velocity: float = 1.5e-7
    amplitude: float = 5e-8
    frequency: float = 1.0  # Hz
    phase: float = 0.0  # rad

    kind = "sine"

    def __post_init__(self) -> None:
        object.__setattr__(self, "mean_velocity", _check_finite("mean_velocity", self.mean_velocity))
        amplitude = _check_finite("amplitude", self.amplitude)
        if amplitude < 0.0:
            raise ParameterError(f"amplitude={self.amplitude!r} must be >= 0 m/s")
        object.__setattr__(self, "amplitude", amplitude)
        object.__setattr__(self, "frequency", _check_positive("frequency", self.frequency))
        object.__setattr__(self, "phase", _check_finite("phase", self.phase))

    @property
    def fundamental_hz(self) -> float:
        """The sine's own frequency."""
        return self.frequency

    def __call__(self, time: np.typing.ArrayLike) -> np.ndarray:
        """v_band(t) in m/s for t in s."""
        t = np.asarray(time, dtype=float)
        return self.mean_velocity + self.amplitude * np.sin(
            2.0 * math.pi * self.frequency * t + self.phase
        )


@dataclass(frozen=True)
class TableBand:
    """Piecewise-linear band velocity through (time, velocity) points; holds the end values."""

    times: tuple[float, ...] = field(default=(0.0, 1.0))
    velocities: tuple[float, ...] = field(default=(1e-7, 1e-7))
    source: str | None = None  # CSV path it came from, for the record

    kind = "table"

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
        return np.interp(np.asarray(time, dtype=float), self.times, self.velocities)

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


BandProfile = ConstantBand | RegularCycle | SinusoidalBand | TableBand
PROFILE_KINDS: dict[str, type] = {
    "constant": ConstantBand,
    "cycle": RegularCycle,
    "sine": SinusoidalBand,
    "table": TableBand,
}


def profile_from_dict(data: dict[str, Any], base_dir: Path | None = None) -> BandProfile:
    """Build a profile from a mapping such as a YAML 'band' section ({kind: ..., ...})."""
    data = dict(data)
    kind = data.pop("kind", None)
    if kind not in PROFILE_KINDS:
        raise ParameterError(f"band kind={kind!r} is not valid; expected one of {list(PROFILE_KINDS)}")
    if kind == "table" and "path" in data:
        path = Path(data.pop("path"))
        if base_dir is not None and not path.is_absolute():
            path = base_dir / path
        if data:
            raise ParameterError(f"unknown table band parameter(s) {sorted(data)}; valid: ['path']")
        return TableBand.from_csv(path)
    cls = PROFILE_KINDS[kind]
    valid = [f.name for f in fields(cls)]
    unknown = set(data) - set(valid)
    if unknown:
        raise ParameterError(f"unknown {kind} band parameter(s) {sorted(unknown)}; valid: {valid}")
    return cls(**data)


def profile_to_dict(profile: BandProfile) -> dict[str, Any]:
    """Mapping that profile_from_dict turns back into an equal profile."""
    data = asdict(profile)
    if isinstance(profile, TableBand):
        data["times"] = list(profile.times)
        data["velocities"] = list(profile.velocities)
        if data.get("source") is None:
            data.pop("source", None)
    return {"kind": profile.kind, **data}
