"""The plant's parameters <-> run configuration, without ROS.

The plant node's configuration parameters (contract entries with `from_config`: rig, friction
law fields, simulation settings) are a flat view of a RunConfig: `parameter_defaults` gives the
parameters of a configuration, `config_from` the configuration of parameter values (applied at a
reset). Which parameters exist depends on the friction law (its parameter dataclass).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, replace
from typing import Any

from ...core.friction_laws import law_parameters
from ...core.presets import RunConfig, from_mapping
from ..interface.contract import RIG_FIELDS, friction_fields, plant_parameters


def law_of(config: RunConfig) -> str:
    """Name of the friction law of a run configuration (core.friction_laws registry)."""
    return str(type(config.rig.friction).law)


def config_parameters(law: str) -> tuple[str, ...]:
    """Plant parameters that rebuild the run configuration (contract entries with `from_config`)."""
    return tuple(p.name for p in plant_parameters(law) if p.from_config)


def runtime_parameters(law: str) -> frozenset[str]:
    """Of these, the ones that may change at run time (applied at the next reset)."""
    return frozenset(p.name for p in plant_parameters(law) if p.from_config and not p.read_only)


#: config_parameters / runtime_parameters of the default (junction-kinetics) law.
CONFIG_PARAMETERS: tuple[str, ...] = config_parameters("junction_kinetics")
RUNTIME_PARAMETERS: frozenset[str] = runtime_parameters("junction_kinetics")


def _field(data: Mapping[str, Any], path: str) -> Any:
    for key in path.split("."):
        data = data[key]
    return data


def parameter_defaults(base: RunConfig, law: str | None = None) -> dict[str, Any]:
    """Default values of the configuration parameters (config_parameters(law)) from a run configuration.

    `law` None: the base's friction law. Another law than the base's takes its own parameter
    defaults (its dataclass's), with the base's normal force. ParameterError for an unknown law.
    """
    law = law or law_of(base)
    data = base.to_dict()
    if law == law_of(base):
        friction = asdict(base.rig.friction)
    else:
        friction = asdict(replace(law_parameters(law)(), normal_force=base.rig.normal_force))
    data["rig"]["friction"] = {"law": law, **friction}
    out: dict[str, Any] = {}
    for p in plant_parameters(law):
        if p.from_config:
            value = _field(data, p.from_config)
            if value is None and p.name == "velocity_coupling":
                value = 0.0  # no explicit γ: the convention's
            out[p.name] = float(value) if p.type == "double" else value
    return out


def config_from(base: RunConfig, values: Mapping[str, Any]) -> RunConfig:
    """The run configuration of `base` with the plant's configuration parameters applied.

    `values` maps parameter names (config_parameters of the law) to values; missing ones keep
    base's. `friction.law` (default: the base's law) selects the friction law whose
    `friction.<field>` values apply; fields not given take the base's values (same law) or the
    law's defaults. An empty `convention` means the base configuration's; `velocity_coupling`
    0 means the convention's γ, > 0 an explicit γ overriding it. ParameterError for invalid values.
    """
    law = values.get("friction.law") or law_of(base)
    defaults = parameter_defaults(base, law)

    def value(name: str) -> Any:
        return values[name] if name in values else defaults[name]

    data = base.to_dict()
    data["rig"].update({n: value(f"rig.{n}") for n in RIG_FIELDS})
    data["rig"]["convention"] = value("convention") or base.rig.convention
    gamma = value("velocity_coupling")  # 0: the convention's γ
    data["rig"]["velocity_coupling"] = float(gamma) if gamma else None
    friction = {n: value(f"friction.{n}") for n in friction_fields(law) if n != "normal_force"}
    friction["normal_force"] = value("rig.normal_force")
    friction["law"] = law
    data["rig"]["friction"] = friction
    data["simulation"].update(
        {n: value(n) for n in ("duration", "sample_rate", "rtol", "initial_perturbation")}
    )
    return from_mapping(data)
