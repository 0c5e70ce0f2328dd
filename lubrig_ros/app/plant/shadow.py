"""Shadow mode without ROS: a real rig's measured displacement paired with the plant's samples.

In ``rig_in_loop`` with `shadow` on, the plant also takes the real rig's measured displacement
(`measured_value`, one value per message) and pairs each with the simulated sample it answers;
the pairing rule is documented once, in app/plant/session.py ("Shadow"). Band values and
measured values are numbered in the order the rig sent them (the band values by the rules of
app/plant/shadow_rules.py, the measured values here, by their place in the segment); a simulated
sample carries the number of the band value it was integrated with (`simulated`). Equal numbers
pair, whichever arrives first; each pair gives the residual measured − simulated and the running
RMS of the residuals of the segment. `take` hands the pairs made since the last call to the
publisher (one ShadowBlock per state_block), in sample order.

A measured value that is not finite, or larger than MEASURED_LIMIT in magnitude (no rig of this
kind moves a metre: such a value is a unit or encoding error, and its square would overflow the
running RMS), is rejected and counted (it keeps its number, so the values after it still pair
correctly), never paired. Numbers waiting for their partner are kept for at most `capacity`
numbers behind the newest; older ones are dropped and counted (`unpaired`): a band value the
plant never integrated (a Float64 replaced by a newer one before a tick took it, a skipped
sample) leaves its measured value without a sample.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: m: the largest |measured displacement| taken (module docstring).
MEASURED_LIMIT = 1.0
_EMPTY = np.zeros(0)
_EMPTY_INDEX = np.zeros(0, dtype=np.int64)


@dataclass(frozen=True)
class ShadowSamples:
    """Paired samples of one segment in sample order: what one ShadowBlock carries (SI units)."""

    segment: int = 0
    sample_index: np.ndarray = field(default_factory=lambda: _EMPTY_INDEX)  # RigStateBlock indices
    measured: np.ndarray = field(default_factory=lambda: _EMPTY)  # m
    simulated: np.ndarray = field(default_factory=lambda: _EMPTY)  # m
    band_velocity: np.ndarray = field(default_factory=lambda: _EMPTY)  # m/s, of the simulated sample
    residual: np.ndarray = field(default_factory=lambda: _EMPTY)  # m, measured − simulated
    residual_rms: np.ndarray = field(default_factory=lambda: _EMPTY)  # m, running RMS in the segment
    rejected: int = 0  # measured values rejected in the segment so far (MEASURED_LIMIT, NaN)
    unpaired: int = 0  # numbers dropped without a partner in the segment so far

    def __len__(self) -> int:
        return int(self.sample_index.size)


def measured_velocity(
    index: np.ndarray, measured: np.ndarray, period: float, previous: tuple[int, float] | None
) -> np.ndarray:
    """ẋ (m/s) of a measured displacement by backward differences over consecutive sample indices.

    `previous` is the (sample index, displacement) of the sample before the first (the last one
    of the previous block), or None. A sample whose predecessor is not the sample just before it
    (the first of a segment, after a gap) gets 0. The rig sends no velocity: this estimate is what
    the analysis of the measured signal uses for its relative velocity (stick flags).
    """
    if index.size == 0:
        return _EMPTY
    before_index = previous[0] if previous is not None else int(index[0]) - 2
    before_x = previous[1] if previous is not None else float(measured[0])
    idx = np.concatenate(([before_index], index))
    x = np.concatenate(([before_x], measured))
    return np.where(np.diff(idx) == 1, np.diff(x) / period, 0.0)


class ShadowPairing:
    """Measured values paired with simulated samples by the number of their band value."""

    def __init__(self, capacity: int) -> None:
        self.capacity = max(1, int(capacity))
        self.segment = 0
        self._clear()

    def _clear(self) -> None:
        self.simulated_by_number: dict[int, tuple[int, float, float]] = {}
        self.measured_by_number: dict[int, float] = {}
        self.measured_count = 0  # measured messages received in the segment (the next one's number)
        self.rejected = 0
        self.last_rejected: float | None = None
        self.unpaired = 0
        self.paired = 0
        self.sum_squares = 0.0
        self.rms = 0.0
        self._out: list[tuple[int, float, float, float, float, float]] = []

    def reset(self, segment: int) -> None:
        """A new segment: the numbering restarts at 0, the running RMS too; pairs not taken are dropped."""
        self.segment = segment
        self._clear()

    def measured_value(self, value: float) -> bool:
        """The next measured displacement (m) from the rig; False if rejected (not a finite float)."""
        number = self.measured_count
        self.measured_count += 1
        if not isinstance(value, float) or not abs(value) <= MEASURED_LIMIT:  # NaN fails too
            self.rejected += 1
            self.last_rejected = value if isinstance(value, float) else math.nan
            return False
        sim = self.simulated_by_number.pop(number, None)
        if sim is not None:
            self._pair(sim[0], value, sim[1], sim[2])
        else:
            self._keep(self.measured_by_number, number, value)
        return True

    def simulated(self, number: int, sample_index: int, displacement: float, band: float) -> None:
        """A published sample of the segment, integrated with band value `number`."""
        measured = self.measured_by_number.pop(number, None)
        if measured is not None:
            self._pair(sample_index, measured, displacement, band)
        else:
            self._keep(self.simulated_by_number, number, (sample_index, displacement, band))

    def _keep(self, waiting: dict[int, Any], number: int, item: Any) -> None:
        """Keep `item` until its partner comes; drop what is `capacity` numbers behind it."""
        waiting[number] = item
        while waiting:
            oldest = next(iter(waiting))
            if oldest > number - self.capacity:
                break
            del waiting[oldest]
            self.unpaired += 1

    def _pair(self, sample_index: int, measured: float, simulated: float, band: float) -> None:
        residual = measured - simulated
        self.paired += 1
        self.sum_squares += residual * residual
        self.rms = math.sqrt(self.sum_squares / self.paired)
        self._out.append((sample_index, measured, simulated, band, residual, self.rms))

    def take(self) -> ShadowSamples | None:
        """The pairs made since the last call, in sample order (None when there are none)."""
        if not self._out:
            return None
        rows = sorted(self._out)
        self._out = []
        columns = np.array(rows, dtype=float).T
        return ShadowSamples(
            segment=self.segment,
            sample_index=columns[0].astype(np.int64),
            measured=columns[1],
            simulated=columns[2],
            band_velocity=columns[3],
            residual=columns[4],
            residual_rms=columns[5],
            rejected=self.rejected,
            unpaired=self.unpaired,
        )
