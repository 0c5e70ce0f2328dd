"""What the live view (`lubrig view`) shows and how often: display rates and decimation (no ROS).

A rig publishes its state at the output rate (1 kHz per sample in realtime; in sim mode blocks of
samples, many times faster than real time). A browser plotting every sample would fall behind, so
the view forwards at most `rate` messages per second of the message's own time (its header stamp:
rig time; receive time for messages without a stamp), and never more than
``WALL_CEILING_FACTOR × rate`` per wall second (a sim run goes many rig seconds per wall second).
Rate 0 forwards every message (latched topics, /diagnostics whose statuses come from two nodes).

Blocks (``state_block``: lubrig_interfaces/RigStateBlock) are shown as the per-sample topic they
stand for (``state``: RigState), the samples taken on the same rule, so a layout plots
``<ns>/state`` in every mode.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..core.params import ParameterError
from .contract import resolve, validate_name

#: Messages per second (of message time) of a topic not named in DISPLAY_RATES.
DEFAULT_DISPLAY_RATE = 50.0
#: Per wall second at most this many times the rate (sim runs faster than real time).
WALL_CEILING_FACTOR = 2.0
#: The wall-clock budget may save up this many seconds' worth of messages (a burst after a pause).
BURST_S = 0.5

#: Display rates (Hz) by contract name; 0 = every message.
DISPLAY_RATES: dict[str, float] = {
    "run_config": 0.0,
    "run_complete": 0.0,
    "/diagnostics": 0.0,
    "dominant_frequency": 10.0,
    "wavelet_power": 10.0,
    "wavelet_image": 10.0,
    "wavelet_frame": 10.0,
    "stability": 10.0,
    "linear_zone": 10.0,
    "critical_damping_ratio": 10.0,
    "oscillation_growing": 10.0,
    "flow_progress": 10.0,
    "/clock": 10.0,
}

#: Block topics shown as the per-sample topic they stand for: block name -> (sample name, type).
EXPANDED_BLOCKS: dict[str, tuple[str, str]] = {
    "state_block": ("state", "lubrig_interfaces/msg/RigState"),
}


def check_rate(value: float, what: str) -> float:
    """`value` if it is a finite rate >= 0 Hz, else ParameterError naming it."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) or value < 0:
        raise ParameterError(
            f"{what}={value!r} is not valid; expected a finite number >= 0 Hz (0: every message)"
        )
    return float(value)


def parse_rates(items: list[str] | tuple[str, ...], namespace: str) -> dict[str, float]:
    """``["state=20", "/diagnostics=1"]`` -> {absolute name: Hz}; ParameterError on a bad item."""
    rates: dict[str, float] = {}
    for item in items:
        name, sep, text = item.partition("=")
        if not sep or not name:
            raise ParameterError(f"rate {item!r} is not valid; expected TOPIC=HZ, e.g. state=20")
        validate_name(name, "rate topic")
        try:
            value = float(text)
        except ValueError:
            raise ParameterError(
                f"rate {item!r} is not valid: {text!r} is not a number; expected TOPIC=HZ, e.g. state=20"
            ) from None
        rates[resolve(namespace, name)] = check_rate(value, f"rate of {name}")
    return rates


@dataclass(frozen=True)
class DisplayRates:
    """Display rate of every topic in `namespace`: overrides, else DISPLAY_RATES, else the default."""

    namespace: str
    overrides: dict[str, float] = field(default_factory=dict)
    default: float = DEFAULT_DISPLAY_RATE

    def rate(self, topic: str) -> float:
        """Hz for the absolute topic name `topic`."""
        if topic in self.overrides:
            return self.overrides[topic]
        for name, rate in DISPLAY_RATES.items():
            if resolve(self.namespace, name) == topic:
                return rate
        return self.default


class Decimator:
    """Take at most `rate` messages per second of message time (and 2×rate per wall second).

    A message (or a sample of a block) is taken when its time is at least one period after the
    last one taken, so consecutive taken times are >= 1/rate apart and at most
    ``duration × rate + 1`` are taken over a stretch of `duration` s of message time. Time going
    back (a plant reset, a replay starting over) starts afresh. Times are integer nanoseconds.
    """

    def __init__(self, rate: float, wall_factor: float = WALL_CEILING_FACTOR) -> None:
        self.rate = check_rate(rate, "rate")
        self.period_ns = round(1e9 / self.rate) if self.rate > 0 else 0
        self.ceiling = self.rate * wall_factor
        self.burst = max(1.0, self.ceiling * BURST_S)
        self._tokens = self.burst
        self._wall: int | None = None
        self._last: int | None = None

    def _refill(self, wall_ns: int) -> None:
        if self._wall is not None and wall_ns > self._wall:
            self._tokens = min(self.burst, self._tokens + (wall_ns - self._wall) * 1e-9 * self.ceiling)
        if self._wall is None or wall_ns > self._wall:
            self._wall = wall_ns

    def take(self, stamp_ns: int, wall_ns: int) -> bool:
        """True if the message of time `stamp_ns`, received at `wall_ns` (monotonic), is shown."""
        return bool(self.take_block(stamp_ns, 0.0, 1, wall_ns))

    def take_block(self, first_ns: int, step_ns: float, count: int, wall_ns: int) -> list[int]:
        """Indices of the samples shown of a block: sample i at ``first_ns + i × step_ns``."""
        if self.period_ns == 0:
            return list(range(count))
        self._refill(wall_ns)
        if self._last is not None and first_ns < self._last:
            self._last = None  # time went back: a reset, a new segment, a replay from the start
        taken: list[int] = []
        i = 0
        while i < count and self._tokens >= 1.0:
            t = first_ns + round(i * step_ns)
            if self._last is not None and t < self._last + self.period_ns:
                if step_ns <= 0:
                    break
                i = max(i + 1, math.ceil((self._last + self.period_ns - first_ns) / step_ns))
                continue
            taken.append(i)
            self._tokens -= 1.0
            self._last = t
            i += 1
        return taken
