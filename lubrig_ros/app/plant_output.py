"""What the plant emits, without ROS: one sample, a block of samples, and the realtime block buffer.

`PlantSample` is one output sample (the per-sample RigState); `PlantBlock` consecutive samples of
one segment (RigStateBlock). `BeltTravel` integrates the band velocity over the emitted samples
(trapezoid rule, in sample order). `BlockBuffer` collects realtime samples, with each sample's
lateness, into blocks of a fixed length: the realtime plant publishes one block per
`output_block_length` samples for the consumers that do not need a message per sample
(recorder, analysis, live view).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

_EMPTY = np.zeros(0)


class PlantSample(NamedTuple):
    """One output sample: what the plant publishes (SI units). A tuple: cheap to make per sample."""

    time: float  # s, rig time
    displacement: float  # m
    velocity: float  # m/s
    friction_coefficient: float  # 1
    band_velocity: float  # m/s, the band velocity this sample was integrated with
    belt_travel: float  # m, integral of the band velocity since the last reset
    friction_force: float  # N, μ · normal force
    relative_velocity: float = 0.0  # m/s, v_band − γ ẋ
    sample_index: int = 0  # samples emitted in this segment before this one
    segment: int = 0  # 0 at start, +1 per reset


#: The per-sample arrays of a PlantBlock, in RigStateBlock's field order.
BLOCK_FIELDS: tuple[str, ...] = (
    "displacement",
    "velocity",
    "friction_coefficient",
    "friction_force",
    "band_velocity",
    "relative_velocity",
    "belt_travel",
)


@dataclass(frozen=True)
class PlantBlock:
    """Consecutive output samples of one segment (SI units): one RigStateBlock.

    Sample i has rig time `time[i]` and sample index first_sample_index + i. Realtime blocks also
    carry each sample's `lateness` (s after its due time) and `skipped`, the sample indices just
    before first_sample_index that the plant skipped when it fell behind (a declared gap).
    """

    segment: int
    first_sample_index: int
    sample_period: float  # s
    time: np.ndarray  # s
    displacement: np.ndarray  # m
    velocity: np.ndarray  # m/s
    friction_coefficient: np.ndarray  # 1
    friction_force: np.ndarray  # N
    band_velocity: np.ndarray  # m/s
    relative_velocity: np.ndarray  # m/s
    belt_travel: np.ndarray  # m
    lateness: np.ndarray = field(default_factory=lambda: _EMPTY)  # s (realtime only)
    skipped: int = 0

    def __len__(self) -> int:
        return int(self.time.size)

    def samples(self) -> list[PlantSample]:
        """The block as PlantSample tuples."""
        return [
            PlantSample(
                float(self.time[i]),
                float(self.displacement[i]),
                float(self.velocity[i]),
                float(self.friction_coefficient[i]),
                float(self.band_velocity[i]),
                float(self.belt_travel[i]),
                float(self.friction_force[i]),
                float(self.relative_velocity[i]),
                self.first_sample_index + i,
                self.segment,
            )
            for i in range(len(self))
        ]


class BeltTravel:
    """∫ v_band dt over the emitted samples since the last reset (trapezoid rule, sample order)."""

    def __init__(self) -> None:
        self.value = 0.0
        self.last: tuple[float, float] | None = None  # (rig time, band velocity) of the last sample

    def add(self, t: float, band: float) -> float:
        """One sample at rig time t; the travel at it."""
        if self.last is not None and t > self.last[0]:
            self.value += 0.5 * (band + self.last[1]) * (t - self.last[0])
        self.last = (t, band)
        return self.value

    def add_many(self, t: np.ndarray, band: np.ndarray) -> np.ndarray:
        """Consecutive samples; the travel at each (summed in order, as one `add` per sample)."""
        steps = np.empty(t.size)
        if self.last is None:
            steps[0] = 0.0
        else:
            t0, b0 = self.last
            steps[0] = 0.5 * (band[0] + b0) * (t[0] - t0) if t[0] > t0 else 0.0
        steps[1:] = np.where(t[1:] > t[:-1], 0.5 * (band[1:] + band[:-1]) * (t[1:] - t[:-1]), 0.0)
        travel = np.cumsum(np.concatenate(([self.value], steps)))[1:]
        self.value = float(travel[-1])
        self.last = (float(t[-1]), float(band[-1]))
        return travel


class BlockBuffer:
    """Realtime samples collected into PlantBlocks of at most `length` samples (preallocated)."""

    _COLUMNS = ("time", *BLOCK_FIELDS, "lateness")

    def __init__(self, length: int, sample_period: float) -> None:
        self.length, self.sample_period = length, sample_period
        self._data = np.zeros((len(self._COLUMNS), length))
        self.count = 0
        self.first_index = 0
        self.segment = 0
        self.skipped = 0  # declared gap before the next block

    def add(self, s: PlantSample, lateness: float) -> PlantBlock | None:
        """Append a sample; the full block when this sample completes one, else None.

        A sample that does not follow the buffered ones (another segment, an index jump) starts a
        new block: call `flush` first (the session does, at a reset and a skip).
        """
        if self.count == 0:
            self.first_index, self.segment = s.sample_index, s.segment
        row = self._data[:, self.count]
        row[0], row[1], row[2], row[3] = s.time, s.displacement, s.velocity, s.friction_coefficient
        row[4], row[5], row[6], row[7] = s.friction_force, s.band_velocity, s.relative_velocity, s.belt_travel
        row[8] = lateness
        self.count += 1
        return self.flush() if self.count >= self.length else None

    def skip(self, count: int) -> None:
        """`count` sample indices are skipped before the next buffered sample (flush first)."""
        self.skipped += count

    def flush(self) -> PlantBlock | None:
        """The buffered samples as a block (None when empty); the buffer starts over."""
        if self.count == 0:
            return None
        cols = {name: self._data[i, : self.count].copy() for i, name in enumerate(self._COLUMNS)}
        block = PlantBlock(
            segment=self.segment,
            first_sample_index=self.first_index,
            sample_period=self.sample_period,
            skipped=self.skipped,
            **cols,
        )
        self.count, self.skipped = 0, 0
        return block

    def clear(self) -> None:
        """Drop what is buffered (a reset)."""
        self.count, self.skipped = 0, 0
