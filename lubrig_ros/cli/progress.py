"""Progress of long commands (`lubrig rig`, `lubrig paper`) on a terminal, silence elsewhere.

One status line, rewritten in place (carriage return): rig time done of the total, the rate in rig seconds
per wall second, and the time left at that rate. It is written only when the stream is a terminal
(isatty), so logs, pipes and CI output stay exactly as before; it is throttled to a few updates
per second and ends with a newline (or is cleared) by finish().
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

#: Least wall time between two status lines, s.
INTERVAL_S = 0.25


def _clock(seconds: float) -> str:
    seconds = max(0.0, seconds)
    if seconds < 60:
        return f"{seconds:.0f} s"
    minutes, rest = divmod(round(seconds), 60)
    return f"{minutes} min {rest:02d} s"


class Progress:
    """Status line of rig time done out of `total_s` (rig seconds)."""

    def __init__(
        self,
        label: str,
        total_s: float,
        stream: TextIO | None = None,
        enabled: bool | None = None,
        interval_s: float = INTERVAL_S,
    ) -> None:
        self.label = label
        self.total_s = float(total_s)
        self.stream = stream if stream is not None else sys.stderr
        if enabled is None:
            isatty = getattr(self.stream, "isatty", None)
            enabled = bool(isatty and isatty())
        self.enabled = enabled
        self.interval_s = interval_s
        self.started = time.monotonic()
        self._last = -float("inf")
        self._pending: tuple[float, str] | None = None
        self._width = 0

    def line(self, done_s: float, detail: str = "") -> str:
        """The status text for `done_s` rig seconds done (what update writes)."""
        wall = time.monotonic() - self.started
        rate = done_s / wall if wall > 0 else 0.0
        text = f"{self.label}: rig time {done_s:.1f} / {self.total_s:g} s"
        if rate > 0:
            left = (self.total_s - done_s) / rate
            text += f", {rate:.2g}× real time, {_clock(left)} left"
        return text + (f" — {detail}" if detail else "")

    def update(self, done_s: float, detail: str = "", force: bool = False) -> None:
        """Rewrite the status line (on a terminal only, at most every interval_s unless force)."""
        if not self.enabled:
            return
        now = time.monotonic()
        if not force and now - self._last < self.interval_s:
            self._pending = (done_s, detail)  # shown by the next update or by finish()
            return
        self._last, self._pending = now, None
        text = self.line(done_s, detail)
        pad = max(0, self._width - len(text))
        self._width = len(text)
        self.stream.write("\r" + text + " " * pad)
        self.stream.flush()

    def finish(self) -> None:
        """Show the last state if it was throttled, then end the line (a newline)."""
        if self.enabled and self._pending is not None:
            self.update(*self._pending, force=True)
        if self.enabled and self._width:
            self.stream.write("\n")
            self.stream.flush()
            self._width = 0
