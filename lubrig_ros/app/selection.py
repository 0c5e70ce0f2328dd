"""Run selection: which run configuration a command or node works on (one home for the rule).

A run is selected by ONE source — a study case (1..10), a configuration file, or the built-in
default (config/rig.yaml) — and then optionally overridden: the band profile, the contact area,
rig fields (the convention and every core/schema.py RIG_FIELDS entry with `override`:
velocity coupling γ, damping ratio, mass, natural frequency) and simulation fields (duration,
sample rate, rtol). Overrides left at None keep the selected configuration's value, so the
defaults live in one place: the configuration files under config/.

Used by `lubrig simulate`, `lubrig rig`, `lubrig friction`, `lubrig stability`, the nodes
(`case` / `config_file` parameters) and sweep specs (`base_case`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from ..core.params import ParameterError
from ..core.presets import CASE_NUMBERS, RunConfig, default_config, load_case, load_config
from ..core.profiles import BandProfile
from ..core.schema import RIG_OVERRIDES as RIG_OVERRIDES

#: Simulation fields an override may set.
RUN_OVERRIDES = ("duration", "sample_rate", "rtol")


def case_number(value: int | str) -> int:
    """A study case number 1..10 from an int or text; ParameterError naming the value otherwise."""
    try:
        number = int(value)
    except (TypeError, ValueError):
        number = -1
    if number not in CASE_NUMBERS or isinstance(value, bool):
        raise ParameterError(
            f"case={value!r} is not a study case; valid: {CASE_NUMBERS.start}..{CASE_NUMBERS.stop - 1}"
        )
    return number


def base_config(case: int | str | None = None, config_file: str | Path | None = None) -> RunConfig:
    """The selected configuration before overrides: case, else file, else the default.

    `case` None or 0 and `config_file` None or "" mean "not given" (the nodes' parameter
    defaults). Both given is an error naming both (before, a node silently took the case).
    """
    has_case = case is not None and case != 0 and case != ""
    has_file = config_file is not None and str(config_file) != ""
    if has_case and has_file:
        raise ParameterError(
            f"case={case!r} and config_file={str(config_file)!r} both given; select one source"
        )
    if case is not None and has_case:
        return load_case(case_number(case))
    if config_file is not None and has_file:
        return load_config(config_file)
    return default_config()


@dataclass(frozen=True, init=False)
class RunSelection:
    """A run source plus overrides; `resolve()` gives the RunConfig.

    Rig overrides are keywords named as the rig's fields (RIG_OVERRIDES: convention,
    velocity_coupling, damping_ratio, ...), held in `rig`; None or absent keeps the base's value.
    """

    case: int | None  # 1..10 (text such as "3" is accepted and converted)
    config_file: Path | None
    band: BandProfile | None
    contact_area: str | float | None  # 'corrected' | 'printed' | m²
    duration: float | None
    sample_rate: float | None
    rtol: float | None
    #: rig field -> value (velocity_coupling: a convention name or a number > 0)
    rig: Mapping[str, Any] = field(hash=False)

    def __init__(
        self,
        case: int | str | None = None,
        config_file: Path | str | None = None,
        band: BandProfile | None = None,
        contact_area: str | float | None = None,
        duration: float | None = None,
        sample_rate: float | None = None,
        rtol: float | None = None,
        **rig: Any,
    ) -> None:
        unknown = set(rig) - set(RIG_OVERRIDES)
        if unknown:
            raise TypeError(
                f"RunSelection got unknown override(s) {sorted(unknown)}; valid: {list(RIG_OVERRIDES)}"
            )
        values = {
            "case": None if case is None else case_number(case),
            "config_file": None if config_file is None else Path(config_file),
            "band": band,
            "contact_area": contact_area,
            "duration": duration,
            "sample_rate": sample_rate,
            "rtol": rtol,
            "rig": {k: v for k, v in rig.items() if v is not None},
        }
        for name, value in values.items():
            object.__setattr__(self, name, value)
        if self.case is not None and self.config_file is not None:
            raise ParameterError(
                f"case={self.case!r} and config_file={str(self.config_file)!r} both given; select one source"
            )

    @property
    def source(self) -> str:
        """Human-readable source: 'case 3', the file name, or 'default (config/rig.yaml)'."""
        if self.case is not None:
            return f"case {self.case}"
        if self.config_file is not None:
            return str(self.config_file)
        return "default (config/rig.yaml)"

    def base(self) -> RunConfig:
        """The selected configuration without overrides."""
        return base_config(self.case, self.config_file)

    def overrides(self) -> dict[str, Any]:
        """The rig and simulation overrides that are set (not None)."""
        run = {name: getattr(self, name) for name in RUN_OVERRIDES if getattr(self, name) is not None}
        return {**self.rig, **run}

    def resolve(self) -> RunConfig:
        """The run configuration: base, then band, contact area, rig and simulation overrides."""
        return apply_overrides(
            self.base(), band=self.band, contact_area=self.contact_area, **self.overrides()
        )


def apply_overrides(
    config: RunConfig,
    *,
    band: BandProfile | None = None,
    contact_area: str | float | None = None,
    **changes: Any,
) -> RunConfig:
    """Copy of config with a band, a contact area and rig/simulation fields replaced (None: kept)."""
    unknown = set(changes) - set(RIG_OVERRIDES) - set(RUN_OVERRIDES)
    if unknown:
        raise ParameterError(
            f"unknown override(s) {sorted(unknown)}; valid: {[*RIG_OVERRIDES, *RUN_OVERRIDES]}"
        )
    if band is not None:
        config = config.with_overrides(band=band)
    if contact_area is not None:
        friction = config.rig.friction.with_contact_area(contact_area)
        config = replace(config, rig=replace(config.rig, friction=friction))
    return config.with_overrides(**changes)


def select_run(case: int | None = None, config_file: str | Path | None = None, **overrides: Any) -> RunConfig:
    """Shorthand for RunSelection(case, config_file, **overrides).resolve() (0 / "": not given)."""
    path = Path(config_file) if config_file is not None and str(config_file) != "" else None
    return RunSelection(case=case or None, config_file=path, **overrides).resolve()
