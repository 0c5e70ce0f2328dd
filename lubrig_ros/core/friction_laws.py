"""Friction laws μ(v): the protocol every law follows and the registry that finds one by name.

A friction law is one module (see docs/extending.md) holding

* its **parameters**: a frozen dataclass, validated in ``__post_init__``, SI units, with a class
  attribute ``law`` (the registry name) and a field ``normal_force`` (N, the load the rig's force
  N μ is made of);
* its **compiled kernel**: a numba function ``(v: float, p: float64[::1]) -> (μ, dμ/dv)`` decorated
  with :func:`law_kernel`, odd μ / even slope, finite for every finite v
  (v = 0 included, where a law may return an infinite slope); ``p`` is ``pack(params)``;
* optional **landmarks**: the friction peak (end of the rising zone 1, the stick threshold) and the
  minimum (start of the rising zone 3), or None when the law has none with these parameters;
* one line in :data:`BUILTIN_LAWS` (its registration), or a call to :func:`register_law`. The
  kernel compiles when first used (:class:`LawKernel`), so importing the module is light and
  :func:`law_parameters` imports it to find the parameters; only the junction law, whose
  module compiles helpers with numba at import, names its dataclass in
  :data:`BUILTIN_PARAMETERS` (it lives in core.params).

Vectorized μ(v) and dμ/dv come with :class:`KernelLaw` (the kernel looped over an array through the
one compiled adapter, core.kernels.evaluate_law), so a law only writes its scalar kernel.

YAML: ``rig: {friction: {law: stribeck, ...}}``; without ``law`` the junction-kinetics law
(:data:`DEFAULT_LAW`) and its parameters, exactly as before laws had names.
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Callable
from dataclasses import dataclass, fields, is_dataclass
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from lubrig_ros.core.errors import InputError

from .validation import ParameterError

#: The law a friction section without `law:` means (the study's junction kinetics).
DEFAULT_LAW = "junction_kinetics"

#: Laws shipped with the package: name → module that registers it (imported on first use, so
#: reading a configuration does not load numba unless a law is evaluated).
BUILTIN_LAWS: dict[str, str] = {
    "junction_kinetics": "lubrig_ros.core.junction",
    "stribeck": "lubrig_ros.core.stribeck",
}
#: Where each built-in law's parameter dataclass lives ("module:name"), apart from its kernel:
#: the topic contract, the parameter descriptors and configuration loading need only the
#: parameters, and a law's module imports numba (about 1 s of every node's start-up).
BUILTIN_PARAMETERS: dict[str, str] = {
    "junction_kinetics": "lubrig_ros.core.params:FrictionParameters",
}


class LawKernel:
    """A law's scalar kernel (v, p) -> (μ, dμ/dv), compiled by numba when first used.

    So importing a law's module costs no numba (about 1 s of CPU): the topic contract, the
    parameter descriptors and configuration loading need only its parameters. Compiled for
    core.kernels.LAW_SIGNATURE with numba's on-disk cache (keyed on the kernel's own file);
    `py_func` is the Python function, `dispatcher` the compiled one.
    """

    def __init__(self, function: Callable[..., tuple[float, float]]) -> None:
        self.py_func = function
        self.__name__, self.__qualname__ = function.__name__, function.__qualname__
        self.__module__, self.__doc__ = function.__module__, function.__doc__
        self._dispatcher: Any = None

    @property
    def dispatcher(self) -> Any:
        """The numba dispatcher, compiled on the first call."""
        if self._dispatcher is None:
            from numba import njit

            from .kernels import LAW_SIGNATURE

            self._dispatcher = njit(LAW_SIGNATURE, cache=True)(self.py_func)
        return self._dispatcher

    def __call__(self, v: float, p: np.ndarray) -> tuple[float, float]:
        """μ(v) and dμ/dv through the compiled kernel."""
        result: tuple[float, float] = self.dispatcher(v, p)
        return result


def law_kernel(function: Callable[..., tuple[float, float]]) -> LawKernel:
    """Decorator of a law's scalar kernel: compiled by numba when first used (LawKernel)."""
    return LawKernel(function)


@dataclass(frozen=True)
class CurveLandmark:
    """A stationary point of μ(v): where and how large."""

    velocity: float  # m/s
    mu: float


@runtime_checkable
class FrictionLaw(Protocol):
    """A friction law: μ(v) and dμ/dv, its compiled kernel and its optional landmarks."""

    @property
    def name(self) -> str:
        """Registry name (YAML `law:`)."""
        ...

    @property
    def parameters(self) -> type[Any]:
        """The parameter dataclass."""
        ...

    @property
    def kernel(self) -> Any:
        """The kernel (v, p) -> (μ, dμ/dv): a LawKernel (law_kernel) or a numba dispatcher."""
        ...

    def pack(self, params: Any) -> np.ndarray:
        """Parameters as the float64 array the kernel receives as p."""
        ...

    def evaluate(self, velocity: np.ndarray, params: Any) -> tuple[np.ndarray, np.ndarray]:
        """μ and dμ/dv (s/m) at every velocity (m/s) of a 1-D float64 array."""
        ...

    def peak(self, params: Any) -> CurveLandmark | None:
        """Maximum of μ for v > 0 (end of zone 1), None if μ has none."""
        ...

    def minimum(self, params: Any) -> CurveLandmark | None:
        """Minimum of μ above the peak (start of zone 3), None if μ has none."""
        ...

    def describe(self, params: Any) -> str:
        """Short text naming the parameters that decide the landmarks (for error messages)."""
        ...


class KernelLaw:
    """Base for a law given by its compiled kernel: packing, vectorized evaluation, landmarks.

    Subclasses set ``name``, ``parameters`` and ``kernel``. The default landmarks scan the slope's
    sign on a log grid over SCAN_RANGE and refine each sign change with brentq in log v; a law may
    override peak/minimum with a closed form or its own bracket.
    """

    name: ClassVar[str]
    parameters: ClassVar[type[Any]]
    kernel: ClassVar[Any]
    #: |v| range (m/s) the default landmark search covers, points per decade of its grid.
    SCAN_RANGE: ClassVar[tuple[float, float]] = (1e-15, 1e-2)
    SCAN_POINTS_PER_DECADE: ClassVar[int] = 20

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        kernel = cls.__dict__.get("kernel")
        if kernel is not None and not isinstance(kernel, staticmethod):
            # a numba dispatcher is a descriptor: self.kernel would be a bound method
            cls.kernel = staticmethod(kernel)

    def pack(self, params: Any) -> np.ndarray:
        """The dataclass fields in declaration order as a contiguous float64 array."""
        return np.array([float(getattr(params, f.name)) for f in fields(params)], dtype=np.float64)

    def evaluate(self, velocity: np.ndarray, params: Any) -> tuple[np.ndarray, np.ndarray]:
        """μ and dμ/dv at every velocity of a 1-D array, through the compiled adapter."""
        from .kernels import evaluate_law

        return evaluate_law(self.kernel, velocity, self.pack(params))

    def landmark(self, params: Any, low: float, high: float) -> CurveLandmark | None:
        """The stationary point of μ between low and high (m/s) if the slope changes sign there."""
        from scipy.optimize import brentq

        from .kernels import evaluate_law

        p = self.pack(params)

        def slope(log_v: float) -> float:
            return float(self.evaluate(np.array([10.0**log_v]), params)[1][0])

        a, b = math.log10(low), math.log10(high)
        if not slope(a) * slope(b) < 0.0:
            return None
        log_v = brentq(slope, a, b, xtol=1e-14, rtol=1e-14)
        v = 10.0**log_v
        return CurveLandmark(velocity=v, mu=float(evaluate_law(self.kernel, np.array([v]), p)[0][0]))

    def _sign_changes(self, params: Any) -> list[tuple[float, float, int]]:
        low, high = self.SCAN_RANGE
        decades = math.log10(high) - math.log10(low)
        v = np.logspace(math.log10(low), math.log10(high), int(decades * self.SCAN_POINTS_PER_DECADE) + 1)
        sign = np.sign(self.evaluate(v, params)[1])
        changes = np.flatnonzero(sign[1:] * sign[:-1] < 0.0)
        return [(float(v[i]), float(v[i + 1]), int(sign[i])) for i in changes]

    def peak(self, params: Any) -> CurveLandmark | None:
        """First maximum of μ (slope + → −) on the scan grid, refined."""
        for low, high, before in self._sign_changes(params):
            if before > 0:
                return self.landmark(params, low, high)
        return None

    def minimum(self, params: Any) -> CurveLandmark | None:
        """First minimum of μ (slope − → +) above the peak, refined."""
        peak = self.peak(params)
        if peak is None:
            return None
        for low, high, before in self._sign_changes(params):
            if before < 0 and low >= peak.velocity * (1.0 - 1e-12):
                return self.landmark(params, low, high)
        return None

    def describe(self, params: Any) -> str:
        """All parameters, name=value."""
        return ", ".join(f"{f.name}={getattr(params, f.name)!r}" for f in fields(params))


_REGISTRY: dict[str, FrictionLaw] = {}


def register_law(law: FrictionLaw) -> FrictionLaw:
    """Add a law to the registry under law.name (its parameters' `law` must say the same)."""
    name = law.name
    if getattr(law.parameters, "law", None) != name:
        raise InputError(f"{law!r}: parameters {law.parameters.__name__}.law must be {name!r}")
    if not is_dataclass(law.parameters) or "normal_force" not in {f.name for f in fields(law.parameters)}:
        raise InputError(f"{law!r}: parameters must be a dataclass with a normal_force field (N)")
    if name in _REGISTRY and _REGISTRY[name] is not law:
        raise InputError(f"friction law {name!r} is already registered")
    _REGISTRY[name] = law
    return law


def law_names() -> list[str]:
    """Every law a configuration may name (built-in first)."""
    return list(dict.fromkeys([*BUILTIN_LAWS, *_REGISTRY]))


def law_named(name: str) -> FrictionLaw:
    """The registered law called `name`; ParameterError naming the valid ones otherwise."""
    if name not in _REGISTRY and name in BUILTIN_LAWS:
        importlib.import_module(BUILTIN_LAWS[name])  # registers itself
    try:
        return _REGISTRY[name]
    except (KeyError, TypeError):
        raise ParameterError(f"friction law={name!r} is not valid; expected one of {law_names()}") from None


def law_parameters(name: str) -> type[Any]:
    """The parameter dataclass of law `name`, without importing a built-in law's kernel module.

    ParameterError naming the valid laws for an unknown one.
    """
    if name not in _REGISTRY and name in BUILTIN_PARAMETERS:
        module, attribute = BUILTIN_PARAMETERS[name].split(":")
        kind: type[Any] = getattr(importlib.import_module(module), attribute)
        return kind
    return law_named(name).parameters  # a law module imports no numba (LawKernel): light


def law_for(params: Any) -> FrictionLaw:
    """The law a parameter set belongs to (by its class attribute `law`)."""
    name = getattr(type(params), "law", None)
    if not isinstance(name, str):
        raise ParameterError(
            f"{type(params).__name__} is not a friction-law parameter set (no class attribute 'law')"
        )
    law = law_named(name)
    if not isinstance(params, law.parameters):
        raise ParameterError(f"{type(params).__name__} is not the parameter set of law {name!r}")
    return law
