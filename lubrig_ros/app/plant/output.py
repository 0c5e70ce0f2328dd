"""What the plant emits, without ROS: one sample, a block of samples, and the realtime block buffer.

`PlantSample` is one output sample (the per-sample RigState); `PlantBlock` consecutive samples of
one segment (RigStateBlock). `BeltTravel` integrates the band velocity over the emitted samples
(trapezoid rule, in sample order). `BlockBuffer` collects realtime samples, with each sample's
lateness, into blocks of a fixed length: the realtime plant publishes one block per
`output_block_length` samples for the consumers that do not need a message per sample
(recorder, analysis, live view).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from ...core.schema import SAMPLE_FIELDS
from ...core.trajectory import Trajectory, TrajectorySample

_EMPTY = np.zeros(0)

#: The per-sample fields of a PlantSample and the arrays of a PlantBlock, in RigState's and
#: RigStateBlock's field order (core.schema.SAMPLE_FIELDS).
BLOCK_FIELDS: tuple[str, ...] = tuple(f.name for f in SAMPLE_FIELDS)
_FIELD_INDEX = {name: i for i, name in enumerate(BLOCK_FIELDS)}

#: The integrator's output per sample (core.trajectory.TrajectorySample but its time).
INTEGRATED: tuple[str, ...] = TrajectorySample._fields[1:]
#: What the formulas of SAMPLE_FIELDS may use, in the order `derive` takes them.
QUANTITIES: tuple[str, ...] = (*INTEGRATED, "belt_travel", "normal_force")


def _compile_formulas() -> Callable[..., tuple[Any, ...]]:
    """One function (QUANTITIES...) -> the SAMPLE_FIELDS' values, compiled from their formulas."""
    for f in SAMPLE_FIELDS:
        names = set(compile(f.formula, f"<{f.name}>", "eval").co_names)
        if not names <= set(QUANTITIES):
            raise ImportError(
                f"core.schema.SAMPLE_FIELDS: the formula of {f.name!r} ({f.formula!r}) uses "
                f"{sorted(names - set(QUANTITIES))}; valid names: {list(QUANTITIES)}"
            )
    body = ", ".join(f"({f.formula})" for f in SAMPLE_FIELDS)
    source = f"def derive({', '.join(QUANTITIES)}):\n    return ({body},)\n"
    namespace: dict[str, Any] = {"__builtins__": {}}
    exec(compile(source, "<core.schema.SAMPLE_FIELDS>", "exec"), namespace)
    derive: Callable[..., tuple[Any, ...]] = namespace["derive"]
    return derive


#: derive(*QUANTITIES) -> the values of SAMPLE_FIELDS, for floats (one sample) or arrays (a block).
derive = _compile_formulas()


def derive_columns(shape: tuple[int, ...], *quantities: Any) -> dict[str, np.ndarray]:
    """The SAMPLE_FIELDS of consecutive samples as arrays of `shape` (a constant is broadcast)."""
    values = derive(*quantities)
    return {
        name: v if isinstance(v, np.ndarray) and v.shape == shape else np.full(shape, v, dtype=float)
        for name, v in zip(BLOCK_FIELDS, values, strict=True)
    }


def check_state_fields(names: tuple[str, ...]) -> None:
    """RuntimeError unless RigState's fields after its header are sample_index, segment, BLOCK_FIELDS."""
    if names != ("sample_index", "segment", *BLOCK_FIELDS):
        raise RuntimeError(
            f"RigState's fields {names} are not sample_index, segment and core.schema.SAMPLE_FIELDS "
            f"{BLOCK_FIELDS}: rebuild lubrig_interfaces (make setup)"
        )


def trajectory_columns(
    traj: Trajectory, belt_travel: np.ndarray, normal_force: float
) -> dict[str, np.ndarray]:
    """The SAMPLE_FIELDS of the samples of `traj`, with their belt travel, for a run's normal force (N)."""
    return derive_columns(
        traj.time.shape, *(getattr(traj, name) for name in INTEGRATED), belt_travel, normal_force
    )


class PlantSample(NamedTuple):
    """One output sample: what the plant publishes (SI units). A tuple: cheap to make per sample.

    `values` holds the SAMPLE_FIELDS in order; each is also an attribute by its name
    (`sample.displacement`).
    """

    time: float  # s, rig time
    values: tuple[float, ...]  # BLOCK_FIELDS
    sample_index: int = 0  # samples emitted in this segment before this one
    segment: int = 0  # 0 at start, +1 per reset

    def __getattr__(self, name: str) -> float:
        try:
            return self.values[_FIELD_INDEX[name]]
        except KeyError:
            raise AttributeError(f"PlantSample has no field {name!r}; fields: {BLOCK_FIELDS}") from None


@dataclass(frozen=True)
class PlantBlock:
    """Consecutive output samples of one segment (SI units): one RigStateBlock.

    Sample i has rig time `time[i]` and sample index first_sample_index + i; `columns` holds one
    array per SAMPLE_FIELDS entry, each also an attribute by its name (`block.displacement`).
    Realtime blocks also carry each sample's `lateness` (s after its due time) and `skipped`, the
    sample indices just before first_sample_index that the plant skipped when it fell behind (a
    declared gap).
    """

    segment: int
    first_sample_index: int
    sample_period: float  # s
    time: np.ndarray  # s
    columns: Mapping[str, np.ndarray]  # BLOCK_FIELDS
    lateness: np.ndarray = field(default_factory=lambda: _EMPTY)  # s (realtime only)
    skipped: int = 0

    def __getattr__(self, name: str) -> np.ndarray:
        columns = self.__dict__.get("columns")
        if columns is None or name not in columns:
            raise AttributeError(f"PlantBlock has no field {name!r}; fields: {BLOCK_FIELDS}")
        column: np.ndarray = columns[name]
        return column

    def __len__(self) -> int:
        return int(self.time.size)

    def samples(self) -> list[PlantSample]:
        """The block as PlantSample tuples."""
        rows = zip(*(self.columns[name].tolist() for name in BLOCK_FIELDS), strict=True)
        return [
            PlantSample(t, tuple(row), self.first_sample_index + i, self.segment)
            for i, (t, row) in enumerate(zip(self.time.tolist(), rows, strict=True))
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
        data = self._data
        data[0, self.count] = s.time
        data[1:-1, self.count] = s.values
        data[-1, self.count] = lateness
        self.count += 1
        return self.flush() if self.count >= self.length else None

    def skip(self, count: int) -> None:
        """`count` sample indices are skipped before the next buffered sample (flush first)."""
        self.skipped += count

    def flush(self) -> PlantBlock | None:
        """The buffered samples as a block (None when empty); the buffer starts over."""
        if self.count == 0:
            return None
        data = self._data[:, : self.count].copy()
        block = PlantBlock(
            segment=self.segment,
            first_sample_index=self.first_index,
            sample_period=self.sample_period,
            time=data[0],
            columns=dict(zip(BLOCK_FIELDS, data[1:-1], strict=True)),
            lateness=data[-1],
            skipped=self.skipped,
        )
        self.count, self.skipped = 0, 0
        return block

    def clear(self) -> None:
        """Drop what is buffered (a reset)."""
        self.count, self.skipped = 0, 0
