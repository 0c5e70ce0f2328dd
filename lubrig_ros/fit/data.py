"""A measured record to fit: band velocity plus displacement and/or friction coefficient.

Two sources, both SI units:

* a CSV with a header naming the columns ``time, band_velocity, displacement[,
  friction_coefficient]`` (s, m/s, m, 1); the unit-suffixed names of timeseries.csv and of `lubrig
  bag export` (``time_s``, ``band_velocity_m_s``, ``displacement_m``: core.schema.unit_column) are
  accepted too, so a run directory's timeseries.csv fits as it is;
* a bag recorded by `lubrig rig` (or any bag with the rig's ``<ns>/state_block`` stream): the
  displacement and friction coefficient from the recorded state stream, the band velocity from the
  recorded band stream ``<ns>/band_velocity_block`` (matched by rig time; the initial sample,
  which belt_drive does not send, from the state stream's own band value), read with the one bag
  reader (bag.reader.Bag). A bag of a rig_in_loop plant in shadow mode (a ``<ns>/shadow_block``
  stream with pairs) is a real rig's record instead: the measured displacement is the pairs'
  ``measured_displacement`` and the band velocity the state stream's ``band_velocity`` of the same
  sample index (the value the plant integrated, which is the rig's band value the pair belongs to;
  app/plant/session.py, "Shadow"), over the longest run of consecutive paired samples of the first
  segment; the state stream's displacement and μ are the model's and are not used.

Samples must be uniform in time (the integrator's output grid): a CSV whose time steps vary by
more than 1e-6 of a step is refused, naming the first bad row.
"""

from __future__ import annotations

import csv
import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lubrig_ros.core.errors import InputError

from ..bag.errors import BagError
from ..bag.reader import Bag, TopicArrays
from ..core.schema import SAMPLE_UNITS, unit_column

#: The measured streams a fit compares with the model (at least one must be present).
MEASURED: tuple[str, ...] = ("displacement", "friction_coefficient")
#: The streams a record may hold, in CSV column order.
COLUMNS: tuple[str, ...] = ("time", "band_velocity", *MEASURED)
#: Samples a record needs at the least (two samples per shooting segment and some to spare).
MIN_SAMPLES = 20


@dataclass(frozen=True)
class MeasuredData:
    """A uniformly sampled record: time (s) from 0, band velocity (m/s), measured streams."""

    time: np.ndarray
    band_velocity: np.ndarray
    displacement: np.ndarray | None
    friction_coefficient: np.ndarray | None
    source: str

    @property
    def sample_rate(self) -> float:
        """Samples per second (Hz), from the time column."""
        return float((self.time.size - 1) / (self.time[-1] - self.time[0]))

    @property
    def streams(self) -> dict[str, np.ndarray]:
        """The measured streams present, by name."""
        held = {"displacement": self.displacement, "friction_coefficient": self.friction_coefficient}
        return {name: values for name, values in held.items() if values is not None}

    def fingerprint(self) -> str:
        """SHA-256 of the record's arrays (float64, in COLUMNS order; absent streams skipped)."""
        digest = hashlib.sha256()
        for name in COLUMNS:
            values = getattr(self, name)
            if values is not None:
                digest.update(name.encode())
                digest.update(np.ascontiguousarray(values, dtype="<f8").tobytes())
        return digest.hexdigest()


def _accepted(name: str) -> tuple[str, ...]:
    """The header spellings of a column: its name and its name with the unit (schema.unit_column)."""
    return (name, unit_column(name, SAMPLE_UNITS[name]))


def checked(
    time: np.ndarray,
    band: np.ndarray,
    displacement: np.ndarray | None,
    friction: np.ndarray | None,
    source: str,
) -> MeasuredData:
    """A MeasuredData after the checks every source shares; InputError naming the problem."""
    if displacement is None and friction is None:
        raise InputError(f"{source}: no measured stream; expected displacement and/or friction_coefficient")
    if time.size < MIN_SAMPLES:
        raise InputError(f"{source}: {time.size} samples; expected at least {MIN_SAMPLES}")
    named = {
        "time": time,
        "band_velocity": band,
        "displacement": displacement,
        "friction_coefficient": friction,
    }
    for name, values in named.items():
        if values is None:
            continue
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise InputError(
                f"{source}: {name} {values[bad[0]]!r} in sample {bad[0]} is not finite; "
                "expected finite SI values"
            )
    step = np.diff(time)
    period = (time[-1] - time[0]) / (time.size - 1)
    uneven = np.flatnonzero(np.abs(step - period) > 1e-6 * period) if period > 0 else np.arange(1)
    if period <= 0 or uneven.size:
        at = int(uneven[0]) if uneven.size else 0
        raise InputError(
            f"{source}: time step {step[at]!r} s after sample {at} differs from the mean {period!r} s; "
            "expected uniformly sampled, increasing time"
        )
    return MeasuredData(time - time[0], band, displacement, friction, source)


def load_csv(path: Path) -> MeasuredData:
    """A record from a CSV (header with column names; see the module's docstring)."""
    source = f"CSV {str(path)!r}"
    try:
        with path.open(newline="") as handle:
            rows = list(csv.reader(handle))
    except OSError as exc:
        raise InputError(f"{source} cannot be read: {exc.strerror}") from None
    except (UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"{source} is not a text CSV: {exc}") from None
    if not rows:
        raise InputError(f"{source} is empty; expected a header {', '.join(COLUMNS)} and rows")
    header = [h.strip() for h in rows[0]]
    where: dict[str, int] = {}
    for name in COLUMNS:
        for spelling in _accepted(name):
            if spelling in header:
                where[name] = header.index(spelling)
    for name in ("time", "band_velocity"):
        if name not in where:
            raise InputError(
                f"{source} has no {name} column (header {header}); expected columns {', '.join(COLUMNS)} "
                "(SI units; time_s, band_velocity_m_s, displacement_m also accepted)"
            )
    table = np.array([_numbers(row, where, number, source) for number, row in enumerate(rows[1:], 2) if row])
    if table.size == 0:
        raise InputError(f"{source} has no data rows")
    column = {name: table[:, k] for k, name in enumerate(where)}
    return checked(
        column["time"],
        column["band_velocity"],
        column.get("displacement"),
        column.get("friction_coefficient"),
        source,
    )


def _numbers(row: list[str], where: dict[str, int], number: int, source: str) -> list[float]:
    """The row's values of the columns in `where`; InputError naming the row and the bad value."""
    values = []
    for name, index in where.items():
        text = row[index] if index < len(row) else ""
        try:
            values.append(float(text))
        except ValueError:
            raise InputError(
                f"{source} row {number}: {name} {text!r} is not a number; expected numbers in SI units"
            ) from None
    return values


def _kept(topic: str) -> bool:
    return topic.endswith(("/state_block", "/band_velocity_block", "/shadow_block"))


def load_bag(path: Path) -> MeasuredData:
    """A record from a bag: state_block's displacement and μ, band_velocity_block's band velocity."""
    source = f"bag {str(path)!r}"
    try:
        bag = Bag(path, keep=_kept)
        bag.refuse_damaged("fit")
        topics = {t.name: t for t in bag.summary().topics if t.count}
        states = sorted(t for t in topics if t.endswith("/state_block"))
        if len(states) != 1:
            raise InputError(
                f"{source} holds {len(states)} state_block streams ({states}); expected one rig's"
            )
        state_topic = states[0]
        band_topic = state_topic[: -len("state_block")] + "band_velocity_block"
        shadow_topic = state_topic[: -len("state_block")] + "shadow_block"
        if shadow_topic in topics:
            arrays = bag.arrays([state_topic, shadow_topic])
            return _shadow_record(arrays[state_topic], arrays[shadow_topic], source)
        arrays = bag.arrays([state_topic, *([band_topic] if band_topic in topics else [])])
    except BagError as exc:
        raise InputError(str(exc)) from None
    state = arrays[state_topic]
    segment = np.asarray(state["segment"], np.int64)
    first = segment == segment.min()  # the run's first segment (a reset starts another)
    index = np.asarray(state["sample_index"], np.int64)[first]
    order = np.argsort(index, kind="stable")
    index, unique = np.unique(index[order], return_index=True)
    pick = lambda name: np.asarray(state[name], float)[first][order][unique]  # noqa: E731
    band = pick("band_velocity")
    if band_topic in arrays:
        band = _recorded_band(arrays[band_topic], int(segment.min()), pick("stamp"), band)
    gaps = np.flatnonzero(np.diff(index) != 1)
    if gaps.size:
        raise InputError(
            f"{source}: the state stream has a gap after sample {int(index[gaps[0]])}; expected every sample"
        )
    stamps = pick("stamp")
    period = float(np.median(np.diff(stamps))) if stamps.size > 1 else 0.0
    if not period > 0.0:
        raise InputError(
            f"{source}: the state stream's stamps do not advance; expected one sample period apart"
        )
    time = (index - index[0]) * (round(period * 1e9) / 1e9)  # stamps are on the nanosecond grid
    return checked(time, band, pick("displacement"), pick("friction_coefficient"), source)


def _shadow_record(state: TopicArrays, shadow: TopicArrays, source: str) -> MeasuredData:
    """Shadow mode: the pairs' measured displacement over the state stream's band (module docstring)."""
    segment = int(np.asarray(shadow["segment"], np.int64).min())
    mine = np.asarray(shadow["segment"], np.int64) == segment
    index, unique = np.unique(np.asarray(shadow["sample_index"], np.int64)[mine], return_index=True)
    measured = np.asarray(shadow["measured_displacement"], float)[mine][unique]
    breaks = np.flatnonzero(np.diff(index) != 1) + 1
    runs = np.split(np.arange(index.size), breaks)
    longest = max(runs, key=len)
    index, measured = index[longest], measured[longest]
    in_segment = np.asarray(state["segment"], np.int64) == segment
    state_index = np.asarray(state["sample_index"], np.int64)[in_segment]
    state_band = np.asarray(state["band_velocity"], float)[in_segment]
    band_of = dict(zip(state_index.tolist(), state_band.tolist(), strict=True))
    missing = [k for k in index.tolist() if k not in band_of]
    if missing:
        raise InputError(
            f"{source}: the state stream has no sample {missing[0]} of segment {segment}, which the "
            "shadow stream pairs; expected every paired sample recorded"
        )
    band = np.array([band_of[k] for k in index.tolist()])
    stamps = np.asarray(state["stamp"], float)[in_segment]
    period = float(np.median(np.diff(np.sort(stamps)))) if stamps.size > 1 else 0.0
    if not period > 0.0:
        raise InputError(
            f"{source}: the state stream's stamps do not advance; expected one sample period apart"
        )
    time = (index - index[0]) * (round(period * 1e9) / 1e9)
    return checked(time, band, measured, None, f"{source} (shadow: measured displacement)")


def _recorded_band(
    recorded: TopicArrays, segment: int, stamps: np.ndarray, fallback: np.ndarray
) -> np.ndarray:
    """The band stream's value at every state sample, matched by rig time (stamp, to the ns).

    A band block's sample index counts band samples (its first is the band at t = 1 dt), so the
    rig time is the common key. A state sample without a band sample (t = 0: belt_drive sends the
    band after the initial state) keeps the state stream's own band value.
    """
    same = np.asarray(recorded["segment"], np.int64) == segment
    keys = np.round(np.asarray(recorded["stamp"], float)[same] * 1e9).astype(np.int64).tolist()
    lookup = dict(zip(keys, np.asarray(recorded["band_velocity"], float)[same].tolist(), strict=True))
    wanted = np.round(stamps * 1e9).astype(np.int64).tolist()
    return np.array([lookup.get(k, float(b)) for k, b in zip(wanted, fallback, strict=True)])


def load_data(path: str | Path) -> MeasuredData:
    """A record from a bag directory (or .mcap file) or a CSV file."""
    path = Path(path)
    if path.is_dir() or path.suffix == ".mcap":
        return load_bag(path)
    if not path.exists():
        raise InputError(f"DATA {str(path)!r} does not exist; expected a CSV file or a bag directory")
    return load_csv(path)
