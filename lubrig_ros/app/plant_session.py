"""The plant's rules without ROS: band sample sequencing, pause/reset, input checks, timing.

`PlantSession` is everything the plant node does that is not ROS. The node feeds it band values
(`band_input`, one value; `band_block`, consecutive values), runs `run_realtime` on its loop
thread in the realtime modes, forwards reset/pause requests and parameter updates, and publishes
what the session hands to its sinks (`on_sample` per sample, `on_block` per block of samples,
`on_complete`, `on_fault`, `log`).

Modes (app/contract.MODES), in two families:

* stepped — ``sim`` and ``lockstep``: rig time is the session's own. Band values are queued and
  integrated strictly in order, one sample per band value, a block (`band_block`) as one call of
  the same core stepper core.run.simulate uses (RigIntegrator.advance); each block's samples go
  to `on_block` as one `PlantBlock` (the first block of a segment starts with the initial
  state, sample_index 0) and to `on_sample` one by one. The run is deterministic, equal to
  core.run.simulate sample for sample whatever the block length; `on_complete(True)` once
  `duration` is reached, band values after that are counted (`ignored_after_end`) and dropped.
  A block stamped with another segment than the current one (sent before a reset) is dropped
  and counted (`stale_blocks`). ``lockstep`` is for rig software that answers each state: it
  emits the initial state at once (`emit_initial`), drops a band block that repeats samples
  already integrated (`repeated_blocks`) and keeps the round trip (state emitted → the band
  value for the next sample arrives) in a histogram.
* wall-clock — ``realtime`` and ``rig_in_loop``: `run_realtime` ticks at the sample rate
  (absolute-time sleeps, app/timing.py); each tick integrates one sample. ``realtime`` takes
  indexed band samples sent ahead (`band_block` with the sample index each value belongs to:
  our belt_drive), so the sample with index k uses the band value of index k; ``rig_in_loop``
  takes the latest good value (one Float64 per sample from foreign rig software; a block's
  values serve one per tick, in order). Without a value for a sample the last one is held.
  Every sample goes to `on_sample` and, in blocks of `output_block_length` samples with each
  sample's lateness (how long after its due time it was computed), to `on_block`.

Falling behind real time (wall-clock modes): a sample is due at the segment's start +
sample_index / sample_rate. Late by up to `max_lag` the loop catches up (the samples it owes
are computed at once, in order). Past `max_lag` the rig has not held real time: ERROR at once
(log and the timing status), and with `lag_policy`

* ``skip`` the rig keeps real time: the samples that are overdue are integrated with the band
  values known for them (else the held value) but not emitted, and the next block declares them
  (`PlantBlock.skipped`: a gap the recorder, `lubrig bag check` and the report show);
* ``stop`` the rig stops: nothing more is emitted, `on_fault` is called once with the reason.

Either way `held_real_time` is False from then on (the node exits with a status saying so).

Segments: `segment` is 0 from the start and +1 at every `reset`; `sample_index` and rig time
restart at 0 with it. `published` is the index of the next sample to emit in the current
segment (samples emitted plus those skipped): what the plant reports on flow_progress.

Band values that are not finite or exceed `band_velocity_limit` in magnitude are rejected in every
mode: counted, the last one reported, never integrated. A sample whose integration fails (an
exception or a non-finite state) restarts the rig at equilibrium for that band velocity at the
next sample time, so rig time stays monotonic and a sim run still completes.

Thread safety: every public method takes the session's lock, so the real-time loop thread and the
executor's callbacks may call it concurrently; sinks are called with the lock held (in order).
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, overload

import numpy as np

from ..core.integrator import RigIntegrator
from ..core.params import ParameterError
from ..core.presets import RunConfig
from ..core.run import integrator_for
from ..core.trajectory import Trajectory, concatenate
from .contract import (
    DEFAULT_LAG_POLICY,
    DEFAULT_MAX_LAG,
    DEFAULT_OUTPUT_BLOCK_LENGTH,
    DEFAULT_TICK_STEP_ATTEMPTS,
    LAG_POLICIES,
    MODES,
    STEPPED_MODES,
)
from .diagnostics import Level, Status
from .plant_config import (
    CONFIG_PARAMETERS,
    RUNTIME_PARAMETERS,
    config_from,
    config_parameters,
    law_of,
    parameter_defaults,
    runtime_parameters,
)
from .plant_output import BeltTravel, BlockBuffer, PlantBlock, PlantSample
from .timing import DeadlineLoop, LatencyHistogram, tight_timer_slack

__all__ = [
    "CONFIG_PARAMETERS",
    "RUNTIME_PARAMETERS",
    "STALL_S",
    "PlantBlock",
    "PlantSample",
    "PlantSession",
    "PlantSettings",
    "config_from",
    "config_parameters",
    "law_of",
    "parameter_defaults",
    "runtime_parameters",
]

HARDWARE_ID = "lubrig_plant"
#: Share of deadline misses above which the timing status is WARN.
MISS_SHARE_WARN = 1e-3
#: Sim: a run that has started, is neither paused nor complete, and got no band sample for this
#: long is reported as stalled (timing status ERROR); back to ok when samples flow again.
STALL_S = 1.0
#: Wall-clock modes: at most one "fell behind" log line per this many seconds (each counted).
BEHIND_LOG_S = 1.0


@dataclass(frozen=True)
class PlantSettings:
    """Read-only node settings (contract defaults)."""

    mode: str = "sim"
    band_velocity_limit: float = 1e-2
    stale_timeout: float = 0.05
    tick_step_attempts: int = DEFAULT_TICK_STEP_ATTEMPTS
    lag_policy: str = DEFAULT_LAG_POLICY
    max_lag: float = DEFAULT_MAX_LAG
    output_block_length: int = DEFAULT_OUTPUT_BLOCK_LENGTH

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ParameterError(f"mode={self.mode!r} is not valid; expected one of {list(MODES)}")
        if self.lag_policy not in LAG_POLICIES:
            raise ParameterError(
                f"lag_policy={self.lag_policy!r} is not valid; expected one of {list(LAG_POLICIES)}"
            )
        for name in ("tick_step_attempts", "output_block_length"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ParameterError(f"{name}={value!r} is not valid; expected an integer >= 1")
        for name in ("band_velocity_limit", "stale_timeout", "max_lag"):
            value = getattr(self, name)
            if not (isinstance(value, float | int) and math.isfinite(value) and value > 0.0):
                raise ParameterError(f"{name}={value!r} is not valid; expected a finite number > 0")


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


def _nothing(*_args: Any) -> None:
    return None


class PlantSession:
    """The plant's state and rules (see the module docstring)."""

    def __init__(
        self,
        base: RunConfig,
        settings: PlantSettings | None = None,
        *,
        on_sample: Callable[[PlantSample], None] = _nothing,
        on_block: Callable[[PlantBlock], None] = _nothing,
        on_complete: Callable[[bool], None] = _nothing,
        on_fault: Callable[[str], None] = _nothing,
        log: Callable[[str, str], None] = _nothing,
        clock: Callable[[], float] = time.monotonic,
        config: RunConfig | None = None,
    ) -> None:
        self.base = base
        self.settings = settings or PlantSettings()
        self.mode = self.settings.mode
        self.stepped = self.mode in STEPPED_MODES
        self.indexed = self.mode == "realtime"  # band samples sent ahead with their index
        self.on_sample, self.on_complete, self.log, self.clock = on_sample, on_complete, log, clock
        self.on_block, self.on_fault = on_block, on_fault
        self.lock = threading.RLock()
        self.config = config if config is not None else base
        self.integrator: RigIntegrator = integrator_for(self.config)
        self.total = self.config.samples
        self.sample_index = 0  # band samples integrated in this segment
        self.segment = 0
        self.published = 0  # index of the next sample to emit in this segment
        self.paused = False
        self.complete = False
        self.restart_clock = False  # realtime: the loop restarts its deadlines (reset, resume)
        self._queue: deque[np.ndarray] = deque()  # stepped: band blocks waiting (paused)
        rate = max(1, round(self.config.sample_rate))
        self._rt_queue: deque[float] = deque(maxlen=rate)  # rig_in_loop: block values, one per tick
        self._band_ahead = IndexedBand(rate)  # realtime: band values by sample index
        self.rt_overflow = 0  # rig_in_loop: block values dropped because more than 1 s was queued
        self.stale_blocks = 0  # stepped: blocks of another segment than the current one (dropped)
        self.index_gaps = 0  # stepped: blocks whose first_sample_index was not the next expected
        self.repeated_blocks = 0  # lockstep: blocks of samples already integrated (dropped)
        self._emitted_initial = False
        # band input bookkeeping
        self.latest_band = float(self.config.band(0.0))
        self.latest_band_recv: float | None = None  # clock() of the latest good value
        self.new_band = False
        self.received = 0
        self.rejected = 0
        self.last_rejected: float | None = None
        self.rejected_since_report = 0
        self.ignored_after_end = 0
        self.integration_errors = 0
        self.held_samples = 0  # realtime: samples integrated with a held value (none sent for them)
        self.overruns = 0  # realtime: ticks whose sample ran out of step budget (nothing emitted)
        self._overruns_reported = 0
        self._pending_band: float | None = None  # realtime: band value of the sample in progress
        self._pending_recv: float | None = None
        self.travel = BeltTravel()
        self.blocks = BlockBuffer(self.settings.output_block_length, self.period)
        # timing (wall-clock modes)
        self.ticks = 0
        self.misses = 0
        self.max_late = 0.0  # worst lateness of a sample, s
        self.lag = 0.0  # lateness of the newest sample, s
        self.latencies = LatencyHistogram()  # rig_in_loop: band value received -> its sample
        self.skipped = 0  # samples skipped (lag_policy skip)
        self.skip_events = 0
        self._skipped_reported = 0
        self._behind_logged = -math.inf
        self.fault: str | None = None  # lag_policy stop: why the rig stopped
        self.segment_start: float | None = None  # clock() due time of sample 0 of the segment
        self.held_real_time = True
        # lockstep: emitted -> next band value
        self.round_trips = LatencyHistogram()
        self._emitted_at: float | None = None

    # ---- configuration -------------------------------------------------------------------
    @property
    def time(self) -> float:
        """Rig time of the latest sample, s."""
        return float(self.integrator.time)

    @property
    def period(self) -> float:
        """Sample period, s."""
        return 1.0 / self.config.sample_rate

    def check_update(self, current: Mapping[str, Any], updates: Mapping[str, Any]) -> str | None:
        """Why a parameter update (applied at the next reset) is invalid, or None when it is fine.

        `current` holds the present values of the configuration parameters; only names in
        runtime_parameters(law of the running configuration) are considered (others are not
        configuration).
        """
        relevant = {k: v for k, v in updates.items() if k in runtime_parameters(law_of(self.config))}
        if not relevant:
            return None
        try:
            config_from(self.base, {**current, **relevant})
        except (ParameterError, ValueError, TypeError) as exc:
            given = ", ".join(f"{k}={v!r}" for k, v in sorted(relevant.items()))
            return f"{given} refused: {exc}"  # names the parameters, not only the field
        return None

    def reset(self, config: RunConfig) -> None:
        """Rig time back to 0 with `config` (e.g. config_from the current parameters).

        A new segment begins (`segment` + 1, `sample_index` and `published` 0). Stepped modes: the
        queue is dropped and the initial state is emitted again with the next band value (lockstep:
        at once); wall-clock modes: the buffered samples of the old segment are emitted, the rig
        restarts at equilibrium for the band value it holds, the loop restarts its deadlines
        (`restart_clock`) and emits the initial state; a `stop` fault is cleared.
        """
        with self.lock:
            if not self.stepped:
                self._flush_block()
            self.config = config
            self.integrator = integrator_for(config)
            self.total = config.samples
            self.sample_index = 0
            self.segment += 1
            self.published = 0
            self.complete = False
            self._queue.clear()
            self._rt_queue.clear()
            self._band_ahead.clear()
            self.blocks.clear()
            self._pending_band = self._pending_recv = None
            self._emitted_initial = False
            self.fault = None
            if not self.stepped:
                self.integrator.reset(band_velocity=self.latest_band)
                self.restart_clock = True
            self.travel = BeltTravel()
            self.on_complete(False)
            if self.mode == "lockstep":
                self.emit_initial()

    def set_paused(self, paused: bool) -> str:
        """Pause (True) or resume; returns 'paused' or 'running'. Stepped: resuming drains the queue."""
        with self.lock:
            was = self.paused
            self.paused = bool(paused)
            if not self.stepped:
                if self.paused:
                    self._flush_block()
                elif was:
                    self.restart_clock = True
            if not self.paused:
                self._drain()
            return "paused" if self.paused else "running"

    def take_restart_clock(self) -> bool:
        """True once after a reset or a resume in realtime modes (the caller restarts its loop)."""
        with self.lock:
            restart, self.restart_clock = self.restart_clock, False
            return restart

    # ---- band input ----------------------------------------------------------------------
    def valid_band(self, value: Any) -> bool:
        """True for a finite float with |value| <= band_velocity_limit."""
        return (
            isinstance(value, float)
            and math.isfinite(value)
            and abs(value) <= self.settings.band_velocity_limit
        )

    def band_input(self, value: float) -> bool:
        """One band value from the topic; False if rejected. Stepped: integrates what it can."""
        now = self.clock()
        with self.lock:
            self.received += 1
            if not self.valid_band(value):
                self.rejected += 1
                self.rejected_since_report += 1
                self.last_rejected = value
                return False
            if self.stepped:
                self._round_trip(now, self.sample_index)
                self._queue.append(np.array([value]))
                self._drain()
            else:
                self.latest_band = value
                self.latest_band_recv = now
                self.new_band = True
                self._rt_queue.clear()  # a single value replaces what a block queued
            return True

    def band_block(
        self,
        values: Any,
        segment: int | None = None,
        first_sample_index: int | None = None,
    ) -> int:
        """Consecutive band values (a BandVelocityBlock); returns how many were accepted.

        Every value is checked as in `band_input`; rejected ones are counted and skipped.
        Stepped: a block of another `segment` than the current one is dropped (`stale_blocks`);
        a `first_sample_index` that is not the next expected sample (samples integrated plus those
        queued) is counted (`index_gaps`) and logged, the values are integrated all the same (the
        flow control never sends one twice) — in lockstep a block that starts before the next
        expected sample repeats what was integrated and is dropped (`repeated_blocks`).
        realtime: the values are kept for their sample indices; rig_in_loop: they serve one per
        tick, in order.
        """
        now = self.clock()
        try:
            band = np.asarray(values, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            band = np.array([math.nan])
        with self.lock:
            self.received += band.size
            good = np.isfinite(band) & (np.abs(band) <= self.settings.band_velocity_limit)
            if not good.all():
                bad = band[~good]
                self.rejected += bad.size
                self.rejected_since_report += bad.size
                self.last_rejected = float(bad[-1])
                # realtime keeps the indices (NaN: no value for that sample), the others the values
                band = np.where(good, band, np.nan) if self.indexed else band[good]
            if self.indexed:
                if segment is not None and segment != self.segment:
                    self.stale_blocks += 1
                    return 0
                first = first_sample_index if first_sample_index is not None else self.sample_index
                kept = np.isfinite(band)
                self._band_ahead.put(int(first), band, self.sample_index)
                if kept.any():
                    self.latest_band_recv = now
                return int(kept.sum())
            if not self.stepped:
                if band.size:
                    room = (self._rt_queue.maxlen or 0) - len(self._rt_queue)
                    self.rt_overflow += max(0, band.size - room)
                    self._rt_queue.extend(band.tolist())
                    self.latest_band_recv = now
                    self.new_band = True
                return int(band.size)
            if segment is not None and segment != self.segment:
                self.stale_blocks += 1
                return 0
            if first_sample_index is not None:
                expected = self.sample_index + sum(b.size for b in self._queue)
                if first_sample_index < expected and self.mode == "lockstep":
                    self.repeated_blocks += 1
                    return 0
                if first_sample_index != expected:
                    self.index_gaps += 1
                    self.log(
                        "warning",
                        f"band block starts at sample {first_sample_index}, expected {expected} "
                        f"(segment {self.segment})",
                    )
            if band.size:
                self._round_trip(now, self.sample_index)
                self.latest_band_recv = now  # for the stall report (diagnostics)
                self._queue.append(band)
                self._drain()
            return int(band.size)

    def _round_trip(self, now: float, index: int) -> None:
        """Lockstep: the band value for the next sample arrived; time since the state was emitted."""
        if self.mode == "lockstep" and self._emitted_at is not None and not self._queue:
            self.round_trips.add(now - self._emitted_at)
            self._emitted_at = None

    # ---- stepped modes -------------------------------------------------------------------
    def emit_initial(self) -> None:
        """Emit the current state once (sim: done with the first block; other modes: at start)."""
        with self.lock:
            if not self._emitted_initial:
                self._emitted_initial = True
                if self.stepped:
                    self._emit_block(self.integrator.current())
                else:
                    self._emit(self.integrator.current(), 0.0)

    def _drain(self) -> None:
        if not self.stepped:
            return
        while self._queue and not self.paused:
            band = self._queue.popleft()
            if self.complete:
                self.ignored_after_end += band.size
                continue
            room = self.total - self.sample_index
            if band.size > room:
                self.ignored_after_end += band.size - room
                band = band[:room]
            self._integrate_block(band)
            if self.sample_index >= self.total:
                self.complete = True
                self.on_complete(True)
                self.log("info", f"{self.mode}: run complete at t = {self.integrator.time:g} s")

    def _integrate_block(self, band: np.ndarray) -> None:
        """Integrate a block of band values and emit it (with the initial state if not yet)."""
        parts = [] if self._emitted_initial else [self.integrator.current()]
        self._emitted_initial = True
        traj = self._advance_block(band)
        self.sample_index += band.size
        parts.append(traj)
        self._emit_block(parts[0] if len(parts) == 1 else concatenate(parts))

    def _advance_block(self, band: np.ndarray) -> Trajectory:
        """The block in one stepper call; on a failure, again sample by sample (`_advance`)."""
        if band.size > 1:
            saved = self.integrator.snapshot()
            try:
                traj = self.integrator.advance(band)
                if np.isfinite(traj.displacement).all() and np.isfinite(traj.velocity).all():
                    return traj
            except (ValueError, ArithmeticError, RuntimeError):
                pass
            self.integrator.restore(saved)
        return concatenate([self._advance(float(b)) for b in band])

    # ---- wall-clock modes ----------------------------------------------------------------
    def _next_band(self) -> tuple[float, float | None]:
        """The band value for the sample to integrate next, and when it arrived (latency)."""
        if self.indexed:
            value = self._band_ahead.get(self.sample_index)
            if value is None:
                if self.latest_band_recv is not None:
                    self.held_samples += 1
                return self.latest_band, None
            self.latest_band = value
            return value, None
        recv = self.latest_band_recv if self.new_band else None
        self.new_band = False
        if self._rt_queue:
            self.latest_band = self._rt_queue.popleft()
            self.new_band = bool(self._rt_queue)
        return self.latest_band, recv

    def tick(self, deadline: float | None = None, late: float = 0.0) -> bool:
        """Realtime: advance one sample and emit it; True if emitted.

        `deadline` (clock() time the sample was due) feeds the timing statistics: the sample's
        lateness is the time from its deadline to its completion; more than one period is a
        deadline miss. `late` is how late the tick started (kept for callers without a
        deadline). At most `tick_step_attempts` integrator steps per call: a sample that needs
        more is an overrun (False, nothing emitted), and the next call carries on with it.
        """
        with self.lock:
            if self._pending_band is None:
                self._pending_band, self._pending_recv = self._next_band()
            traj = self._advance(self._pending_band, self.settings.tick_step_attempts)
            done = self.clock()
            if traj is None:  # the sample's step budget ran out: carry on at the next call
                self.overruns += 1
                return False
            recv, self._pending_band, self._pending_recv = self._pending_recv, None, None
            self.sample_index += 1
            lateness = max(late, done - deadline) if deadline is not None else late
            self._emit(traj, lateness)
            self._emitted_initial = True
            self.ticks += 1
            if recv is not None:
                self.latencies.add(done - recv)
            if lateness > self.period:
                self.misses += 1
            return True

    def fell_behind(self, k: int, late: float, due_index: int) -> int:
        """Sample k starts `late` s after its due time, more than max_lag; returns the next k.

        skip: samples k .. due_index - 1 are integrated (band values known for them, else the
        held one) without being emitted, the next block declares them; returns due_index.
        stop: the fault is set and `on_fault` called; returns k. Logged at once (ERROR),
        then at most once per BEHIND_LOG_S.
        """
        with self.lock:
            self.held_real_time = False
            bound = self.settings.max_lag
            if self.settings.lag_policy == "stop":
                self.fault = (
                    f"could not hold real time: sample {k} of segment {self.segment} started "
                    f"{1e3 * late:.1f} ms after its due time (max_lag {1e3 * bound:g} ms, lag_policy stop)"
                )
                self._flush_block()
                self.log("error", self.fault + "; no more output")
                self.on_fault(self.fault)
                return k
            count = max(0, due_index - k)
            if count:
                self._skip(count)
            self.skipped += count
            self.skip_events += 1
            now = self.clock()
            if now - self._behind_logged >= BEHIND_LOG_S:
                self._behind_logged = now
                self.log(
                    "error",
                    f"fell behind real time: sample {k} of segment {self.segment} started "
                    f"{1e3 * late:.1f} ms late (max_lag {1e3 * bound:g} ms); {count} samples "
                    f"skipped (integrated, not published; {self.skipped} in {self.skip_events} "
                    "gaps so far, lag_policy skip)",
                )
            return k + count

    def _skip(self, count: int) -> None:
        """Integrate the next `count` samples without emitting them; the next block declares them."""
        band = np.empty(count)
        first = self.sample_index
        for i in range(count):
            self.sample_index = first + i
            band[i], _ = self._next_band()
        self.sample_index = first
        self._flush_block()
        t0 = self.integrator.time
        try:
            traj = self.integrator.advance(band)
            finite = np.isfinite(traj.displacement).all() and np.isfinite(traj.velocity).all()
        except (ValueError, ArithmeticError, RuntimeError):
            finite = False
        if finite:
            self.travel.add_many(traj.time, traj.band_velocity)
        else:
            self.integration_errors += 1
            t_next = t0 + band.size * self.integrator.dt
            self.log("error", f"integration of skipped samples failed; rig restarted at equilibrium "
                     f"at t = {t_next:.6g} s")
            self.integrator.reset(band_velocity=float(band[-1]), time=t_next)
        self.sample_index += band.size
        self.published += band.size
        self.blocks.skip(band.size)

    def run_realtime(self, stopped: Callable[[], bool]) -> None:
        """Wall-clock modes: emit the initial state, then tick at the sample rate until stopped().

        Absolute deadlines (app.timing.DeadlineLoop, no spinning); paused: wait; after a reset or
        a resume the deadlines restart from now. An overrun tick is retried at once for the same
        deadline (the loop sees stop, pause and reset between the calls, and other threads get
        the GIL, which the compiled integrator holds). Past max_lag: `fell_behind`. Exceptions
        of a tick propagate to the caller.
        """
        tight_timer_slack()
        self._warm_up()
        loop, k = self._start_loop()
        while not stopped():
            if self.paused or self.fault is not None:
                time.sleep(0.01)
                if self.take_restart_clock():
                    loop, k = self._start_loop()
                continue
            if self.take_restart_clock():
                loop, k = self._start_loop()
            k += 1
            late = loop.wait(k)
            if self.restart_clock or self.paused:  # a reset or pause came while it slept
                k -= 1
                continue
            if late > self.settings.max_lag:
                k = self.fell_behind(k, late, loop.due_index(self.clock()))
                if self.fault is not None:
                    continue
                late = max(0.0, self.clock() - loop.deadline(k))
            if not self.tick(loop.deadline(k), late):
                k -= 1  # the same sample and deadline again, without waiting
        with self.lock:
            self._flush_block()

    def _warm_up(self) -> None:
        """One sample integrated and undone: the compiled kernel's first call (about 10 ms) is not a tick."""
        with self.lock:
            saved = self.integrator.snapshot()
            with contextlib.suppress(ValueError, ArithmeticError, RuntimeError):
                self.integrator.advance_bounded(self.latest_band, self.settings.tick_step_attempts)
            self.integrator.restore(saved)

    def _start_loop(self) -> tuple[DeadlineLoop, int]:
        """Deadlines from now for the segment (start, reset, resume); the initial state if not yet."""
        with self.lock:
            loop = DeadlineLoop(self.period, self.clock())
            if not self._emitted_initial:
                self.segment_start = loop.start
            else:  # a resume: the samples already emitted keep their due times
                loop.start -= self.published * self.period
                self.segment_start = loop.start
            self.emit_initial()
            self._flush_block()  # at once: its flow_progress tells the band source where we are
            return loop, self.published - 1

    # ---- integration and output ----------------------------------------------------------
    @overload
    def _advance(self, band: float) -> Trajectory: ...
    @overload
    def _advance(self, band: float, max_attempts: int) -> Trajectory | None: ...

    def _advance(self, band: float, max_attempts: int | None = None) -> Trajectory | None:
        """One sample; a failed one restarts the rig at equilibrium at the next sample time.

        Restarting there (not at t = 0) keeps rig time monotonic and the sample count right, so a
        sim run still completes and belt_drive's flow control does not stall. With `max_attempts`
        (realtime ticks) None means the sample is unfinished: call again with the same band value.
        """
        t_next = self.integrator.time + self.integrator.dt
        try:
            if max_attempts is None:
                traj = self.integrator.advance(np.array([band]))
            else:
                bounded = self.integrator.advance_bounded(band, max_attempts)
                if bounded is None:
                    return None
                traj = bounded
            if math.isfinite(traj.displacement[0]) and math.isfinite(traj.velocity[0]):
                return traj
            problem = "non-finite state"
        except (ValueError, ArithmeticError, RuntimeError) as exc:
            problem = str(exc)
        self.integration_errors += 1
        self.log(
            "error",
            f"integration failed at t = {t_next:.6g} s ({problem}); rig restarted at equilibrium "
            f"for band velocity {band!r} m/s",
        )
        self.integrator.reset(band_velocity=band, time=t_next)
        return self.integrator.current()

    def _emit(self, traj: Trajectory, lateness: float) -> None:
        """Emit a one-sample trajectory (wall-clock modes): on_sample, and into the block buffer."""
        x = float(traj.displacement[0])
        v = float(traj.velocity[0])
        mu = float(traj.friction_coefficient[0])
        if not (math.isfinite(x) and math.isfinite(v) and math.isfinite(mu)):
            return  # never published (cannot happen after _advance's check; kept as the last guard)
        t, band = float(traj.time[0]), float(traj.band_velocity[0])
        force = mu * self.config.rig.friction.normal_force
        sample = PlantSample(t, x, v, mu, band, self.travel.add(t, band), force,
                             float(traj.relative_velocity[0]), self.published, self.segment)
        self.published += 1
        self.lag = lateness
        self.max_late = max(self.max_late, lateness)
        self.on_sample(sample)
        block = self.blocks.add(sample, lateness)
        if block is not None:
            self.on_block(block)

    def _flush_block(self) -> None:
        block = self.blocks.flush()
        if block is not None:
            self.on_block(block)

    def _emit_block(self, traj: Trajectory) -> None:
        """Stepped modes: emit consecutive samples as one PlantBlock, then each by on_sample."""
        keep = np.isfinite(traj.displacement) & np.isfinite(traj.velocity)
        keep &= np.isfinite(traj.friction_coefficient)
        if not keep.all():  # never published (cannot happen after _advance's check; last guard)
            traj = Trajectory(**{name: getattr(traj, name)[keep] for name, _ in Trajectory.COLUMNS})
        if not len(traj):
            return
        # rig time from the sample index, k / sample_rate as core.run.simulate has it (the
        # integrator's own clock adds dt per sample and so depends on where blocks start)
        t = (self.published + np.arange(len(traj), dtype=float)) * self.integrator.dt
        band = traj.band_velocity
        block = PlantBlock(
            segment=self.segment,
            first_sample_index=self.published,
            sample_period=self.period,
            time=t,
            displacement=traj.displacement,
            velocity=traj.velocity,
            friction_coefficient=traj.friction_coefficient,
            friction_force=traj.friction_coefficient * self.config.rig.friction.normal_force,
            band_velocity=band,
            relative_velocity=traj.relative_velocity,
            belt_travel=self.travel.add_many(t, band),
        )
        self.published += len(block)
        self.on_block(block)
        if self.on_sample is not _nothing:
            for sample in block.samples():
                self.on_sample(sample)
        if self.mode == "lockstep":
            self._emitted_at = self.clock()

    # ---- diagnostics ---------------------------------------------------------------------
    def input_age(self) -> float | None:
        """Seconds since the latest good band value (None: none yet)."""
        recv = self.latest_band_recv
        return None if recv is None else self.clock() - recv

    def stale(self) -> bool:
        """Wall-clock modes, running, once band input has started: none for more than stale_timeout."""
        age = self.input_age()
        return not self.stepped and not self.paused and age is not None and age > self.settings.stale_timeout

    def stalled(self) -> float | None:
        """Stepped: seconds without a band sample while the run should progress (> STALL_S), else None."""
        age = self.input_age()
        if self.mode != "sim" or self.paused or self.complete or age is None or age <= STALL_S:
            return None
        return age

    def _timing_status(self) -> tuple[Level, str]:
        stalled = self.stalled()
        if stalled is not None:
            return "error", (
                f"stalled: no band sample for {stalled:.1f} s at rig time "
                f"{self.integrator.time:.3f} s ({self.sample_index} of {self.total} samples); "
                "belt_drive waits for the plant or a required consumer (flow_progress)"
            )
        if self.fault is not None:
            return "error", self.fault
        if self.stepped:
            return "ok", "complete" if self.complete else "running"
        samples = self.ticks
        share = self.misses / samples if samples else 0.0
        skipped = self.skipped - self._skipped_reported
        level: Level = "warn" if share > MISS_SHARE_WARN else "ok"
        message = f"{self.misses} deadline misses in {samples} samples"
        if skipped:
            level = "error"
            message = (
                f"fell behind real time by more than max_lag {1e3 * self.settings.max_lag:g} ms: "
                f"{skipped} samples skipped since the last report ({self.skipped} in "
                f"{self.skip_events} gaps so far); " + message
            )
        overran = self.overruns - self._overruns_reported
        if overran:
            level = "warn" if level == "ok" else level
            message += (
                f"; {overran} tick overrun(s) since the last report (a sample needed more "
                f"than tick_step_attempts={self.settings.tick_step_attempts} step attempts "
                "and was finished by further calls)"
            )
        return level, message

    def diagnostics(self) -> list[Status]:
        """The timing and band-input statuses; starts a new 'since last report' count."""
        with self.lock:
            level, message = self._timing_status()
            p50, p99 = self.latencies.percentiles()
            samples = self.ticks if not self.stepped else self.sample_index
            share = self.misses / samples if samples else 0.0
            values = [
                ("mode", self.mode),
                ("rig_time_s", f"{self.integrator.time:.6f}"),
                ("samples", str(samples)),
                ("deadline_misses", str(self.misses)),
                ("deadline_miss_share", f"{share:.6f}"),
                ("max_lateness_s", f"{self.max_late:.6f}"),
                ("lag_s", f"{self.lag:.6f}"),
                ("lag_bound_s", f"{self.settings.max_lag:g}"),
                ("lag_policy", self.settings.lag_policy),
                ("skipped_samples", str(self.skipped)),
                ("skip_events", str(self.skip_events)),
                ("held_real_time", str(self.held_real_time).lower()),
                ("latency_p50_s", f"{p50:.6f}"),
                ("latency_p99_s", f"{p99:.6f}"),
                ("latency_samples", str(self.latencies.count)),
                ("integration_errors", str(self.integration_errors)),
                ("tick_overruns", str(self.overruns)),
                ("paused", str(self.paused).lower()),
                ("run_complete", str(self.complete).lower()),
            ]
            if self.mode == "lockstep":
                r50, r99 = self.round_trips.percentiles()
                values += [("round_trip_p50_s", f"{r50:.6f}"), ("round_trip_p99_s", f"{r99:.6f}"),
                           ("round_trips", str(self.round_trips.count))]
            self._overruns_reported = self.overruns
            self._skipped_reported = self.skipped
            timing = Status(name="timing", hardware_id=HARDWARE_ID, level=level, message=message,
                            values=tuple(values))
            age = self.input_age()
            stale = self.stale()
            problems = []
            if stale:
                problems.append("stale input, holding last good value")
            if self.rejected_since_report:
                problems.append(f"{self.rejected_since_report} bad band value(s) rejected")
            waiting = not self.stepped and age is None
            band = Status(
                name="band input",
                hardware_id=HARDWARE_ID,
                level="warn" if problems else "ok",
                message="; ".join(problems) or ("waiting for band input" if waiting else "ok"),
                values=(
                    ("received", str(self.received)),
                    ("rejected", str(self.rejected)),
                    ("rejected_since_last_report", str(self.rejected_since_report)),
                    ("last_rejected_value", repr(self.last_rejected)),
                    ("valid_range_m_s", f"finite, |v| <= {self.settings.band_velocity_limit:g}"),
                    ("held_band_velocity_m_s", repr(self.latest_band)),
                    ("stale", str(stale).lower()),
                    ("input_age_s", "none" if age is None else f"{age:.4f}"),
                    ("stale_timeout_s", f"{self.settings.stale_timeout:g}"),
                    ("ignored_after_run_end", str(self.ignored_after_end)),
                    ("segment", str(self.segment)),
                    ("stale_blocks", str(self.stale_blocks)),
                    ("index_gaps", str(self.index_gaps)),
                    ("repeated_blocks", str(self.repeated_blocks)),
                    ("held_samples", str(self.held_samples)),
                    ("late_band_samples", str(self._band_ahead.late)),
                    ("queue_overflow", str(self.rt_overflow + self._band_ahead.overflow)),
                ),
            )
            self.rejected_since_report = 0
            return [timing, band]
