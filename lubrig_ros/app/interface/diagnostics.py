"""Diagnostics as plain data: what a node reports on /diagnostics, without ROS message types."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

Level = Literal["ok", "warn", "error"]


@dataclass(frozen=True)
class Status:
    """One diagnostic status: name, level, a one-line message and (key, value) text pairs.

    The node adapter turns it into a diagnostic_msgs/DiagnosticStatus (level OK/WARN/ERROR).
    """

    name: str
    hardware_id: str
    level: Level
    message: str
    values: tuple[tuple[str, str], ...] = field(default=())

    def as_dict(self) -> dict[str, str]:
        """The values as a mapping (plus '_message' and '_level'), handy for checks."""
        return dict(self.values) | {"_message": self.message, "_level": self.level}
