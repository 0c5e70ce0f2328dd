"""The rig's realtime timing as recorded (no ROS): lateness statistics and declared gaps.

In the realtime modes the plant computes sample k of a segment at its due time, the segment's
start (wall clock) + k · sample_period, or later: a RigStateBlock carries per sample its
**lateness** (s, ≥ 0), how long after the due time the sample was computed, i.e. how far rig
time lagged behind wall time there. When the lag exceeds the plant's `max_lag` bound the plant
skips samples to catch up and says so in the next block's `skipped`: a **declared gap** (the
samples were integrated but never published), not a lost message.

`RigTiming` holds what one segment of a recording says about this; its statistics are the
report's "timing" section and the timing figure (figures/timing.py), so both state the same
numbers. Percentiles are sample values (inverted CDF: p99 is the smallest recorded lateness that
at least 99 % of the samples do not exceed), never interpolated between samples.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..interface.contract import DEFAULT_MAX_LAG

__all__ = ["DEFAULT_MAX_LAG", "DeclaredGap", "RigTiming", "rig_timing"]


@dataclass(frozen=True)
class DeclaredGap:
    """Samples [first_index, first_index + count) of a segment that the plant skipped."""

    segment: int
    first_index: int
    count: int
    rig_time_s: float  # rig time of the first skipped sample (first_index · sample_period)

    def as_dict(self) -> dict[str, Any]:
        """The gap for summary.json."""
        return {
            "segment": self.segment,
            "first_index": self.first_index,
            "count": self.count,
            "rig_time_s": self.rig_time_s,
        }


@dataclass(frozen=True)
class RigTiming:
    """Lateness of every recorded sample of one segment and the gaps the plant declared in it."""

    segment: int
    sample_period: float  # s: the deadline of a sample is one period after its due time
    sample_index: np.ndarray  # int64, ascending, the samples that carry a lateness
    lateness: np.ndarray  # s, per sample (same length)
    gaps: tuple[DeclaredGap, ...]
    #: s, the plant's bound on the lag before it skips (the plant parameter's default unless the
    #: recording states it)
    max_lag: float = DEFAULT_MAX_LAG
    max_lag_stated: bool = False  # True when the recording states max_lag (else the default)

    @property
    def rig_time(self) -> np.ndarray:
        """Rig time of each sample (s): sample_index · sample_period (due time − segment start)."""
        return self.sample_index * self.sample_period

    @property
    def samples(self) -> int:
        """Samples with a recorded lateness."""
        return int(self.lateness.size)

    def quantile(self, q: float) -> float:
        """The q-quantile (0..1) of the lateness, a recorded value (inverted CDF), s."""
        return float(np.quantile(self.lateness, q, method="inverted_cdf"))

    @property
    def late_samples(self) -> int:
        """Samples computed more than one sample period after their due time."""
        return int(np.count_nonzero(self.lateness > self.sample_period))

    @property
    def skipped(self) -> int:
        """Samples in declared gaps."""
        return sum(g.count for g in self.gaps)

    def summary(self) -> dict[str, Any]:
        """The report's "timing" section (summary.json): seconds, shares in 0..1."""
        return {
            "segment": self.segment,
            "samples": self.samples,
            "sample_period_s": self.sample_period,
            "lateness_p50_s": self.quantile(0.50),
            "lateness_p99_s": self.quantile(0.99),
            "lateness_max_s": float(self.lateness.max()),
            "late_samples": self.late_samples,
            "late_share": self.late_samples / self.samples,
            "skipped_samples": self.skipped,
            "gaps": [g.as_dict() for g in self.gaps],
            "max_lag_s": self.max_lag,
            "max_lag_source": "recording" if self.max_lag_stated else "default",
        }


def rig_timing(
    segment: int,
    sample_period: float,
    sample_index: np.ndarray,
    lateness: np.ndarray,
    skipped: np.ndarray,
    max_lag: float | None = None,
) -> RigTiming | None:
    """The RigTiming of one segment's samples (each once, in index order), None without lateness.

    lateness: s per sample, NaN where none was recorded (sim samples, bags recorded before the
    field existed); skipped: per sample, the samples the plant skipped just before it (its
    block's declaration, on the block's first sample; 0 elsewhere). max_lag: the bound the
    recording states, if any.
    """
    index = np.asarray(sample_index, dtype=np.int64)
    late = np.asarray(lateness, dtype=float)
    skip = np.asarray(skipped, dtype=np.int64)
    timed = np.isfinite(late)
    if not timed.any():
        return None
    gaps = tuple(
        DeclaredGap(segment, int(k - n), int(n), float((k - n) * sample_period))
        for k, n in zip(index[skip > 0].tolist(), skip[skip > 0].tolist(), strict=True)
    )
    return RigTiming(
        segment=segment,
        sample_period=float(sample_period),
        sample_index=index[timed],
        lateness=late[timed],
        gaps=gaps,
        max_lag=DEFAULT_MAX_LAG if max_lag is None else float(max_lag),
        max_lag_stated=max_lag is not None,
    )
