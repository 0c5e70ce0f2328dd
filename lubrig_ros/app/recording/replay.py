"""Playback of a recorded bag without ROS: the replay node's state machine.

`ReplaySession` holds the messages to replay (topic, log time, bytes, in log-time order) and
decides, given the time now (any monotonic clock, seconds), what the player does next
(`next`): publish a message, wait, or stop. The player's controls change that state:

- **paused**: nothing is due; `resume` plays on from the bag time it was paused at.
- **rate**: the time scale (2 = twice as fast); changing it keeps the bag time reached so far.
- **step** (`step`, paused only): the next message at once, one message (a sim bag's
  RigStateBlock is one block of samples).
- **seek**: the next message is the first one at or after the bag time sought; playing goes on
  from there with the time scale, paused stays paused.
- **until**: the last message played is the last one at or before that bag time.
- **loop**: after the last message, start over at the first one at or after the start time.

Bag times given to and shown by the session are seconds from the bag's first log time
(`origin_ns`), as `lubrig replay --start/--until` take them.

Pacing: message at log time t is due at wall + (t - bag) / rate, from an anchor (wall, bag)
set when playing starts, resumes, seeks, loops or changes rate. With a `LosslessFlow`
(app/recording/replay_flow.py), a message of the flow-controlled topic is also held until the named
subscribers have taken enough of what was sent (`Wait` with the reason, no deadline).
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass

from lubrig_ros.app.interface.cdr import SampleSpan
from lubrig_ros.app.recording.replay_flow import LosslessFlow
from lubrig_ros.core.errors import InputError

#: Fastest time scale: beyond it a 1 kHz bag is 1 MHz of messages, no replay.
MAX_RATE = 1000.0


@dataclass(frozen=True)
class Entry:
    """One message to replay: topic, log time (ns), serialized bytes, and its samples if paced."""

    topic: str
    time_ns: int
    data: bytes
    span: SampleSpan | None = None  # set for the flow-controlled topic (lossless mode)


@dataclass(frozen=True)
class Publish:
    """Publish this message now."""

    entry: Entry


@dataclass(frozen=True)
class Wait:
    """Nothing to publish yet: wait at most `seconds` (None: until a control or a report)."""

    seconds: float | None
    reason: str = ""  # why, when held by flow control


@dataclass(frozen=True)
class Done:
    """Everything is played (not looping)."""


Action = Publish | Wait | Done


def check_rate(rate: float, name: str = "--rate") -> float:
    """The rate, or InputError naming it and the valid range."""
    if (
        isinstance(rate, bool)
        or not isinstance(rate, int | float)
        or not (math.isfinite(rate) and 0 < rate <= MAX_RATE)
    ):
        raise InputError(f"{name} {rate} is invalid: expected a time scale in (0, {MAX_RATE:g}]")
    return float(rate)


class ReplaySession:
    """The player's state (see the module docstring); every method takes the time now (s)."""

    def __init__(
        self,
        entries: Sequence[Entry],
        *,
        origin_ns: int,
        now: float,
        rate: float = 1.0,
        start_s: float = 0.0,
        until_s: float | None = None,
        loop: bool = False,
        paused: bool = False,
        flow: LosslessFlow | None = None,
    ) -> None:
        self.entries = list(entries)
        self.times = [e.time_ns for e in self.entries]
        self.origin_ns = origin_ns
        self.rate = check_rate(rate)
        self.start_ns = origin_ns + round(start_s * 1e9)
        self.until_ns = None if until_s is None else origin_ns + round(until_s * 1e9)
        self.first = bisect.bisect_left(self.times, self.start_ns)
        self.end = (
            len(self.times) if self.until_ns is None else bisect.bisect_right(self.times, self.until_ns)
        )
        self.loop = loop
        self.flow = flow
        self.position = self.first
        self.paused = paused
        self.anchor = (now, self.start_ns)  # (wall s, bag ns) of the pacing
        self.paused_at_ns = self.start_ns  # bag time while paused
        self.published = 0

    # ---- where the player is ------------------------------------------------------------
    def bag_time_ns(self, now: float) -> int:
        """The bag time reached: frozen while paused; never beyond the next message's time."""
        if self.paused:
            return self.paused_at_ns
        wall, bag = self.anchor
        t = bag + round((now - wall) * self.rate * 1e9)
        if self.position < self.end:
            t = min(t, self.times[self.position])
        return t

    def seconds(self, t_ns: int) -> float:
        """Bag time t_ns as seconds from the bag's first log time."""
        return (t_ns - self.origin_ns) / 1e9

    def bounds_s(self) -> tuple[float, float]:
        """The bag times a seek may go to: from the bag's start to --until or its last message."""
        last = (
            self.until_ns if self.until_ns is not None else (self.times[-1] if self.times else self.origin_ns)
        )
        return 0.0, self.seconds(max(last, self.origin_ns))

    # ---- controls -----------------------------------------------------------------------
    def pause(self, now: float) -> bool:
        """Pause; False if already paused."""
        if self.paused:
            return False
        self.paused_at_ns = self.bag_time_ns(now)
        self.paused = True
        return True

    def resume(self, now: float) -> bool:
        """Play on from the bag time paused at; False if not paused."""
        if not self.paused:
            return False
        self.paused = False
        self.anchor = (now, self.paused_at_ns)
        return True

    def toggle(self, now: float) -> bool:
        """Pause if playing, resume if paused; returns whether it is paused now."""
        if not self.resume(now):
            self.pause(now)
        return self.paused

    def set_rate(self, rate: float, now: float) -> None:
        """A new time scale from the bag time reached (InputError outside (0, MAX_RATE])."""
        rate = check_rate(rate, "rate")
        if not self.paused:
            self.anchor = (now, self.bag_time_ns(now))
        self.rate = rate

    def seek(self, t_s: float, now: float) -> None:
        """Go to bag time t_s (s from the bag's start): the next message is the first at or after it.

        InputError outside the bag (or beyond --until).
        """
        low, high = self.bounds_s()
        if (
            isinstance(t_s, bool)
            or not isinstance(t_s, int | float)
            or not (math.isfinite(t_s) and low <= t_s <= high)
        ):
            raise InputError(f"seek {t_s} is invalid: expected seconds of bag time in [{low:g}, {high:g}]")
        t_ns = self.origin_ns + round(t_s * 1e9)
        self.position = bisect.bisect_left(self.times, t_ns, 0, self.end)
        self.paused_at_ns = t_ns
        self.anchor = (now, t_ns)

    def step(self, now: float) -> Entry | str:
        """Paused: the next message, published at once (the position moves past it).

        Returns the reason as a string when there is none: not paused, at the end, or held by
        the lossless flow control.
        """
        if not self.paused:
            return "not paused: play_next steps a paused replay"
        if not self._wrap(now):
            return "at the end of the replayed range"
        entry = self.entries[self.position]
        held = self._held(entry)
        if held:
            return held
        self.paused_at_ns = entry.time_ns
        self._advance(entry)
        return entry

    # ---- the player's loop --------------------------------------------------------------
    def next(self, now: float) -> Action:
        """What to do now: publish the next message, wait, or stop (Done)."""
        if self.paused and (self.position < self.end or self.loop):
            return Wait(None)
        if not self._wrap(now):
            pending = self.flow.pending() if self.flow is not None else None
            return Wait(None, pending) if pending else Done()
        entry = self.entries[self.position]
        wall, bag = self.anchor
        left = wall + (entry.time_ns - bag) / 1e9 / self.rate - now
        if left > 0:
            return Wait(left)
        held = self._held(entry)
        if held:
            return Wait(None, held)
        self._advance(entry)
        return Publish(entry)

    # ---- internals ----------------------------------------------------------------------
    def _wrap(self, now: float) -> bool:
        """True if there is a next message; at the end with loop, back to the start time."""
        if self.position < self.end:
            return True
        if not self.loop or self.first >= self.end:
            return False
        self.position = self.first
        self.paused_at_ns = self.start_ns
        self.anchor = (now, self.start_ns)
        return True

    def _held(self, entry: Entry) -> str:
        """Lossless: no message before every subscriber's first report, no block beyond the window."""
        if self.flow is None:
            return ""
        if entry.span is None:
            return self.flow.unheard() or ""
        return self.flow.hold(entry.span) or ""

    def _advance(self, entry: Entry) -> None:
        self.position += 1
        self.published += 1
        if self.flow is not None and entry.span is not None:
            self.flow.sent(entry.span)
