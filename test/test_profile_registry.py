"""Band profiles as a registry: a new kind needs no edit elsewhere; shared field names do not leak."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

from lubrig_ros.core.params import ParameterError
from lubrig_ros.core.presets import from_mapping
from lubrig_ros.core.profiles import (
    ConstantBand,
    ProfileParameters,
    RegularCycle,
    SinusoidalBand,
    TableBand,
    profile_class,
    profile_from_dict,
    profile_kinds,
    profile_to_dict,
    register_profile,
    unregister_profile,
)


@dataclass(frozen=True)
class SquareBand:
    """Test kind: square wave; shares low/high_velocity (cycle) and frequency (sine)."""

    low_velocity: float = 1e-7
    high_velocity: float = 3e-7
    frequency: float = 5.0  # Hz

    kind: ClassVar[str] = "square"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.frequency) and self.frequency > 0):
            raise ParameterError(f"frequency={self.frequency!r} must be > 0 Hz")

    @property
    def fundamental_hz(self) -> float:
        return self.frequency

    def __call__(self, time: np.typing.ArrayLike) -> np.ndarray:
        phase = np.mod(np.asarray(time, dtype=float) * self.frequency, 1.0)
        return np.where(phase < 0.5, self.high_velocity, self.low_velocity)

    def verdict_velocities(self) -> tuple[float, ...]:
        return tuple(v for v in (self.low_velocity, self.high_velocity) if v > 0.0)


@pytest.fixture
def square() -> Iterator[type[SquareBand]]:
    register_profile(SquareBand)
    try:
        yield SquareBand
    finally:
        unregister_profile("square")


def test_builtin_kinds_are_registered() -> None:
    assert profile_kinds()[:4] == ["constant", "cycle", "sine", "table"]
    assert [profile_class(k) for k in ("constant", "cycle", "sine", "table")] == [
        ConstantBand,
        RegularCycle,
        SinusoidalBand,
        TableBand,
    ]
    with pytest.raises(ParameterError, match=r"kind='sawtooth' is not valid; expected one of \['constant'"):
        profile_class("sawtooth")


def test_registering_twice_under_one_name_is_refused(square: type[SquareBand]) -> None:
    @dataclass(frozen=True)
    class Other:
        kind: ClassVar[str] = "square"

    with pytest.raises(ValueError, match="already registered"):
        register_profile(Other)
    register_profile(SquareBand)  # the same class again is harmless


def test_a_registered_kind_works_in_configs_and_sweep_verdicts(square: type[SquareBand]) -> None:
    from lubrig_ros.sweep.point import linear_columns

    assert "square" in profile_kinds()
    band = profile_from_dict({"kind": "square", "frequency": 2.0})
    assert band == SquareBand(frequency=2.0)
    assert profile_from_dict(profile_to_dict(band)) == band
    config = from_mapping({"band": {"kind": "square", "low_velocity": 1e-7, "high_velocity": 1e-6}})
    assert config.band.fundamental_hz == 5.0
    assert float(config.band(0.0)) == 1e-6 and float(config.band(0.15)) == 1e-7
    columns = linear_columns(config)  # judged at the kind's own verdict velocities
    assert columns["linear_velocity_m_s"] in (1e-7, 1e-6)
    with pytest.raises(ParameterError, match=r"unknown square band parameter\(s\) \['phase'\]"):
        profile_from_dict({"kind": "square", "phase": 1.0})


def test_verdict_velocities_of_the_builtin_kinds() -> None:
    assert ConstantBand(0.0).verdict_velocities() == (0.0,)  # 0: the verdict itself says why not
    assert RegularCycle(1e-7, 1e-6).verdict_velocities() == (1e-7, 1e-6)
    assert RegularCycle(-1e-7, 0.0).verdict_velocities() == ()
    assert SinusoidalBand(mean_velocity=0.0).verdict_velocities() == ()
    assert TableBand((0.0, 1.0, 2.0), (0.0, 3e-7, 2e-7)).verdict_velocities() == (2e-7,)


def test_node_parameters_of_every_kind_are_one_flat_set() -> None:
    params = ProfileParameters(ConstantBand(2e-7))
    flat = params.flat()
    assert flat["velocity"] == 2e-7 and flat["frequency"] == 1.0 and flat["path"] == ""
    assert params.owners["low_velocity"] == ("cycle",)
    # a field of another kind is kept for that kind; the running profile is unchanged
    assert params.apply({"frequency": 3.0}) == ConstantBand(2e-7)
    assert params.apply(params.completed({"kind": "sine"})) == SinusoidalBand(frequency=3.0)
    assert params.apply(params.completed({"kind": "constant"})) == ConstantBand(2e-7)


def test_a_field_shared_by_two_kinds_does_not_leak_between_them(square: type[SquareBand]) -> None:
    """The bug of issue 10: with belt_drive's old PROFILE_FIELDS (one entry per field name, the last
    kind winning), sine ignored profile.frequency, cycle ignored profile.low_velocity, and a switch to
    square took sine's frequency and cycle's low_velocity."""
    params = ProfileParameters(SinusoidalBand())
    assert params.owners["frequency"] == ("sine", "square")
    assert params.owners["low_velocity"] == ("cycle", "square")
    # each kind's own field applies to it
    assert params.apply({"frequency": 2.0}) == SinusoidalBand(frequency=2.0)
    cycle = params.apply(params.completed({"kind": "cycle", "low_velocity": 5e-8}))
    assert cycle == RegularCycle(low_velocity=5e-8)
    # switching to square does not carry sine's frequency nor cycle's low_velocity
    update = params.completed({"kind": "square"})
    assert update["frequency"] == 5.0 and update["low_velocity"] == 1e-7
    assert params.apply(update) == SquareBand()
    assert params.apply({"frequency": 7.0}) == SquareBand(frequency=7.0)
    # and back: each kind finds its own values again
    assert params.apply(params.completed({"kind": "sine"})) == SinusoidalBand(frequency=2.0)
    assert params.apply(params.completed({"kind": "cycle"})) == RegularCycle(low_velocity=5e-8)
    assert params.apply(params.completed({"kind": "square"})) == SquareBand(frequency=7.0)


def test_invalid_updates_change_nothing() -> None:
    params = ProfileParameters(ConstantBand(2e-7))
    with pytest.raises(ParameterError, match="sawtooth"):
        params.apply(params.completed({"kind": "sawtooth"}))
    with pytest.raises(ParameterError, match="velocity=nan"):
        params.apply({"velocity": float("nan")})
    with pytest.raises(ParameterError, match=r"profile\.speed is not a band profile parameter"):
        params.apply({"speed": 1.0})
    with pytest.raises(ParameterError, match=r"needs profile\.path"):
        params.apply({"kind": "table"})
    assert params.kind == "constant" and params.profile == ConstantBand(2e-7)
    assert params.values() == {"velocity": 2e-7}


def test_table_kind_takes_a_csv_path_or_keeps_the_configured_table(tmp_path) -> None:
    csv = tmp_path / "band.csv"
    csv.write_text("time_s,band_velocity_m_s\n0,1e-7\n1,3e-7\n")
    table = TableBand((0.0, 1.0), (1e-7, 2e-7))
    params = ProfileParameters(table)
    assert params.flat()["path"] == ""
    assert params.apply(params.completed({"kind": "constant"})) == ConstantBand()
    assert params.apply(params.completed({"kind": "table"})) == table  # the configured one
    loaded = params.apply({"path": str(csv)})
    assert loaded == TableBand.from_csv(csv) and loaded.source == str(csv)
