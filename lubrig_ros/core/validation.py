"""Parameter validation shared by every parameter set: the error type and the number checks."""

from __future__ import annotations

import math
from typing import Any

from lubrig_ros.core.errors import LubrigError


class ParameterError(LubrigError, ValueError):
    """A parameter value outside what the model accepts; the message names value and valid range."""


def _check_finite(name: str, value: Any) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name}={value!r} is not a number; expected a finite float") from None
    if not math.isfinite(number):
        raise ParameterError(f"{name}={value!r} is not finite; expected a finite float")
    return number


def _check_positive(name: str, value: Any) -> float:
    number = _check_finite(name, value)
    if number <= 0.0:
        raise ParameterError(f"{name}={value!r} must be > 0")
    return number


def _check_range(name: str, value: Any, low: float, high: float) -> float:
    number = _check_finite(name, value)
    if not low <= number <= high:
        raise ParameterError(f"{name}={value!r} is outside the valid range [{low}, {high}]")
    return number
