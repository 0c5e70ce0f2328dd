"""belt_drive's band profile parameters as data: profile.kind, every band kind's fields, profile.path.

Part of the nodes' parameters (app/interface/node_parameters.py re-exports them,
app/interface/contract.py in turn); the numeric fields take their unit and physical range from
core/schema.py `BAND_FIELDS`.
"""

from __future__ import annotations

from ...core import schema
from .parameter_types import NodeParameter
from .parameter_types import field_parameter as _field
from .parameter_types import param as _p


def _profile_parameters() -> tuple[NodeParameter, ...]:
    """profile.kind, every numeric field of the band kinds (ranges: core/schema.py) and profile.path."""
    kinds = " | ".join(schema.BAND_FIELDS)
    out = [
        _p(
            "profile.kind",
            "string",
            None,
            f"band profile kind ({kinds}); run time",
            read_only=False,
            from_config="band.kind",
        )
    ]
    for kind, table in schema.BAND_FIELDS.items():
        for name, spec in table.items():
            if kind == "table":
                continue  # a table is given by its CSV (profile.path)
            text = f"{kind} profile: {spec.symbol + ', ' if spec.symbol else ''}{spec.description}; run time"
            out.append(_field(f"profile.{name}", spec, text, read_only=False, from_config=f"band.{name}"))
    out.append(
        _p(
            "profile.path",
            "string",
            None,
            "table profile: CSV of time_s,band_velocity_m_s (rows checked as the table's); run time",
            read_only=False,
            from_config="band.path",
        )
    )
    return tuple(out)


#: belt_drive's band profile parameters (core.profiles kinds; validated by their classes).
PROFILE_PARAMETERS: tuple[NodeParameter, ...] = _profile_parameters()


def profile_parameter(name: str) -> NodeParameter | None:
    """The contract's `profile.<name>` parameter, None for a field of a kind outside core/schema.py."""
    return next((p for p in PROFILE_PARAMETERS if p.name == f"profile.{name}"), None)
