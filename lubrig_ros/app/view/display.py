"""What the live view (`lubrig view`) shows and how often: display rates and decimation (no ROS).

A rig publishes its state at the output rate (1 kHz per sample in realtime; in sim mode blocks of
samples, many times faster than real time). A browser plotting every sample would fall behind, so
the view forwards at most `rate` messages per second of the message's own time (its header stamp:
rig time; receive time for messages without a stamp), and never more than
``WALL_CEILING_FACTOR × rate`` per wall second (a sim run goes many rig seconds per wall second).
Rate 0 forwards every message (latched topics, /diagnostics whose statuses come from two nodes).

Blocks (``state_block``: lubrig_interfaces/RigStateBlock) are shown as the per-sample topic they
stand for (``state``: RigState), the samples taken on the same rule, so a layout plots
``<ns>/state`` in every mode. Between two samples shown the view also keeps the extremes of a
block topic's samples (`Envelope`, fields `EXTREME_FIELDS`): the samples holding the least and
the greatest value of each field since the last sample shown, where that value lies outside the
range of the two shown samples around it. They are shown just before the later of the two, in
time order: a one-sample slip spike between two displayed samples is shown, a monotone stretch
adds nothing, and a display interval holds at most 1 + 2 × len(EXTREME_FIELDS) samples.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from ...core.params import ParameterError
from ..interface.contract import resolve, validate_name

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

#: Fields of a block's samples whose extremes between two samples shown are kept (Envelope).
EXTREME_FIELDS = ("displacement", "velocity", "friction_coefficient")

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


class Envelope:
    """The extremes of each field between two samples shown (see the module docstring).

    `offer` each sample not shown; `shown` a sample that is shown returns the held samples to
    show before it (their items as offered, in offer order). Items are whatever the caller needs
    to show a sample later (the view keeps the sample's values).
    """

    def __init__(self, n_fields: int) -> None:
        self.n_fields = n_fields
        self._ends: Sequence[float] | None = None  # the values of the last sample shown
        self._low: list[tuple[float, int, object] | None] = [None] * n_fields
        self._high: list[tuple[float, int, object] | None] = [None] * n_fields
        self._order = 0

    def offer(self, values: Sequence[float], item: object) -> None:
        """A sample not shown (on the rate rule): held while it is a field's least or greatest."""
        self._order += 1
        for f in range(self.n_fields):
            v = values[f]
            low, high = self._low[f], self._high[f]
            if low is None or v < low[0]:
                self._low[f] = (v, self._order, item)
            if high is None or v > high[0]:
                self._high[f] = (v, self._order, item)

    def shown(self, values: Sequence[float]) -> list[object]:
        """A sample is shown now: the held extremes outside the range of it and the one before."""
        keep: dict[int, object] = {}
        if self._ends is not None:
            for f in range(self.n_fields):
                top, bottom = max(self._ends[f], values[f]), min(self._ends[f], values[f])
                high, low = self._high[f], self._low[f]
                if high is not None and high[0] > top:
                    keep[high[1]] = high[2]
                if low is not None and low[0] < bottom:
                    keep[low[1]] = low[2]
        self.reset()
        self._ends = list(values)
        return [keep[k] for k in sorted(keep)]

    def reset(self) -> None:
        """Forget what was held (a reset, time going back: the next sample shown starts afresh)."""
        self._ends = None
        self._low = [None] * self.n_fields
        self._high = [None] * self.n_fields
