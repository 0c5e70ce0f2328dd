"""A bag's sample streams as tables (CSV or Parquet): one row per sample, one file per stream.

What `lubrig bag export` writes (docs/data.md). Every RigStateBlock and BandVelocityBlock is
flattened into its samples, every RigState is one row; each row carries the sample's index and
segment, its rig time (the block's stamp + i · sample_period) and its log time (the message's +
i · sample_period), then the sample's fields with their units in the column names
(core.schema.SAMPLE_UNITS via unit_column: displacement_m, velocity_m_s, ...; the Parquet
schema also states each column's unit as field metadata). A RigStateBlock adds each sample's
lateness (s; missing, an empty CSV cell or a Parquet null, outside the realtime modes) and
`skipped`, the samples the plant declared skipped just before the block, on its first sample.

One file per stream, not one table: the streams of a bag have their own rates, sample indices
and columns (a band block stream is one sample behind the state stream), so joining them would
invent rows; each file stands alone and joins on (segment, sample_index) where the user wants it.

The bag is read once, message by message (lubrig_ros.bag.stream), and rows go out in batches of
BATCH_ROWS through pyarrow's writers: memory stays bounded whatever the length of the run.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from lubrig_ros.app.fileio import write_text_atomic
from lubrig_ros.bag.errors import BagError
from lubrig_ros.bag.reader import (
    BLOCK_FIELDS,
    RIG_STATE,
    RIG_STATE_BLOCK,
    RIG_STATE_FIELDS,
    _block_samples,
    stream_typestore,
)
from lubrig_ros.bag.stream import OpenedBag
from lubrig_ros.core.schema import SAMPLE_UNITS, unit_column

FORMATS = ("csv", "parquet")
#: Message types with one row per sample.
EXPORTABLE_TYPES: tuple[str, ...] = (*BLOCK_FIELDS, RIG_STATE)
#: Rows gathered before a batch is written.
BATCH_ROWS = 1 << 16
CONFIG_FILE = "config.yaml"
#: The columns every table starts with: (name, unit, integer).
INDEX_COLUMNS: tuple[tuple[str, str, bool], ...] = (
    ("sample_index", "1", True),
    ("segment", "1", True),
    ("rig_time", "s", False),
    ("log_time", "s", False),
)


@dataclass(frozen=True)
class Column:
    """One column of an exported table: the sample field it holds, its header and unit."""

    source: str  # key of the decoded sample arrays (reader._block_samples)
    name: str  # header, with the unit (unit_column)
    unit: str
    integer: bool = False
    missing_if_nan: bool = False  # NaN means "none" here (lateness of a sample without timing): null


def columns_of(msgtype: str) -> tuple[Column, ...]:
    """The columns of the table of a stream of msgtype (one of EXPORTABLE_TYPES)."""
    index = [Column(n, unit_column(n, u), u, i) for n, u, i in INDEX_COLUMNS]
    fields = RIG_STATE_FIELDS if msgtype == RIG_STATE else BLOCK_FIELDS[msgtype]
    cols = index + [Column(f, unit_column(f, SAMPLE_UNITS[f]), SAMPLE_UNITS[f]) for f in fields]
    if msgtype == RIG_STATE_BLOCK:
        unit = SAMPLE_UNITS["lateness"]
        cols += [Column("lateness", unit_column("lateness", unit), unit, missing_if_nan=True)]
        cols += [Column("skipped", "skipped", "1", True)]
    return tuple(cols)


def file_name(topic: str, fmt: str) -> str:
    """The file of a topic's table: /lubrig/state_block -> lubrig.state_block.csv."""
    return topic.strip("/").replace("/", ".") + "." + fmt


@dataclass
class ExportedStream:
    """One written table."""

    topic: str
    msgtype: str
    path: Path
    rows: int = 0


@dataclass
class ExportReport:
    """What an export wrote."""

    out: Path
    streams: dict[str, ExportedStream] = field(default_factory=dict)
    config: Path | None = None

    @property
    def rows(self) -> int:
        """Rows written over every table."""
        return sum(s.rows for s in self.streams.values())


def exportable_topics(bag: OpenedBag) -> list[str]:
    """The bag's topics that have a per-sample table (EXPORTABLE_TYPES), in channel order."""
    return [t for t, m in bag.types.items() if m in EXPORTABLE_TYPES]


def select_topics(bag: OpenedBag, topics: Iterable[str] | None) -> list[str]:
    """The topics to export (None: every sample stream with messages); BagError naming a bad one.

    A topic the bag does not hold, or one of a type without a per-sample table, is refused.
    """
    valid = exportable_topics(bag)
    if topics is None:  # every sample stream that holds a message
        held = [t for t in valid if bag.counts.get(t, 0)]
        if not held:
            listed = ", ".join(f"{t} ({m})" for t, m in bag.types.items()) or "none"
            raise BagError(f"bag {str(bag.path)!r} holds no sample stream to export; its topics: {listed}")
        return held
    chosen = list(dict.fromkeys(topics))
    for topic in chosen:
        if topic not in valid:
            what = (
                f"holds no topic {topic!r}"
                if topic not in bag.types
                else f"topic {topic!r} ({bag.types[topic]}) has no per-sample table"
            )
            raise BagError(f"bag {str(bag.path)!r} {what}; exportable: {', '.join(valid) or 'none'}")
    return chosen


class _Table:
    """One output table written in batches through pyarrow (CSV or Parquet)."""

    def __init__(self, path: Path, fmt: str, columns: tuple[Column, ...], meta: dict[str, str]) -> None:
        import pyarrow as pa

        self.pa = pa
        self.path, self.columns = path, columns
        self.partial = path.with_name(path.name + ".partial")
        fields = [
            pa.field(c.name, pa.int64() if c.integer else pa.float64(), metadata={"unit": c.unit})
            for c in columns
        ]
        self.schema = pa.schema(fields, metadata=meta)
        self.parts: list[dict[str, np.ndarray]] = []
        self.pending = 0
        self.rows = 0
        self.writer: Any
        self.file: Any = None
        if fmt == "csv":  # the header unquoted (pyarrow quotes it), the rows by pyarrow
            from pyarrow import csv

            self.file = open(self.partial, "wb")  # noqa: SIM115 (closed in close())
            self.file.write((",".join(c.name for c in columns) + "\n").encode())
            self.writer = csv.CSVWriter(
                self.file, self.schema, write_options=csv.WriteOptions(include_header=False)
            )
        else:
            from pyarrow import parquet

            self.writer = parquet.ParquetWriter(str(self.partial), self.schema, compression="zstd")

    def add(self, samples: dict[str, np.ndarray]) -> None:
        n = len(samples["sample_index"])
        if n:
            self.parts.append(samples)
            self.pending += n
            if self.pending >= BATCH_ROWS:
                self.flush()

    def flush(self) -> None:
        if not self.parts:
            return
        arrays = [
            self.pa.array(
                np.concatenate([p[c.source] for p in self.parts]).astype(np.int64 if c.integer else float),
                from_pandas=c.missing_if_nan,
            )
            for c in self.columns
        ]
        self.writer.write_table(self.pa.Table.from_arrays(arrays, schema=self.schema))
        self.rows += self.pending
        self.parts, self.pending = [], 0

    def close(self, keep: bool) -> None:
        if keep:
            self.flush()
        self.writer.close()
        if self.file is not None:
            self.file.close()
        if keep:
            os.replace(self.partial, self.path)
        else:
            self.partial.unlink(missing_ok=True)


def _samples(msgtype: str, msg: Any, log_ns: int) -> dict[str, np.ndarray]:
    """The per-sample arrays of one decoded message, with rig_time and log_time (s).

    Times are taken from whole nanoseconds (stamp_ns / 1e9, not sec + nanosec · 1e-9), so a
    wall-clock stamp keeps every digit a double can hold.
    """
    stamp_s = (int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)) / 1e9
    if msgtype == RIG_STATE:
        cols = {name: np.array([float(getattr(msg, name))]) for name in RIG_STATE_FIELDS}
        cols["sample_index"] = np.array([int(msg.sample_index)], dtype=np.int64)
        cols["segment"] = np.array([int(msg.segment)], dtype=np.int64)
        cols["rig_time"] = np.array([stamp_s])
        cols["log_time"] = np.array([log_ns / 1e9])
        return cols
    cols = _block_samples(msgtype, msg)
    offsets = np.arange(len(cols["sample_index"])) * float(msg.sample_period)
    cols["rig_time"] = stamp_s + offsets
    cols["log_time"] = log_ns / 1e9 + offsets
    return cols


def _window(cols: dict[str, np.ndarray], start_s: float | None, end_s: float | None) -> dict[str, np.ndarray]:
    """The samples whose log time is within [start_s, end_s] (None: open)."""
    t = cols["log_time"]
    keep = np.ones(t.size, dtype=bool)
    if start_s is not None:
        keep &= t >= start_s
    if end_s is not None:
        keep &= t <= end_s
    return cols if keep.all() else {k: v[keep] for k, v in cols.items()}


def export_bag(
    bag: OpenedBag,
    out: Path,
    fmt: str,
    topics: Iterable[str] | None = None,
    start_ns: int | None = None,
    end_ns: int | None = None,
) -> ExportReport:
    """Write one table per selected stream into the directory `out` (created), and config.yaml.

    start_ns / end_ns: log-time bounds (absolute, ns; a sample is kept when its log time is
    within them). Tables are written as NAME.partial and renamed when complete; on a BagError
    (a chunk found damaged on the way) the partial files (and `out`, if created here and left
    empty) are removed and the error raised.
    """
    if fmt not in FORMATS:
        raise BagError(f"--format {fmt!r} is invalid; valid: {', '.join(FORMATS)}")
    chosen = select_topics(bag, topics)
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    report = ExportReport(out)
    tables: dict[str, _Table] = {}
    for topic in chosen:
        msgtype = bag.types[topic]
        path = out / file_name(topic, fmt)
        meta = {"lubrig_ros.topic": topic, "lubrig_ros.msgtype": msgtype, "lubrig_ros.bag": str(bag.path)}
        tables[topic] = _Table(path, fmt, columns_of(msgtype), meta)
        report.streams[topic] = ExportedStream(topic, msgtype, path)
    start_s = None if start_ns is None else start_ns / 1e9
    end_s = None if end_ns is None else end_ns / 1e9
    ok = False
    try:
        for stream, t, data in bag.messages(chosen):
            try:
                msg = stream_typestore(stream).deserialize_cdr(data, stream.msgtype)
                cols = _samples(stream.msgtype, msg, t)
            except Exception as exc:  # a stream that does not decode is named, never skipped
                raise BagError(
                    f"bag {str(bag.path)!r}: topic {stream.topic} ({stream.msgtype}): the message at log "
                    f"time {t} ns does not decode ({type(exc).__name__}); the stream cannot be exported"
                ) from None
            tables[stream.topic].add(_window(cols, start_s, end_s))
        ok = True
    finally:
        for topic, table in tables.items():
            table.close(keep=ok)
            report.streams[topic].rows = table.rows
        if not ok and created and not any(out.iterdir()):
            out.rmdir()
    if bag.run_config is not None:
        report.config = out / CONFIG_FILE
        write_text_atomic(report.config, bag.run_config)
    return report
