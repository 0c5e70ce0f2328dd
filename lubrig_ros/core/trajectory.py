"""The sampled rig response: what the integrator returns and what run folders and bags hold.

Apart from the integrator (core.integrator re-exports both names) so that readers of a run
(the run directory, the report) need numpy only, not the compiled kernels.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

__all__ = ["Trajectory", "TrajectorySample", "concatenate"]


@dataclass
class Trajectory:
    """Uniformly sampled rig response (SI units; relative velocity per the run's convention)."""

    time: np.ndarray  # s
    displacement: np.ndarray  # x, m
    velocity: np.ndarray  # ẋ, m/s
    friction_coefficient: np.ndarray  # μ(v_rel)
    band_velocity: np.ndarray  # m/s
    relative_velocity: np.ndarray  # v_band − γ ẋ, m/s

    COLUMNS = (
        ("time", "time_s"),
        ("displacement", "displacement_m"),
        ("velocity", "velocity_m_s"),
        ("friction_coefficient", "friction_coefficient"),
        ("band_velocity", "band_velocity_m_s"),
        ("relative_velocity", "relative_velocity_m_s"),
    )

    def __len__(self) -> int:
        return int(self.time.size)

    def sample(self, i: int) -> TrajectorySample:
        """Sample i as floats."""
        return TrajectorySample(*(float(getattr(self, name)[i]) for name, _ in self.COLUMNS))

    def as_columns(self) -> dict[str, np.ndarray]:
        """Arrays keyed by their CSV column names (with units)."""
        return {column: getattr(self, name) for name, column in self.COLUMNS}


class TrajectorySample(NamedTuple):
    """One sample of a Trajectory as floats (its columns, in order): what a real-time tick makes."""

    time: float  # s
    displacement: float  # x, m
    velocity: float  # ẋ, m/s
    friction_coefficient: float  # μ(v_rel)
    band_velocity: float  # m/s
    relative_velocity: float  # v_band − γ ẋ, m/s


if TrajectorySample._fields != tuple(name for name, _ in Trajectory.COLUMNS):
    raise ImportError("TrajectorySample's fields must be Trajectory.COLUMNS' names, in order")


def concatenate(parts: list[Trajectory]) -> Trajectory:
    """Join consecutive trajectories."""
    return Trajectory(
        **{name: np.concatenate([getattr(p, name) for p in parts]) for name, _ in Trajectory.COLUMNS}
    )
