"""Typed, validated parameter sets of the rig and of the friction law (SI units throughout).

Units are stated here once: lengths in m, times in s, velocities in m/s, forces in N,
stresses and moduli in Pa, viscosities in Pa·s, masses in kg, frequencies in Hz.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields, is_dataclass, replace
from typing import Any, ClassVar, Literal, get_args

from .friction_laws import DEFAULT_LAW, law_parameters
from .schema import JUNCTION_KINETICS_FIELDS, FieldSpec, rig_fields
from .validation import ParameterError, _check_finite, _check_positive, _check_range

__all__ = [
    "CONTACT_AREA_CHOICES",
    "CONTACT_AREA_CORRECTED",
    "CONTACT_AREA_PRINTED",
    "CONVENTIONS",
    "Convention",
    "FrictionParameters",
    "ParameterError",
    "RigParameters",
    "_check_finite",
    "_check_positive",
    "_check_range",
]

Convention = Literal["physical", "paper", "hertz"]
#: Named readings of the velocity coupling γ in v_rel = v_band − γ ẋ (see COUPLING_READINGS).
CONVENTIONS: tuple[str, ...] = get_args(Convention)
#: What each named convention sets γ to, and the argument for it (docs/model.md, docs/study.md).
COUPLING_READINGS: dict[str, str] = {
    "physical": "γ = 1: v_rel = v_band − ẋ, the study's written equation in SI units "
    "(dimensionally consistent; what a rig engineer should use)",
    "paper": "γ = 1/ω0: friction evaluated at the hyper-time derivative x' = dx/dt', t' = ω0 t "
    "(the study's non-dimensional form taken literally)",
    "hertz": "γ = 1/f0: time counted in natural periods, t' = f0 t (ω0 written where f0 was "
    "meant, a factor 2π); same dynamics as γ = 1 with the printed contact area (s = 0.1)",
}
#: The conventions with their γ, for help texts and parameter descriptions.
CONVENTION_CHOICES = " | ".join(f"{name} ({COUPLING_READINGS[name].split(':')[0]})" for name in CONVENTIONS)

#: Contact area that reproduces every friction coefficient the study reports (default).
CONTACT_AREA_CORRECTED = 2.83e-10
#: Contact area as printed in the study; gives friction coefficients exactly 10x smaller.
CONTACT_AREA_PRINTED = 28.3e-12
CONTACT_AREA_CHOICES: dict[str, float] = {
    "corrected": CONTACT_AREA_CORRECTED,
    "printed": CONTACT_AREA_PRINTED,
}


@dataclass(frozen=True)
class FrictionParameters:
    """Junction-kinetics friction law of the confined interface (diamine in PAO, N = 1 mN).

    The default law (core.junction); its fields are the compiled kernel's p in this order.
    """

    ranges: ClassVar[dict[str, FieldSpec]] = JUNCTION_KINETICS_FIELDS  # physical ranges (schema)

    law: ClassVar[str] = "junction_kinetics"

    shear_modulus: float = 3.9e6  # G, Pa
    interface_thickness: float = 4.25e-9  # D, m
    interpenetration_thickness: float = 1e-10  # d, m
    yield_distance: float = 1.6e-9  # l*, m
    thermal_break_time: float = 1000.0  # τ0, s
    reference_activation_time: float = 18.0  # τ_ref, s
    reference_velocity: float = 1e-10  # v_ref, m/s
    activation_exponent: float = -0.41  # k1, in [-1, 0]
    reference_viscosity: float = 900.0  # η_ref, Pa·s
    shear_thinning_exponent: float = -0.62  # k2, in [-1, 0]
    contact_area: float = CONTACT_AREA_CORRECTED  # A, m² (see docs/model.md on the printed value)
    normal_force: float = 1e-3  # N, N

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in ("activation_exponent", "shear_thinning_exponent"):
                _check_range(f.name, value, -1.0, 0.0)
            else:
                _check_positive(f.name, value)
            object.__setattr__(self, f.name, float(value))

    @property
    def critical_velocity(self) -> float:
        """v0 = l*/τ0, the velocity where junction stretching and thermal breaking balance."""
        return self.yield_distance / self.thermal_break_time

    def with_contact_area(self, choice: str | float) -> FrictionParameters:
        """Copy with the contact area set by name ('corrected', 'printed') or value in m²."""
        if isinstance(choice, str):
            if choice not in CONTACT_AREA_CHOICES:
                try:
                    return replace(self, contact_area=float(choice))
                except ValueError:
                    raise ParameterError(
                        f"contact_area={choice!r} is not valid; expected one of "
                        f"{sorted(CONTACT_AREA_CHOICES)} or a positive area in m²"
                    ) from None
            return replace(self, contact_area=CONTACT_AREA_CHOICES[choice])
        return replace(self, contact_area=choice)


def convention_coupling(convention: str, natural_frequency: float) -> float:
    """γ of a named convention for a rig of natural frequency f0 (Hz)."""
    if convention == "physical":
        return 1.0
    if convention == "paper":
        return 1.0 / (2.0 * math.pi * natural_frequency)
    if convention == "hertz":
        return 1.0 / natural_frequency
    raise ParameterError(f"convention={convention!r} is not valid; expected one of {list(CONVENTIONS)}")


def check_rig_ranges(rig: RigParameters) -> None:
    """ParameterError naming the first of a run's rig values outside its physical range.

    The ranges are core/schema.py's RIG_FIELDS and the `ranges` of the rig's friction law's dataclass,
    with the cross-check d <= D of the junction-kinetics law. RigParameters itself does not check
    them: the linear stability analysis explores damping ratios far beyond a rig's (ζ_crit reaches
    1e5 with γ = 1).
    """
    for name, rig_spec in rig_fields(on_rig=True).items():
        value = getattr(rig, name)
        if value is not None:  # a field that may be unset (velocity_coupling: the convention's γ)
            rig_spec.check(value)
    ranges: dict[str, FieldSpec] = getattr(type(rig.friction), "ranges", {})
    for f in fields(rig.friction):
        spec = ranges.get(f.name)
        if spec is not None:
            spec.check(getattr(rig.friction, f.name))
    inner = getattr(rig.friction, "interpenetration_thickness", None)
    outer = getattr(rig.friction, "interface_thickness", None)
    if inner is not None and outer is not None and inner > outer:
        raise ParameterError(
            f"interpenetration_thickness={inner!r} m is larger than interface_thickness={outer!r} m; "
            "the interpenetration zone lies inside the interface (d <= D)"
        )


@dataclass(frozen=True)
class RigParameters:
    """Mass–spring–damper held against the band, plus the relative-velocity convention.

    Each field but `convention` and `friction` has its entry in core/schema.py's RIG_FIELDS
    (unit, rig range, the model's own bound checked here, where a run may set it).
    """

    mass: float = 0.1  # m, kg
    natural_frequency: float = 10.0  # f0, Hz
    damping_ratio: float = 0.01  # ζ, dimensionless
    convention: str = "physical"  # named γ: physical (1), paper (1/ω0), hertz (1/f0)
    #: the friction law's parameter set (FrictionParameters = junction kinetics, or any registered
    #: law's, see core.friction_laws); its normal_force is the rig's load N.
    friction: Any = field(default_factory=FrictionParameters)
    #: explicit γ (s/s, > 0) overriding the convention's; a convention name is accepted too
    velocity_coupling: float | str | None = None  # γ; a convention name is normalized in __post_init__

    def __post_init__(self) -> None:
        for name, spec in rig_fields(on_rig=True, unset="").items():
            object.__setattr__(self, name, spec.check_model(getattr(self, name)))
        if self.convention not in CONVENTIONS:
            raise ParameterError(
                f"convention={self.convention!r} is not valid; expected one of {list(CONVENTIONS)}"
            )
        coupling: Any = self.velocity_coupling
        if isinstance(coupling, str) and coupling.strip() in CONVENTIONS:
            object.__setattr__(self, "convention", coupling.strip())
            coupling = None
        elif isinstance(coupling, str) and coupling.strip() in ("", "none", "null"):
            coupling = None
        if coupling is not None:
            if isinstance(coupling, bool):
                coupling = "bool"  # rejected below with the valid choices
            try:
                coupling = float(coupling)
            except (TypeError, ValueError):
                raise ParameterError(
                    f"velocity_coupling={self.velocity_coupling!r} is not valid; expected one of "
                    f"{list(CONVENTIONS)} or a finite number > 0 (γ in v_rel = v_band − γ ẋ)"
                ) from None
            if not (math.isfinite(coupling) and coupling > 0.0):
                raise ParameterError(
                    f"velocity_coupling={self.velocity_coupling!r} is not valid; expected one of "
                    f"{list(CONVENTIONS)} or a finite number > 0 (γ in v_rel = v_band − γ ẋ)"
                )
        object.__setattr__(self, "velocity_coupling", coupling)
        if not (is_dataclass(self.friction) and isinstance(getattr(type(self.friction), "law", None), str)):
            raise ParameterError(
                f"friction={self.friction!r} is not valid; expected the parameters of a friction law "
                "(FrictionParameters or another core.friction_laws law's)"
            )

    @property
    def angular_frequency(self) -> float:
        """ω0 = 2π f0 in rad/s."""
        return 2.0 * math.pi * self.natural_frequency

    @property
    def stiffness(self) -> float:
        """K = m ω0² in N/m."""
        return self.mass * self.angular_frequency**2

    @property
    def damping(self) -> float:
        """C = 2 ζ sqrt(k m) in N·s/m."""
        return 2.0 * self.damping_ratio * math.sqrt(self.stiffness * self.mass)

    @property
    def velocity_factor(self) -> float:
        """γ in v_rel = v_band − γ ẋ: explicit, or by convention 1 (physical), 1/ω0 (paper), 1/f0 (hertz)."""
        if self.velocity_coupling is not None:
            return float(self.velocity_coupling)
        return convention_coupling(self.convention, self.natural_frequency)

    @property
    def coupling_name(self) -> str:
        """The convention's name, or 'explicit' when γ is given as a number."""
        return self.convention if self.velocity_coupling is None else "explicit"

    @property
    def coupling_strength(self) -> float:
        """S = γ · A / A_default: the one number the dynamics of v_rel depend on (model doc §5).

        For a friction law without a contact area (e.g. Stribeck) s is γ.
        """
        area = getattr(self.friction, "contact_area", CONTACT_AREA_CORRECTED)
        return self.velocity_factor * area / CONTACT_AREA_CORRECTED

    @property
    def coupling_label(self) -> str:
        """Short text for titles: 'paper convention (γ = 0.0159)' or 'γ = 0.05'."""
        gamma = f"γ = {self.velocity_factor:.3g}"
        return gamma if self.velocity_coupling is not None else f"{self.convention} convention ({gamma})"

    def relative_velocity(self, band_velocity: Any, velocity: Any) -> Any:
        """v_rel = v_band − γ ẋ in m/s (scalars or arrays): the one home of the convention."""
        return band_velocity - self.velocity_factor * velocity

    @property
    def normal_force(self) -> float:
        """N in N (held by the friction parameters)."""
        return float(self.friction.normal_force)

    def to_dict(self) -> dict[str, Any]:
        """Plain dictionary (YAML/JSON friendly), friction nested; `law` named unless the default."""
        data = asdict(self)
        law = type(self.friction).law
        if law != DEFAULT_LAW:
            data["friction"] = {"law": law, **data["friction"]}
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RigParameters:
        """Build from a mapping such as a YAML 'rig' section; unknown keys are an error."""
        data = dict(data)
        friction_data = dict(data.pop("friction", {}) or {})
        known_rig = {f.name for f in fields(cls)} - {"friction"}
        unknown = set(data) - known_rig
        if unknown:
            raise ParameterError(f"unknown rig parameter(s) {sorted(unknown)}; valid: {sorted(known_rig)}")
        return cls(**data, friction=friction_from_dict(friction_data))


def friction_from_dict(data: dict[str, Any]) -> Any:
    """A friction-law parameter set from a 'friction' mapping ({law: name, field: value, ...}).

    Without `law` (or law: junction_kinetics) the junction-kinetics FrictionParameters, whose
    contact_area may also be 'corrected' or 'printed'. Unknown fields are an error naming the valid ones.
    """
    data = dict(data)
    law = data.pop("law", DEFAULT_LAW)
    if law == DEFAULT_LAW:
        area = data.pop("contact_area", None)
        known = [f.name for f in fields(FrictionParameters)]
        unknown = set(data) - set(known)
        if unknown:
            raise ParameterError(f"unknown friction parameter(s) {sorted(unknown)}; valid: {sorted(known)}")
        friction = FrictionParameters(**data)
        return friction if area is None else friction.with_contact_area(area)
    kind = law_parameters(law)
    known = [f.name for f in fields(kind)]
    unknown = set(data) - set(known)
    if unknown:
        raise ParameterError(f"unknown {law} friction parameter(s) {sorted(unknown)}; valid: {sorted(known)}")
    return kind(**data)
