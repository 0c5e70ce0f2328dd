"""Physical ranges of every configuration field: name, unit, range, meaning (no numpy).

The one home of what a run may hold. A value outside its range is a typo, not an experiment: the
model describes a bench-top rig sliding at up to 1 cm/s through a nanometre-thin interface.
Who applies them:

* ``RunConfig`` (core/presets.py) checks every field of a run and the cross-checks between
  fields (every run: CLI, YAML, sweeps, the nodes' parameters applied at a reset);
* the band profile kinds (core/profiles.py) check their own fields;
* the nodes' parameter descriptors carry them (app/interface/node_parameters.py derives the plant's and
  belt_drive's parameters from these tables, so ``ros2 param describe`` shows the same range);
* ``lubrig --help`` shows them (cli/common.py), config/rig.yaml states them in its comments
  (test/test_schema.py checks both against this module);
* a rig field's entry (RigField) also says where a run may set it: the run selection's
  overrides (app/selection.py), its ``lubrig simulate`` option, the plant's ``rig.<name>``
  parameter and ``lubrig fit --free`` derive from RIG_FIELDS.

The parameter dataclasses themselves (RigParameters, FrictionParameters) only demand finite,
positive values (a rig field: its `model_low`): the linear stability analysis and the tests
explore far beyond a rig's ranges.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from .validation import ParameterError, _check_finite

__all__ = [
    "BAND_FIELDS",
    "BAND_VELOCITY_LIMIT",
    "CONVENTION",
    "JUNCTION_KINETICS_FIELDS",
    "MAX_SAMPLES",
    "MIN_SAMPLES_PER_PERIOD",
    "NORMAL_FORCE",
    "RIG_FIELDS",
    "RIG_OVERRIDES",
    "SAMPLE_FIELDS",
    "SAMPLE_UNITS",
    "SHADOW_FIELDS",
    "SIMULATION_FIELDS",
    "FieldSpec",
    "RigField",
    "SampleField",
    "band_field",
    "field_table",
    "friction_field",
    "friction_fields",
    "rig_fields",
    "unit_column",
]


def number_text(x: float) -> str:
    """A bound as written in messages, docs and YAML comments: 0.01, 1e-13, 1e+06 -> 1e6."""
    if float(x).is_integer() and abs(x) < 1e6:
        return str(int(x))
    text = f"{x:g}"
    if "e" in text:
        mantissa, exponent = text.split("e")
        text = f"{mantissa}e{int(exponent)}"
    return text


@dataclass(frozen=True)
class FieldSpec:
    """One field: its name, SI unit ('1' for a pure number), range, symbol and meaning.

    The range is closed, or open at `low` if `low_open`.
    """

    name: str
    unit: str
    low: float
    high: float
    description: str
    symbol: str = ""
    low_open: bool = False

    @property
    def unit_text(self) -> str:
        """' kg' for a unit, '' for a pure number (for appending to a number)."""
        return "" if self.unit in ("1", "") else f" {self.unit}"

    def range_text(self) -> str:
        """'[0.0001, 1000] kg', '(0, 1e6] s': the range with its unit."""
        opening = "(" if self.low_open else "["
        return f"{opening}{number_text(self.low)}, {number_text(self.high)}]{self.unit_text}"

    def contains(self, value: float) -> bool:
        """True if the finite number `value` is inside the range."""
        above = value > self.low if self.low_open else value >= self.low
        return above and value <= self.high

    def check(self, value: Any, name: str | None = None) -> float:
        """`value` as a float if it is a finite number inside the range.

        Otherwise ParameterError naming the value and the physical range.
        """
        label = name or self.name
        number = _check_finite(label, value)
        if isinstance(value, bool) or not self.contains(number):
            raise ParameterError(f"{label}={value!r} is outside the physical range {self.range_text()}")
        return number


def field_table(*specs: FieldSpec) -> dict[str, FieldSpec]:
    """Field specs by name, in order."""
    return {s.name: s for s in specs}


#: Largest |band velocity| a run may have and the plant accepts by default, m/s.
BAND_VELOCITY_LIMIT = 1e-2
#: Output samples per natural period at the least (sample_rate >= this × f0): the integrator
#: steps adaptively, but the analysis and the figures see only the output samples.
MIN_SAMPLES_PER_PERIOD = 20
#: Output samples a run may have at most (duration × sample_rate): 11.6 days at 1 kHz; what
#: `lubrig simulate` can hold in this machine's memory is checked there on top.
MAX_SAMPLES = 1_000_000_000


@dataclass(frozen=True)
class RigField(FieldSpec):
    """A rig parameter: its FieldSpec plus where a run may set it and what the model itself needs.

    The range (`low`, `high`) is a rig's: every run configuration is checked against it. The
    model's own bound (`model_low`, open unless `model_low_open` is False) is what RigParameters
    demands: the linear stability analysis and the tests go far beyond a rig's range (ζ_crit
    reaches 1e5 with γ = 1). A field `held` by the friction law (normal_force) is one of the law
    parameters' fields; the others are RigParameters fields of the same name. What derives from
    an entry: RigParameters' checks, every run configuration's range check, the overrides of a run
    selection (`override`) and the `lubrig simulate` option (`option`: '' its name with dashes,
    None none), the plant's `rig.<name>` parameter (`node`), `lubrig fit --free` (`fit`) and the
    docs' tables generated from those.
    """

    held: str = "rig"  # "rig": a RigParameters field; "friction": the friction law's
    option: str | None = ""  # `lubrig simulate --<option>`; '' its name with dashes; None none
    metavar: str = ""  # the option's value in --help; '' its unit in capitals (X for a number)
    override: bool = True  # a run selection (command line, launchers) may set it
    node: bool = True  # the plant's parameter rig.<name>, applied at the next reset
    fit: bool = True  # `lubrig fit --free` may estimate it
    unset: str = ""  # for a field that may be left unset (None): what that means
    model_low: float = 0.0
    model_low_open: bool = True

    @property
    def on_rig(self) -> bool:
        """True for a RigParameters field (not one of the friction law's)."""
        return self.held == "rig"

    @property
    def cli_option(self) -> str | None:
        """'--zeta': the command-line option of the field, None for none."""
        if self.option is None:
            return None
        return "--" + (self.option or self.name.replace("_", "-"))

    @property
    def cli_metavar(self) -> str:
        """The option's value in --help: 'KG', 'HZ', 'Z'."""
        if self.metavar:
            return self.metavar
        return "X" if self.unit in ("1", "") else self.unit.upper()

    @property
    def label(self) -> str:
        """'mass m, kg', 'damping ratio ζ': name, symbol and unit for help texts."""
        text = f"{self.name.replace('_', ' ')} {self.symbol}".rstrip()
        return text if self.unit in ("1", "") else f"{text}, {self.unit}"

    def check_model(self, value: Any, name: str | None = None) -> float:
        """`value` as a float if finite and within the model's own bound (not the rig's range).

        Otherwise ParameterError: 'mass=0.0 must be > 0', 'damping_ratio=-0.1 must be >= 0'.
        """
        label = name or self.name
        number = _check_finite(label, value)
        inside = number > self.model_low if self.model_low_open else number >= self.model_low
        if not inside:
            relation = ">" if self.model_low_open else ">="
            raise ParameterError(f"{label}={value!r} must be {relation} {number_text(self.model_low)}")
        return number


NORMAL_FORCE = RigField(
    "normal_force",
    "N",
    1e-9,
    10.0,
    "normal force pressing the mass on the band",
    "N",
    held="friction",
    option=None,
    override=False,
    node=False,
    fit=False,
)

#: The rig's parameters. A new one is an entry here, its field on core.params.RigParameters and
#: its line in config/rig.yaml (docs/extending.md); normal_force is the friction law's field
#: (its `ranges` hold it too), and velocity_coupling's option and node parameter are declared
#: beside the convention's (a convention name is a value of it too; 0 on the node: the
#: convention's γ).
RIG_FIELDS: dict[str, RigField] = {
    f.name: f
    for f in (
        RigField("mass", "kg", 1e-4, 1e3, "mass of the slider", "m"),
        RigField("natural_frequency", "Hz", 1e-2, 500.0, "natural frequency, k = m (2π f0)²", "f0"),
        RigField(
            "damping_ratio",
            "1",
            0.0,
            2.0,
            "damping ratio, c = 2 ζ sqrt(k m) (0: undamped)",
            "ζ",
            option="zeta",
            metavar="Z",
            model_low_open=False,
        ),
        RigField(
            "velocity_coupling",
            "1",
            1e-6,
            1e3,
            "explicit γ in v_rel = v_band − γ ẋ (s/s; physical 1, paper 1/ω0, hertz 1/f0)",
            "γ",
            option=None,
            node=False,
            unset="the convention's γ",
        ),
        NORMAL_FORCE,
    )
}

#: The rig's named choice of γ (core.params.CONVENTIONS), set beside velocity_coupling.
CONVENTION = "convention"
#: The rig fields a run selection may override (RunConfig.with_overrides): the convention and
#: every RIG_FIELDS entry with `override`.
RIG_OVERRIDES: tuple[str, ...] = (CONVENTION, *(n for n, f in RIG_FIELDS.items() if f.override))


def rig_fields(**flags: object) -> dict[str, RigField]:
    """The RIG_FIELDS entries whose attributes have the given values (e.g. on_rig=True, node=True)."""
    return {n: f for n, f in RIG_FIELDS.items() if all(getattr(f, k) == v for k, v in flags.items())}


#: The ranges of the junction-kinetics law's fields (core.params.FrictionParameters.ranges); every
#: other law states its own on its parameter dataclass (`ranges`, e.g. core/stribeck.py).
JUNCTION_KINETICS_FIELDS: dict[str, FieldSpec] = field_table(
    FieldSpec("shear_modulus", "Pa", 1e3, 1e11, "shear modulus of the confined interface", "G"),
    FieldSpec("interface_thickness", "m", 1e-10, 1e-6, "interface thickness", "D"),
    FieldSpec(
        "interpenetration_thickness",
        "m",
        1e-12,
        1e-6,
        "interpenetration zone thickness (at most D)",
        "d",
    ),
    FieldSpec("yield_distance", "m", 1e-12, 1e-6, "yield distance of a junction", "l*"),
    FieldSpec("thermal_break_time", "s", 1e-6, 1e6, "thermal break time at zero force", "τ0"),
    FieldSpec("reference_activation_time", "s", 1e-6, 1e6, "reference activation time", "τ_ref"),
    FieldSpec("reference_velocity", "m/s", 1e-15, 1.0, "reference velocity", "v_ref"),
    FieldSpec("activation_exponent", "1", -1.0, 0.0, "activation-time power index", "k1"),
    FieldSpec("reference_viscosity", "Pa·s", 1e-4, 1e6, "reference viscosity", "η_ref"),
    FieldSpec("shear_thinning_exponent", "1", -1.0, 0.0, "shear-thinning power index", "k2"),
    FieldSpec("contact_area", "m²", 1e-14, 1e-4, "contact area (corrected 2.83e-10 m²)", "A"),
    NORMAL_FORCE,
)

SIMULATION_FIELDS: dict[str, FieldSpec] = field_table(
    FieldSpec("duration", "s", 0.0, 1e6, "run length in rig time", low_open=True),
    FieldSpec("sample_rate", "Hz", 1.0, 1e5, "output samples per second of rig time"),
    FieldSpec("rtol", "1", 1e-13, 1e-2, "relative tolerance of the Radau IIA integrator"),
    FieldSpec("initial_perturbation", "1", -1.0, 1.0, "x(0) = (1 + this) x0, ẋ(0) = 0"),
)

_V = BAND_VELOCITY_LIMIT
#: Per band profile kind (core.profiles registry name): the ranges of its numeric fields.
BAND_FIELDS: dict[str, dict[str, FieldSpec]] = {
    "constant": field_table(FieldSpec("velocity", "m/s", -_V, _V, "band velocity")),
    "cycle": field_table(
        FieldSpec("low_velocity", "m/s", -_V, _V, "V1, the lower plateau", "V1"),
        FieldSpec("high_velocity", "m/s", -_V, _V, "V2, the upper plateau (> V1)", "V2"),
        FieldSpec("plateau_time", "s", 0.0, 1e6, "both plateaus together", "T_c"),
        FieldSpec("ramp_time", "s", 0.0, 1e6, "both ramps together", "T_ramp", low_open=True),
    ),
    "sine": field_table(
        FieldSpec("mean_velocity", "m/s", -_V, _V, "mean band velocity"),
        FieldSpec("amplitude", "m/s", 0.0, _V, "amplitude (|mean| + amplitude within the limit)"),
        FieldSpec("frequency", "Hz", 0.0, 5e4, "frequency (at most half the sample rate)", low_open=True),
        FieldSpec("phase", "rad", -2.0 * math.pi, 2.0 * math.pi, "phase at t = 0"),
    ),
    "table": field_table(FieldSpec("velocities", "m/s", -_V, _V, "band velocities of the table rows")),
}


def friction_fields(law: str) -> dict[str, FieldSpec]:
    """The ranges of friction law `law`'s fields: its parameter dataclass's `ranges` (empty: none).

    ParameterError naming the valid laws for an unknown one.
    """
    from .friction_laws import law_parameters  # the registry: imported when first asked

    ranges: dict[str, FieldSpec] = getattr(law_parameters(law), "ranges", {})
    return ranges


def friction_field(law: str, name: str) -> FieldSpec | None:
    """The range of friction law `law`'s field `name`, None for a field without one."""
    return friction_fields(law).get(name)


def band_field(name: str) -> FieldSpec | None:
    """The range of a band profile field by its name (profile field names are unique across kinds)."""
    for table in BAND_FIELDS.values():
        if name in table:
            return table[name]
    return None


@dataclass(frozen=True)
class SampleField:
    """One per-sample output field of the plant: a RigState field and a RigStateBlock array.

    `formula` is a Python expression that gives the field's value from the plant's quantities: the
    integrator's output sample (core.trajectory.TrajectorySample's fields but its time), the
    plant's `belt_travel` and the run's `normal_force` (N). The plant compiles every formula into
    one function, applied to one sample in the wall-clock modes and to whole arrays in the
    stepped modes (app/plant/output.py). So a new output field is one entry here plus its line in
    RigState.msg and RigStateBlock.msg (test/test_interfaces.py checks the .msg files against this
    table: names, order, units).
    """

    name: str
    unit: str  # SI, '1' for a pure number
    symbol: str
    meaning: str
    formula: str


#: The plant's per-sample output, in RigState's and RigStateBlock's field order.
SAMPLE_FIELDS: tuple[SampleField, ...] = (
    SampleField("displacement", "m", "x", "displacement of the mass (spring at rest: 0)", "displacement"),
    SampleField("velocity", "m/s", "ẋ", "velocity of the mass", "velocity"),
    SampleField("friction_coefficient", "1", "μ", "friction coefficient μ(v_rel)", "friction_coefficient"),
    SampleField(
        "friction_force",
        "N",
        "F",
        "friction force of the interface on the mass, μ N",
        "friction_coefficient * normal_force",
    ),
    SampleField(
        "band_velocity", "m/s", "v_band", "the band velocity this sample was integrated with", "band_velocity"
    ),
    SampleField(
        "relative_velocity",
        "m/s",
        "v_rel",
        "v_band − γ ẋ (γ: the run's velocity coupling)",
        "relative_velocity",
    ),
    SampleField(
        "belt_travel", "m", "", "∫ v_band dt over rig time since the last start or reset", "belt_travel"
    ),
    SampleField("normal_force", "N", "N", "normal force pressing the mass on the band", "normal_force"),
)

#: Shadow mode's per-pair arrays (ShadowBlock, in its field order) and their SI units: the real
#: rig's measured displacement, the plant's sample it is paired with, measured − simulated and the
#: running RMS of that residual over the segment (app/plant/shadow.py).
SHADOW_FIELDS: dict[str, str] = {
    "measured_displacement": "m",
    "simulated_displacement": "m",
    "band_velocity": "m/s",
    "residual": "m",
    "residual_rms": "m",
}

#: SI unit of every per-sample column a bag or a table holds, by name ('1' for a pure number):
#: the SAMPLE_FIELDS, a sample's rig time, RigStateBlock's realtime lateness and SHADOW_FIELDS.
SAMPLE_UNITS: dict[str, str] = (
    {f.name: f.unit for f in SAMPLE_FIELDS} | SHADOW_FIELDS | {"lateness": "s", "time": "s"}
)


def unit_column(name: str, unit: str) -> str:
    """A table column named with its unit: displacement_m, velocity_m_s, friction_coefficient.

    The naming of timeseries.csv (core.trajectory.Trajectory.COLUMNS) and of `lubrig bag export`:
    '/' becomes '_', a pure number ('1') adds nothing.
    """
    return name if unit in ("1", "") else f"{name}_{unit.replace('/', '_')}"
