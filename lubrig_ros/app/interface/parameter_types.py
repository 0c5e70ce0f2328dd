"""The type of a node parameter in the contract: name, type, default, unit, range, meaning.

Plain data (no ROS import); the tables of every node's parameters are app/interface/node_parameters.py,
the ROS descriptors are made from these by nodes/common.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

from ...core.schema import FieldSpec, number_text
from ...core.validation import ParameterError

ParameterType = Literal["double", "integer", "string", "bool", "string_array"]


@dataclass(frozen=True)
class NodeParameter:
    """One ROS parameter of a node.

    `default` None means "from the selected run configuration" (`from_config` names the field);
    `low`/`high` bound numbers (`low_open`: strictly greater than low); `choices` lists the
    valid strings; `read_only` parameters are fixed at start-up, the others may be set at run time.
    """

    name: str
    type: ParameterType
    default: Any
    description: str
    unit: str = ""
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    choices: tuple[str, ...] = ()
    read_only: bool = True
    from_config: str = ""
    #: 0 is valid and means this (velocity_coupling 0: the convention's γ); then `low` is 0 (the
    #: descriptor's range) and a value other than 0 must be at least `nonzero_low`
    zero_means: str = ""
    nonzero_low: float = 0.0

    def expected(self) -> str:
        """What is valid, in words (used in error messages and the docs)."""
        unit = f" {self.unit}" if self.unit and self.unit not in ("1", "SI") else ""
        if self.choices:
            return f"one of {list(self.choices)}"
        if self.type == "string":
            return "a string"
        if self.type == "string_array":
            return "a list of strings"
        if self.type == "bool":
            return "true or false"
        number = "an integer" if self.type == "integer" else "a finite number"
        if self.zero_means:
            return f"0 ({self.zero_means}) or {_num(self.nonzero_low)}..{_num(self.high or 0.0)}{unit}"
        if self.low is not None and self.high is not None:
            if self.low_open:
                return f"{number} > {_num(self.low)} and <= {_num(self.high)}{unit}"
            return f"{_num(self.low)}..{_num(self.high)}{unit}"
        if self.low is not None:
            return f"{number} {'>' if self.low_open else '>='} {_num(self.low)}{unit}"
        if self.high is not None:
            return f"{number} <= {_num(self.high)}{unit}"
        return number

    def check(self, value: Any) -> Any:
        """Return `value` if valid for this parameter, else ParameterError naming value and range."""
        bad = ParameterError(f"{self.name}={value!r} is not valid; expected {self.expected()}")
        if self.type in ("double", "integer"):
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise bad
            if self.type == "integer" and not isinstance(value, int):
                raise bad
            if not math.isfinite(value):
                raise bad
            if self.zero_means and value == 0:
                return value
            if self.zero_means and value < self.nonzero_low:
                raise bad
            if self.low is not None and (value < self.low or (self.low_open and value <= self.low)):
                raise bad
            if self.high is not None and value > self.high:
                raise bad
        elif self.type == "string":
            if not isinstance(value, str) or (self.choices and value not in self.choices):
                raise bad
        elif self.type == "string_array":
            if isinstance(value, str) or not isinstance(value, list | tuple):
                raise bad
            if not all(isinstance(v, str) for v in value):
                raise bad
        elif not isinstance(value, bool):
            raise bad
        return value


def _num(x: float) -> str:
    return number_text(float(x))


def param(name: str, type_: ParameterType, default: Any, text: str, **kw: Any) -> NodeParameter:
    """A NodeParameter (the tables' short form)."""
    return NodeParameter(name, type_, default, text, **kw)


def field_parameter(name: str, spec: FieldSpec, text: str, **kw: Any) -> NodeParameter:
    """A double parameter whose unit and range are a configuration field's (core/schema.py)."""
    return NodeParameter(
        name,
        "double",
        kw.pop("default", None),
        text,
        unit=spec.unit,
        low=spec.low,
        high=spec.high,
        low_open=spec.low_open,
        **kw,
    )
