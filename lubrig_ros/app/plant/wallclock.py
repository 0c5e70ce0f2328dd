"""The wall-clock modes' rules (``realtime``, ``rig_in_loop``): the deadline loop and its ticks.

`WallClockRules` (``rig_in_loop``: the latest good band value, a block's values one per tick)
and `IndexedRules` (``realtime``: band values sent ahead with the sample index each belongs to,
kept in an `IndexedBand`). `run` ticks at the sample rate with absolute-time sleeps
(app/timing.py), integrates one sample per tick within a step budget, and applies the lag
policy when the loop falls behind (`fell_behind`). The rules are documented once, in the module
docstring of app/plant/session.py; this module implements them over the session's state.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections import deque
from collections.abc import Callable

import numpy as np
from typing_extensions import override

from ...core.errors import InputError
from ..timing import DeadlineLoop, tight_timer_slack
from .modes import ModeRules
from .state import PlantState

#: At most one "fell behind" log line per this many seconds (each one counted).
BEHIND_LOG_S = 1.0


class IndexedBand:
    """Band values by sample index for the samples ahead (realtime: what belt_drive sent).

    A ring of `capacity` slots; a value older than the sample in progress is late and dropped.
    """

    def __init__(self, capacity: int) -> None:
        self.values = np.zeros(capacity)
        self.index = np.full(capacity, -1, dtype=np.int64)
        self.late = 0  # values that arrived for samples already integrated
        self.overflow = 0  # values more than `capacity` samples ahead (dropped)

    def clear(self) -> None:
        """Forget every value (a reset)."""
        self.index.fill(-1)

    def put(self, first: int, values: np.ndarray, next_needed: int) -> None:
        """Values for sample indices first, first + 1, ... (NaN: none); next_needed: the next to integrate."""
        capacity = self.index.size
        idx = first + np.arange(values.size, dtype=np.int64)
        given = np.isfinite(values)
        keep = given & (idx >= next_needed)
        self.late += int((given & ~keep).sum())
        ahead = idx < next_needed + capacity
        self.overflow += int((keep & ~ahead).sum())
        keep &= ahead
        slots = idx[keep] % capacity
        self.values[slots] = values[keep]
        self.index[slots] = idx[keep]

    def get(self, k: int) -> float | None:
        """The value for sample index k, or None."""
        slot = k % self.index.size
        return float(self.values[slot]) if self.index[slot] == k else None


class WallClockRules(ModeRules):
    """``rig_in_loop``: one sample per tick with the latest good band value (see the module docstring)."""

    stepped = False
    reports_stall = False

    def __init__(self, session: PlantState) -> None:
        self.s = session
        rate = max(1, round(session.config.sample_rate))
        self.queue: deque[float] = deque(maxlen=rate)  # a block's values, one per tick
        self.overflow = 0  # block values dropped because more than 1 s was queued
        self.pending_band: float | None = None  # band value of the sample in progress
        self.pending_recv: float | None = None
        self.new_band = False
        self.behind_logged = -math.inf

    # ---- input ---------------------------------------------------------------------------
    @override
    def band_value(self, value: float, now: float) -> None:
        s = self.s
        s.latest_band = value
        s.latest_band_recv = now
        self.new_band = True
        self.queue.clear()  # a single value replaces what a block queued

    @override
    def band_values(
        self, band: np.ndarray, good: np.ndarray, segment: int | None, first: int | None, now: float
    ) -> int:
        band = band[good]
        if band.size:
            room = (self.queue.maxlen or 0) - len(self.queue)
            self.overflow += max(0, band.size - room)
            self.queue.extend(band.tolist())
            self.s.latest_band_recv = now
            self.new_band = True
        return int(band.size)

    def next_band(self) -> tuple[float, float | None]:
        """The band value for the sample to integrate next, and when it arrived (latency)."""
        s = self.s
        recv = s.latest_band_recv if self.new_band else None
        self.new_band = False
        if self.queue:
            s.latest_band = self.queue.popleft()
            self.new_band = bool(self.queue)
        return s.latest_band, recv

    @override
    def queue_overflow(self) -> int:
        """Band values dropped for want of room."""
        return self.overflow

    @override
    def late_band(self) -> int:
        """Band values that came for samples already integrated (indexed input only)."""
        return 0

    @override
    def timing_values(self) -> list[tuple[str, str]]:
        return []

    # ---- segment and pause ---------------------------------------------------------------
    @override
    def emit_initial(self) -> None:
        self.s.emit(self.s.integrator.current().sample(0), 0.0)

    @override
    def reset(self) -> None:
        s = self.s
        self.queue.clear()
        self.pending_band = self.pending_recv = None
        try:
            s.integrator.reset(band_velocity=s.latest_band)
        except InputError as exc:  # 0 < |held value| below what the integrator resolves
            # a band at rest in all but name (core.integrator): the rig restarts at rest; the held
            # value stays the band input until the next one comes
            s.integrator.reset(band_velocity=0.0)
            s.log("warning", f"reset: restarted at rest, not at the held band value: {exc}")
        s.restart_clock = True

    @override
    def set_paused(self, paused: bool, was: bool) -> None:
        if paused:
            self.s.flush_block()
        elif was:
            self.s.restart_clock = True

    @override
    def drain(self) -> None:
        """Nothing: the loop integrates, one sample per tick."""

    # ---- the loop ------------------------------------------------------------------------
    def run(self, stopped: Callable[[], bool]) -> None:
        """The initial state, then a tick per sample period until stopped() (PlantSession.run_realtime)."""
        s = self.s
        tight_timer_slack()
        self.warm_up()
        loop, k = self.start_loop()
        while not stopped():
            if s.paused or s.fault is not None:
                time.sleep(0.01)
                if s.take_restart_clock():
                    loop, k = self.start_loop()
                continue
            if s.take_restart_clock():
                loop, k = self.start_loop()
            k += 1
            late = loop.wait(k)
            if s.restart_clock or s.paused:  # a reset or pause came while it slept
                k -= 1
                continue
            if late > s.settings.max_lag:
                k = self.fell_behind(k, late, loop.due_index(s.clock()))
                if s.fault is not None:
                    continue
                late = max(0.0, s.clock() - loop.deadline(k))
            if not self.tick(loop.deadline(k), late):
                k -= 1  # the same sample and deadline again, without waiting
        with s.lock:
            s.flush_block()

    def warm_up(self) -> None:
        """One sample integrated and undone: the compiled kernel's first call (about 10 ms) is not a tick."""
        s = self.s
        with s.lock:
            saved = s.integrator.snapshot()
            with contextlib.suppress(ValueError, ArithmeticError, RuntimeError):
                s.integrator.advance_bounded(s.latest_band, s.settings.tick_step_attempts)
            s.integrator.restore(saved)

    def start_loop(self) -> tuple[DeadlineLoop, int]:
        """Deadlines from now for the segment (start, reset, resume); the initial state if not yet."""
        s = self.s
        with s.lock:
            loop = DeadlineLoop(s.period, s.clock())
            if s.emitted_initial:  # a resume: the samples already emitted keep their due times
                loop.start -= s.published * s.period
            s.segment_start = loop.start
            if not s.emitted_initial:
                s.emitted_initial = True
                self.emit_initial()
            s.flush_block()  # at once: its flow_progress tells the band source where we are
            return loop, s.published - 1

    def tick(self, deadline: float | None = None, late: float = 0.0) -> bool:
        """Advance one sample and emit it; True if emitted (see PlantSession.tick)."""
        s = self.s
        with s.lock:
            if s.fault is not None:  # lag_policy stop, or a failed sample: nothing until a reset
                return False
            if self.pending_band is None:
                self.pending_band, self.pending_recv = self.next_band()
            traj = s.advance(self.pending_band, s.settings.tick_step_attempts)
            done = s.clock()
            if traj is None and s.fault is not None:  # failed: nothing more until a reset
                return False
            if traj is None:  # the sample's step budget ran out: carry on at the next call
                s.overruns += 1
                return False
            recv, self.pending_band, self.pending_recv = self.pending_recv, None, None
            s.sample_index += 1
            lateness = max(late, done - deadline) if deadline is not None else late
            s.emit(traj, lateness)
            s.emitted_initial = True
            s.ticks += 1
            if recv is not None:
                s.latencies.add(done - recv)
            if lateness > s.period:
                s.misses += 1
            return True

    def fell_behind(self, k: int, late: float, due_index: int) -> int:
        """Sample k starts `late` s after its due time, more than max_lag; returns the next k.

        skip: samples k .. due_index - 1 are integrated (band values known for them, else the
        held one) without being emitted, the next block declares them; returns due_index.
        stop: the fault is set and `on_fault` called; returns k. Logged at once (ERROR),
        then at most once per BEHIND_LOG_S.
        """
        s = self.s
        with s.lock:
            s.held_real_time = False
            bound = s.settings.max_lag
            if s.settings.lag_policy == "stop":
                s.fault = (
                    f"could not hold real time: sample {k} of segment {s.segment} started "
                    f"{1e3 * late:.1f} ms after its due time (max_lag {1e3 * bound:g} ms, lag_policy stop)"
                )
                s.flush_block()
                s.log("error", s.fault + "; no more output")
                s.on_fault(s.fault)
                return k
            count = max(0, due_index - k)
            if count:
                self.skip(count)
            s.skipped += count
            s.skip_events += 1
            now = s.clock()
            if now - self.behind_logged >= BEHIND_LOG_S:
                self.behind_logged = now
                s.log(
                    "error",
                    f"fell behind real time: sample {k} of segment {s.segment} started "
                    f"{1e3 * late:.1f} ms late (max_lag {1e3 * bound:g} ms); {count} samples "
                    f"skipped (integrated, not published; {s.skipped} in {s.skip_events} "
                    "gaps so far, lag_policy skip)",
                )
            return k + count

    def skip(self, count: int) -> None:
        """Integrate the next `count` samples without emitting them; the next block declares them."""
        s = self.s
        band = np.empty(count)
        first = s.sample_index
        for i in range(count):
            s.sample_index = first + i
            band[i], _ = self.next_band()
        s.sample_index = first
        s.flush_block()
        t0 = s.integrator.time
        try:
            traj = s.integrator.advance(band)
            finite = np.isfinite(traj.displacement).all() and np.isfinite(traj.velocity).all()
            problem = "" if finite else "non-finite state"
        except (ValueError, ArithmeticError, RuntimeError) as exc:
            problem = str(exc)
        if problem:  # nothing of it is emitted; the fault holds the loop until a reset
            s.fail(t0 + s.integrator.dt, float(band[0]), f"{problem} (in {count} skipped samples)")
            return
        s.travel.add_many(traj.time, traj.band_velocity)
        s.sample_index += band.size
        s.published += band.size
        s.blocks.skip(band.size)


class IndexedRules(WallClockRules):
    """``realtime``: the sample with index k uses the band value sent for index k (else the held one)."""

    def __init__(self, session: PlantState) -> None:
        super().__init__(session)
        self.ahead = IndexedBand(max(1, round(session.config.sample_rate)))

    @override
    def band_values(
        self, band: np.ndarray, good: np.ndarray, segment: int | None, first: int | None, now: float
    ) -> int:
        s = self.s
        band = np.where(good, band, np.nan)  # the indices stay: NaN is no value for that sample
        if segment is not None and segment != s.segment:
            s.stale_blocks += 1
            return 0
        start = first if first is not None else s.sample_index
        kept = np.isfinite(band)
        self.ahead.put(int(start), band, s.sample_index)
        if kept.any():
            s.latest_band_recv = now
        return int(kept.sum())

    @override
    def next_band(self) -> tuple[float, float | None]:
        s = self.s
        value = self.ahead.get(s.sample_index)
        if value is None:
            if s.latest_band_recv is not None:
                s.held_samples += 1
            return s.latest_band, None
        s.latest_band = value
        # the input is as fresh as the newest value in hand for a sample: sent ahead in blocks
        # (belt_drive tops up with each flow_progress, 0.1 s apart), it is stale only once the
        # plant holds, not while it takes values that came a while ago
        s.latest_band_recv = s.clock()
        return value, None

    @override
    def queue_overflow(self) -> int:
        return self.overflow + self.ahead.overflow

    @override
    def late_band(self) -> int:
        return self.ahead.late

    @override
    def reset(self) -> None:
        super().reset()
        self.ahead.clear()
