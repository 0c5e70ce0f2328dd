"""The parameters a fit may free: names, units and physical bounds, all from core/schema.py.

A free parameter is a field of the rig (RIG_FIELDS entries with `fit`: damping_ratio,
natural_frequency, velocity_coupling, mass) or of the run's friction law (their dataclass's
`ranges`: for the junction law shear_modulus, reference_activation_time, activation_exponent,
reference_viscosity, shear_thinning_exponent, contact_area, ...; normal_force lives there too).
Nothing here repeats a unit or a range: each FreeParameter holds the schema's FieldSpec.

The optimizer works on a transformed value θ: ln p for a field whose physical range is strictly
positive (moduli, times, areas span decades, and ln makes a relative change the natural step),
p / scale otherwise (damping ratio, power indices), so that every θ moves on a scale of about one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

from lubrig_ros.core.errors import InputError

from ..core.friction_laws import law_names
from ..core.presets import RunConfig
from ..core.schema import FieldSpec, friction_fields, rig_fields

#: Rig fields a fit may free (normal_force is the friction law's field, named there).
RIG_SECTION = "rig"
FRICTION_SECTION = "friction"


@dataclass(frozen=True)
class FreeParameter:
    """One parameter the fit estimates: its schema field, where it lives, how it is transformed."""

    name: str
    section: str  # RIG_SECTION or FRICTION_SECTION
    spec: FieldSpec
    scale: float  # θ = p / scale for a linear parameter (1 for a logarithmic one)

    @property
    def logarithmic(self) -> bool:
        """True when θ = ln p: the physical range is strictly positive."""
        return self.spec.low > 0.0 or (self.spec.low_open and self.spec.low >= 0.0)

    @property
    def unit(self) -> str:
        """The schema's unit ('1' for a pure number)."""
        return self.spec.unit

    def to_theta(self, value: float) -> float:
        """The optimizer's coordinate of a physical value."""
        return math.log(value) if self.logarithmic else value / self.scale

    def from_theta(self, theta: float) -> float:
        """The physical value of an optimizer coordinate."""
        return math.exp(theta) if self.logarithmic else theta * self.scale

    def theta_bounds(self) -> tuple[float, float]:
        """The physical range in θ (an open lower end at 0 becomes the smallest positive double)."""
        low = self.spec.low if self.spec.low > 0.0 else math.ulp(0.0) if self.logarithmic else self.spec.low
        return self.to_theta(low), self.to_theta(self.spec.high)

    def physical_error(self, value: float, theta_error: float) -> float:
        """Standard error in the parameter's unit from that of θ (delta method)."""
        return abs(value) * theta_error if self.logarithmic else self.scale * theta_error


def _law(config: RunConfig) -> str:
    return type(config.rig.friction).law


def fittable_names(config: RunConfig) -> list[str]:
    """Every name --free accepts for this configuration's friction law, rig fields first."""
    return [*rig_fields(fit=True), *friction_fields(_law(config))]


def current_value(config: RunConfig, parameter: FreeParameter) -> float:
    """The parameter's value in `config` (velocity_coupling: the γ its convention gives)."""
    if parameter.section == FRICTION_SECTION:
        return float(getattr(config.rig.friction, parameter.name))
    return _rig_value(config, parameter.name)


def _rig_value(config: RunConfig, name: str) -> float:
    if name == "velocity_coupling":
        return float(config.rig.velocity_factor)
    return float(getattr(config.rig, name))


def free_parameters(names: list[str], config: RunConfig) -> list[FreeParameter]:
    """The FreeParameter of each name, in the given order; InputError naming a bad one."""
    law = _law(config)
    if not friction_fields(law):
        raise InputError(
            f"friction law {law!r} has no physical ranges to fit within; fittable laws: "
            f"{sorted(name for name in law_names() if friction_fields(name))}"
        )
    valid = fittable_names(config)
    chosen: list[FreeParameter] = []
    for name in names:
        if name not in valid:
            raise InputError(
                f"--free {name!r} is not a parameter of this rig ({law} law); valid: {', '.join(valid)}"
            )
        if any(p.name == name for p in chosen):
            raise InputError(f"--free {name!r} is given twice; name each parameter once")
        rig = rig_fields(fit=True)
        section = RIG_SECTION if name in rig else FRICTION_SECTION
        spec = rig[name] if section == RIG_SECTION else friction_fields(law)[name]
        probe = FreeParameter(name, section, spec, 1.0)
        value = current_value(config, probe)
        scale = 1.0 if probe.logarithmic else max(abs(value), 1e-2 * (spec.high - spec.low))
        chosen.append(FreeParameter(name, section, spec, scale))
    if not chosen:
        raise InputError(f"no --free parameter given; valid: {', '.join(valid)}")
    return chosen


def with_values(config: RunConfig, parameters: list[FreeParameter], values: np.ndarray) -> RunConfig:
    """`config` with each free parameter set to its value (physical units)."""
    rig_changes: dict[str, Any] = {}
    friction_changes: dict[str, float] = {}
    for parameter, value in zip(parameters, values, strict=True):
        target = friction_changes if parameter.section == FRICTION_SECTION else rig_changes
        target[parameter.name] = float(value)
    friction = replace(config.rig.friction, **friction_changes) if friction_changes else config.rig.friction
    rig = replace(config.rig, friction=friction, **rig_changes)
    return replace(config, rig=rig)


def fixed_values(config: RunConfig, parameters: list[FreeParameter]) -> dict[str, float | str]:
    """Every rig and friction field the fit held fixed, with its value (for fit.json)."""
    free = {p.name for p in parameters}
    held: dict[str, float | str] = {}
    for name in rig_fields(fit=True):
        if name not in free:
            held[name] = _rig_value(config, name)
    held["friction_law"] = _law(config)
    for f in fields(config.rig.friction):
        if f.name not in free:
            held[f.name] = float(getattr(config.rig.friction, f.name))
    return held
