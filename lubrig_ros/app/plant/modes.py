"""What differs between the plant's modes: the `ModeRules` protocol and the stepped modes' rules.

A `PlantSession` holds the shared state (configuration, integrator, counters, sinks) and one
`ModeRules` object chosen by mode from `MODE_RULES`; the session's band input, reset, pause and
start go through it. This module has the stepped family (``sim``, ``lockstep``: rig time is the
session's own, band values integrated strictly in order in blocks); app/plant/wallclock.py has
the wall-clock family (``realtime``, ``rig_in_loop``). The rules are documented once, in the
module docstring of app/plant/session.py.

Every method is called with the session's lock held.
"""

from __future__ import annotations

from collections import deque
from typing import Protocol

import numpy as np
from typing_extensions import override

from ...core.trajectory import Trajectory, concatenate
from .state import PlantState


class ModeRules(Protocol):
    """One mode's rules over the plant's state (app.plant.state.PlantState; the session's `rules`)."""

    #: Rig time is the session's own (True), or it follows the wall clock.
    stepped: bool
    #: A run without band input for STALL_S is an error (sim; the others wait for their input).
    reports_stall: bool

    def band_value(self, value: float, now: float) -> None:
        """One good band value, arrived at clock() time `now`."""

    def band_values(
        self, band: np.ndarray, good: np.ndarray, segment: int | None, first: int | None, now: float
    ) -> int:
        """A block's values (`good`: inside the band limits; the rest are counted); how many are kept."""
        ...

    def emit_initial(self) -> None:
        """Emit the segment's initial state, now (the session has marked it emitted)."""

    def reset(self) -> None:
        """A new segment: after the session reset its shared state."""

    def set_paused(self, paused: bool, was: bool) -> None:
        """After the session's paused flag changed from `was` to `paused`."""

    def drain(self) -> None:
        """Integrate what the input allows (stepped), or nothing."""

    def timing_values(self) -> list[tuple[str, str]]:
        """The mode's own entries of the timing status (diagnostics key, text)."""
        ...

    def queue_overflow(self) -> int:
        """Band values dropped for want of room."""
        ...

    def late_band(self) -> int:
        """Band values that came for samples already integrated."""
        ...


class SteppedRules(ModeRules):
    """``sim``: band values queued and integrated in order, a block as one stepper call."""

    stepped = True
    reports_stall = True

    def __init__(self, session: PlantState) -> None:
        self.s = session
        self.queue: deque[np.ndarray] = deque()  # band blocks waiting (paused)

    # ---- input ---------------------------------------------------------------------------
    @override
    def band_value(self, value: float, now: float) -> None:
        self.arrived(now)
        self.queue.append(np.array([value]))
        self.drain()

    @override
    def band_values(
        self, band: np.ndarray, good: np.ndarray, segment: int | None, first: int | None, now: float
    ) -> int:
        s = self.s
        band = band[good]
        if s.fault is not None:  # a failed sample ended the run: nothing more is integrated
            s.ignored_after_end += band.size
            return 0
        if segment is not None and segment != s.segment:
            s.stale_blocks += 1
            return 0
        if first is not None:
            expected = s.sample_index + sum(b.size for b in self.queue)
            if self.repeats(first, expected):
                s.repeated_blocks += 1
                return 0
            if first != expected:
                s.index_gaps += 1
                s.log(
                    "warning",
                    f"band block starts at sample {first}, expected {expected} (segment {s.segment})",
                )
        if band.size:
            self.arrived(now)
            s.latest_band_recv = now  # for the stall report (diagnostics)
            self.queue.append(band)
            self.drain()
        return int(band.size)

    @override
    def timing_values(self) -> list[tuple[str, str]]:
        return []

    @override
    def queue_overflow(self) -> int:
        return 0  # the queue holds what comes (flow control bounds it)

    @override
    def late_band(self) -> int:
        return 0

    def repeats(self, first: int, expected: int) -> bool:
        """A block that starts before the next expected sample is integrated all the same (sim)."""
        return False

    def arrived(self, now: float) -> None:
        """Band input arrived (lockstep keeps the round trip)."""

    # ---- segment and pause ---------------------------------------------------------------
    @override
    def emit_initial(self) -> None:
        self.s.emit_block(self.s.integrator.current())

    @override
    def reset(self) -> None:
        self.queue.clear()

    @override
    def set_paused(self, paused: bool, was: bool) -> None:
        if not paused:
            self.drain()

    # ---- integration ---------------------------------------------------------------------
    @override
    def drain(self) -> None:
        s = self.s
        while self.queue and not s.paused:
            band = self.queue.popleft()
            if s.complete or s.fault is not None:
                s.ignored_after_end += band.size
                continue
            room = s.total - s.sample_index
            if band.size > room:
                s.ignored_after_end += band.size - room
                band = band[:room]
            self._integrate_block(band)
            if s.sample_index >= s.total:
                s.complete = True
                s.on_complete(True)
                s.log("info", f"{s.mode}: run complete at t = {s.integrator.time:g} s")

    def _integrate_block(self, band: np.ndarray) -> None:
        """Integrate a block of band values and emit it (with the initial state if not yet)."""
        s = self.s
        parts = [] if s.emitted_initial else [s.integrator.current()]
        s.emitted_initial = True
        traj = self._advance_block(band)
        s.sample_index += len(traj)
        s.ignored_after_end += band.size - len(traj)  # after a failed sample (s.fault)
        parts.append(traj)
        s.emit_block(parts[0] if len(parts) == 1 else concatenate(parts))
        self.emitted()

    def emitted(self) -> None:
        """A block went out (lockstep starts its round trip)."""

    def _advance_block(self, band: np.ndarray) -> Trajectory:
        """The block in one stepper call; on a failure, again sample by sample up to a failed one."""
        s = self.s
        if band.size > 1:
            saved = s.integrator.snapshot()
            try:
                traj = s.integrator.advance(band)
                if np.isfinite(traj.displacement).all() and np.isfinite(traj.velocity).all():
                    return traj
            except (ValueError, ArithmeticError, RuntimeError):
                pass
            s.integrator.restore(saved)
        done = []
        for b in band:
            one = s.advance(float(b))
            if one is None:  # s.fault says why; the samples before it are emitted
                break
            done.append(one)
        if not done:
            return Trajectory(**{name: np.zeros(0) for name, _ in Trajectory.COLUMNS})
        return Trajectory(*(np.array(column) for column in zip(*done, strict=True)))


class LockstepRules(SteppedRules):
    """``lockstep``: sim's rules for rig software that answers each state.

    The initial state goes out at once (at start and after a reset); a block that starts before
    the next expected sample repeats what was integrated and is dropped; the round trip (state
    emitted → the band value for the next sample arrives) is kept in the session's histogram.
    """

    reports_stall = False

    def __init__(self, session: PlantState) -> None:
        super().__init__(session)
        self.emitted_at: float | None = None

    @override
    def repeats(self, first: int, expected: int) -> bool:
        return first < expected

    @override
    def arrived(self, now: float) -> None:
        if self.emitted_at is not None and not self.queue:
            self.s.round_trips.add(now - self.emitted_at)
            self.emitted_at = None

    @override
    def emit_initial(self) -> None:
        super().emit_initial()
        self.emitted()

    @override
    def emitted(self) -> None:
        self.emitted_at = self.s.clock()

    @override
    def timing_values(self) -> list[tuple[str, str]]:
        trips = self.s.round_trips
        r50, r99 = trips.percentiles()
        return [
            ("round_trip_p50_s", f"{r50:.6f}"),
            ("round_trip_p99_s", f"{r99:.6f}"),
            ("round_trips", str(trips.count)),
        ]

    @override
    def reset(self) -> None:
        super().reset()
        self.s.emitted_initial = True
        self.emit_initial()
