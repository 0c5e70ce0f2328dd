"""The plant's rules without ROS: band sample sequencing, pause/reset, input checks, timing.

`PlantSession` is everything the plant node does that is not ROS. The node feeds it band values
(`band_input`, one value; `band_block`, consecutive values), calls `tick` from its real-time loop,
forwards reset/pause requests and parameter updates, and publishes what the session hands to its
sinks (`on_sample` per sample, `on_block` per integrated block, `on_complete`, `log`).

Modes (app/contract.MODES):

* ``sim``: rig time is the session's own. Band values are queued and integrated strictly in
  order, one sample per band value, a block (`band_block`) as one call of the same core stepper
  core.run.simulate uses (RigIntegrator.advance); the block's samples go to `on_block` as one
  `PlantBlock` (the first block of a segment starts with the initial state, sample_index 0) and,
  if an `on_sample` sink is given, one by one. The run is deterministic, equal to
  core.run.simulate sample for sample whatever the block length; `on_complete(True)` once
  `duration` is reached, band values after that are counted (`ignored_after_end`) and dropped.
  A block stamped with another segment than the current one (sent before a reset) is dropped
  and counted (`stale_blocks`).
* ``realtime`` / ``rig_in_loop``: `tick` advances one sample with the latest good band value
  (held while no new one arrives); the values of a band block are used one per tick, in order.
  The caller paces the ticks; the session keeps the timing statistics (deadline misses,
  lateness, band→state latency) and the staleness of the input.

Segments: `segment` is 0 from the start and +1 at every `reset`; `sample_index` and rig time
restart at 0 with it. `published` counts the samples emitted in the current segment (the
initial state included): what the plant reports on flow_progress (app/flow.py).

Band values that are not finite or exceed `band_velocity_limit` in magnitude are rejected in every
mode: counted, the last one reported, never integrated. A sample whose integration fails (an
exception or a non-finite state) restarts the rig at equilibrium for that band velocity at the
next sample time, so rig time stays monotonic and a sim run still completes.

Thread safety: every public method takes the session's lock, so the real-time loop thread and the
executor's callbacks may call it concurrently; sinks are called with the lock held (in order).
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, replace
from typing import Any, NamedTuple, overload

import numpy as np

from ..core.friction_laws import law_parameters
from ..core.integrator import RigIntegrator
from ..core.params import ParameterError
from ..core.presets import RunConfig, from_mapping
from ..core.run import integrator_for
from ..core.trajectory import Trajectory, concatenate
from .contract import (
    DEFAULT_TICK_STEP_ATTEMPTS,
    MODES,
    RIG_FIELDS,
    friction_fields,
    plant_parameters,
)
from .diagnostics import Level, Status
from .timing import DeadlineLoop, LatencyHistogram


def law_of(config: RunConfig) -> str:
    """Name of the friction law of a run configuration (core.friction_laws registry)."""
    return str(type(config.rig.friction).law)


def config_parameters(law: str) -> tuple[str, ...]:
    """Plant parameters that rebuild the run configuration (contract entries with `from_config`)."""
    return tuple(p.name for p in plant_parameters(law) if p.from_config)


def runtime_parameters(law: str) -> frozenset[str]:
    """Of these, the ones that may change at run time (applied at the next reset)."""
    return frozenset(p.name for p in plant_parameters(law) if p.from_config and not p.read_only)


#: config_parameters / runtime_parameters of the default (junction-kinetics) law.
CONFIG_PARAMETERS: tuple[str, ...] = config_parameters("junction_kinetics")
RUNTIME_PARAMETERS: frozenset[str] = runtime_parameters("junction_kinetics")
HARDWARE_ID = "lubrig_plant"
#: Share of deadline misses above which the timing status is WARN.
MISS_SHARE_WARN = 1e-3
#: Sim: a run that has started, is neither paused nor complete, and got no band sample for this
#: long is reported as stalled (timing status ERROR); back to ok when samples flow again.
STALL_S = 1.0


class PlantSample(NamedTuple):
    """One output sample: what the plant publishes (SI units). A tuple: cheap to make per sample."""

    time: float  # s, rig time
    displacement: float  # m
    velocity: float  # m/s
    friction_coefficient: float  # 1
    band_velocity: float  # m/s, the band velocity this sample was integrated with
    belt_travel: float  # m, integral of the band velocity since the last reset
    friction_force: float  # N, μ · normal force
    relative_velocity: float = 0.0  # m/s, v_band − γ ẋ
    sample_index: int = 0  # samples emitted in this segment before this one
    segment: int = 0  # 0 at start, +1 per reset


@dataclass(frozen=True)
class PlantBlock:
    """Consecutive output samples of one segment (SI units): what a sim plant publishes per block.

    Sample i has rig time `time[i]` and sample index first_sample_index + i.
    """

    segment: int
    first_sample_index: int
    sample_period: float  # s
    time: np.ndarray  # s
    displacement: np.ndarray  # m
    velocity: np.ndarray  # m/s
    friction_coefficient: np.ndarray  # 1
    friction_force: np.ndarray  # N
    band_velocity: np.ndarray  # m/s
    relative_velocity: np.ndarray  # m/s
    belt_travel: np.ndarray  # m

    def __len__(self) -> int:
        return int(self.time.size)

    def samples(self) -> list[PlantSample]:
        """The block as PlantSample tuples."""
        return [
            PlantSample(
                float(self.time[i]), float(self.displacement[i]), float(self.velocity[i]),
                float(self.friction_coefficient[i]), float(self.band_velocity[i]),
                float(self.belt_travel[i]), float(self.friction_force[i]),
                float(self.relative_velocity[i]), self.first_sample_index + i, self.segment,
            )
            for i in range(len(self))
        ]


@dataclass(frozen=True)
class PlantSettings:
    """Read-only node settings (contract defaults)."""

    mode: str = "sim"
    band_velocity_limit: float = 1e-2
    stale_timeout: float = 0.05
    tick_step_attempts: int = DEFAULT_TICK_STEP_ATTEMPTS

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ParameterError(f"mode={self.mode!r} is not valid; expected one of {list(MODES)}")
        attempts = self.tick_step_attempts
        if isinstance(attempts, bool) or not isinstance(attempts, int) or attempts < 1:
            raise ParameterError(
                f"tick_step_attempts={attempts!r} is not valid; expected an integer >= 1"
            )
        for name in ("band_velocity_limit", "stale_timeout"):
            value = getattr(self, name)
            if not (isinstance(value, float | int) and math.isfinite(value) and value > 0.0):
                raise ParameterError(f"{name}={value!r} is not valid; expected a finite number > 0")


def _field(data: Mapping[str, Any], path: str) -> Any:
    for key in path.split("."):
        data = data[key]
    return data


def parameter_defaults(base: RunConfig, law: str | None = None) -> dict[str, Any]:
    """Default values of the configuration parameters (config_parameters(law)) from a run configuration.

    `law` None: the base's friction law. Another law than the base's takes its own parameter
    defaults (its dataclass's), with the base's normal force. ParameterError for an unknown law.
    """
    law = law or law_of(base)
    data = base.to_dict()
    if law == law_of(base):
        friction = asdict(base.rig.friction)
    else:
        friction = asdict(replace(law_parameters(law)(), normal_force=base.rig.normal_force))
    data["rig"]["friction"] = {"law": law, **friction}
    out: dict[str, Any] = {}
    for p in plant_parameters(law):
        if p.from_config:
            value = _field(data, p.from_config)
            if value is None and p.name == "velocity_coupling":
                value = 0.0  # no explicit γ: the convention's
            out[p.name] = float(value) if p.type == "double" else value
    return out


def config_from(base: RunConfig, values: Mapping[str, Any]) -> RunConfig:
    """The run configuration of `base` with the plant's configuration parameters applied.

    `values` maps parameter names (config_parameters of the law) to values; missing ones keep
    base's. `friction.law` (default: the base's law) selects the friction law whose
    `friction.<field>` values apply; fields not given take the base's values (same law) or the
    law's defaults. An empty `convention` means the base configuration's; `velocity_coupling`
    0 means the convention's γ, > 0 an explicit γ overriding it. ParameterError for invalid values.
    """
    law = values.get("friction.law") or law_of(base)
    defaults = parameter_defaults(base, law)

    def value(name: str) -> Any:
        return values[name] if name in values else defaults[name]

    data = base.to_dict()
    data["rig"].update({n: value(f"rig.{n}") for n in RIG_FIELDS})
    data["rig"]["convention"] = value("convention") or base.rig.convention
    gamma = value("velocity_coupling")  # 0: the convention's γ
    data["rig"]["velocity_coupling"] = float(gamma) if gamma else None
    friction = {n: value(f"friction.{n}") for n in friction_fields(law) if n != "normal_force"}
    friction["normal_force"] = value("rig.normal_force")
    friction["law"] = law
    data["rig"]["friction"] = friction
    data["simulation"].update(
        {n: value(n) for n in ("duration", "sample_rate", "rtol", "initial_perturbation")}
    )
    return from_mapping(data)


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
        log: Callable[[str, str], None] = _nothing,
        clock: Callable[[], float] = time.perf_counter,
        config: RunConfig | None = None,
    ) -> None:
        self.base = base
        self.settings = settings or PlantSettings()
        self.mode = self.settings.mode
        self.on_sample, self.on_complete, self.log, self.clock = on_sample, on_complete, log, clock
        self.on_block = on_block
        self.lock = threading.RLock()
        self.config = config if config is not None else base
        self.integrator: RigIntegrator = integrator_for(self.config)
        self.total = self.config.samples
        self.sample_index = 0  # band samples integrated in this segment
        self.segment = 0
        self.published = 0  # samples emitted in this segment (the initial state included)
        self.paused = False
        self.complete = False
        self.restart_clock = False  # realtime: the caller restarts its deadline loop (reset, resume)
        self._queue: deque[np.ndarray] = deque()  # sim: band blocks waiting (paused)
        self._rt_queue: deque[float] = deque(maxlen=max(1, round(self.config.sample_rate)))
        self.rt_overflow = 0  # realtime: block values dropped because more than 1 s was queued
        self.stale_blocks = 0  # sim: blocks of another segment than the current one (dropped)
        self.index_gaps = 0  # sim: blocks whose first_sample_index was not the next expected
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
        self.overruns = 0  # realtime: ticks whose sample ran out of step budget (nothing emitted)
        self._overruns_reported = 0
        self._pending_band: float | None = None  # realtime: band value of the sample in progress
        self._pending_recv: float | None = None
        # belt travel (trapezoid rule over the emitted samples)
        self.belt_travel = 0.0
        self._last_band: tuple[float, float] | None = None
        # timing (realtime)
        self.ticks = 0
        self.misses = 0
        self.max_late = 0.0
        self.latencies = LatencyHistogram()

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

        A new segment begins (`segment` + 1, `sample_index` and `published` 0). sim: the queue
        is dropped and the initial state is emitted again with the next band value; realtime /
        rig in the loop: the rig restarts at equilibrium for the band value it holds and the
        caller restarts its deadline loop (`restart_clock`).
        """
        with self.lock:
            self.config = config
            self.integrator = integrator_for(config)
            self.total = config.samples
            self.sample_index = 0
            self.segment += 1
            self.published = 0
            self.complete = False
            self._queue.clear()
            self._rt_queue.clear()
            self._pending_band = self._pending_recv = None
            self._emitted_initial = False
            if self.mode != "sim":
                self.integrator.reset(band_velocity=self.latest_band)
                self.restart_clock = True
            self.belt_travel, self._last_band = 0.0, None
            self.on_complete(False)

    def set_paused(self, paused: bool) -> str:
        """Pause (True) or resume; returns 'paused' or 'running'. sim: resuming drains the queue."""
        with self.lock:
            was = self.paused
            self.paused = bool(paused)
            if was and not self.paused and self.mode != "sim":
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
        """One band value from the topic; False if rejected. sim: integrates what it can."""
        now = self.clock()
        with self.lock:
            self.received += 1
            if not self.valid_band(value):
                self.rejected += 1
                self.rejected_since_report += 1
                self.last_rejected = value
                return False
            if self.mode == "sim":
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

        Every value is checked as in `band_input`; rejected ones are counted and skipped. sim:
        a block of another `segment` than the current one is dropped (`stale_blocks`); a
        `first_sample_index` that is not the next expected sample (samples integrated plus those
        queued) is counted (`index_gaps`) and logged, the values are integrated all the same
        (the flow control never sends one twice). realtime: the values serve one per tick.
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
                band = band[good]
            if self.mode != "sim":
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
                if first_sample_index != expected:
                    self.index_gaps += 1
                    self.log(
                        "warning",
                        f"band block starts at sample {first_sample_index}, expected {expected} "
                        f"(segment {self.segment})",
                    )
            if band.size:
                self.latest_band_recv = now  # sim: for the stall report (diagnostics)
                self._queue.append(band)
                self._drain()
            return int(band.size)

    # ---- sim -----------------------------------------------------------------------------
    def emit_initial(self) -> None:
        """Emit the current state once (sim: done before the first sample; realtime: at start)."""
        with self.lock:
            if not self._emitted_initial:
                self._emitted_initial = True
                if self.mode == "sim":
                    self._emit_block(self.integrator.current())
                else:
                    self._emit(self.integrator.current())

    def _drain(self) -> None:
        if self.mode != "sim":
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
                self.log("info", f"sim: run complete at t = {self.integrator.time:g} s")

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

    # ---- realtime / rig in the loop ------------------------------------------------------
    def tick(self, deadline: float | None = None, late: float = 0.0) -> bool:
        """Realtime: advance one sample with the latest good band value and emit it; True if emitted.

        `deadline` (clock() time the tick was due) and `late` (how late it started) feed the
        timing statistics: a tick that finishes more than one period after its deadline is a
        deadline miss; the latency from a new band value's arrival to its sample is recorded.
        At most `tick_step_attempts` integrator steps per call: a sample that needs more is an
        overrun (False, nothing emitted), and the next call carries on with the same band value.
        """
        with self.lock:
            if self._pending_band is None:
                recv = self.latest_band_recv if self.new_band else None
                self.new_band = False
                if self._rt_queue:
                    self.latest_band = self._rt_queue.popleft()
                    self.new_band = bool(self._rt_queue)
                self._pending_band, self._pending_recv = self.latest_band, recv
            traj = self._advance(self._pending_band, self.settings.tick_step_attempts)
            done = self.clock()
            self.max_late = max(self.max_late, late)
            if traj is None:  # the sample's step budget ran out: carry on at the next call
                self.overruns += 1
                return False
            recv, self._pending_band, self._pending_recv = self._pending_recv, None, None
            self._emit(traj)
            self._emitted_initial = True
            self.ticks += 1
            if recv is not None:
                self.latencies.add(done - recv)
            if deadline is not None and done - deadline > self.period:
                self.misses += 1
            return True

    def run_realtime(self, stopped: Callable[[], bool]) -> None:
        """Realtime: emit the initial state, then tick at the sample rate until stopped().

        Absolute deadlines (app.timing.DeadlineLoop); paused: wait; after a reset or a resume
        the deadlines restart from now. An overrun tick is retried at once for the same deadline
        (the loop sees stop, pause and reset between the calls, and other threads get the GIL,
        which the compiled integrator holds). Exceptions of a tick propagate to the caller.
        """
        loop = DeadlineLoop(self.period)
        k = 0
        self.emit_initial()
        while not stopped():
            if self.paused:
                time.sleep(0.01)
                continue
            if self.take_restart_clock():
                loop, k = DeadlineLoop(self.period), 0
            k += 1
            late = loop.wait(k)
            if not self.tick(loop.deadline(k), late):
                k -= 1  # the same sample and deadline again, without waiting

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

    def _emit(self, traj: Trajectory) -> None:
        """Emit a one-sample trajectory (realtime ticks, the realtime initial state)."""
        x = float(traj.displacement[0])
        v = float(traj.velocity[0])
        mu = float(traj.friction_coefficient[0])
        if not (math.isfinite(x) and math.isfinite(v) and math.isfinite(mu)):
            return  # never published (cannot happen after _advance's check; kept as the last guard)
        t, band = float(traj.time[0]), float(traj.band_velocity[0])
        if self._last_band is not None and t > self._last_band[0]:  # belt travel, trapezoid rule
            self.belt_travel += 0.5 * (band + self._last_band[1]) * (t - self._last_band[0])
        self._last_band = (t, band)
        force = mu * self.config.rig.friction.normal_force
        index = self.published
        self.published += 1
        self.on_sample(
            PlantSample(t, x, v, mu, band, self.belt_travel, force, float(traj.relative_velocity[0]),
                        index, self.segment)
        )

    def _emit_block(self, traj: Trajectory) -> None:
        """Emit consecutive samples as one PlantBlock (and per sample if on_sample is set)."""
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
        # belt travel, trapezoid rule, summed in sample order (as one addition per sample)
        steps = np.empty(t.size)
        if self._last_band is None:
            steps[0] = 0.0
        else:
            t0, b0 = self._last_band
            steps[0] = 0.5 * (band[0] + b0) * (t[0] - t0) if t[0] > t0 else 0.0
        steps[1:] = np.where(t[1:] > t[:-1], 0.5 * (band[1:] + band[:-1]) * (t[1:] - t[:-1]), 0.0)
        travel = np.cumsum(np.concatenate(([self.belt_travel], steps)))[1:]
        self.belt_travel = float(travel[-1])
        self._last_band = (float(t[-1]), float(band[-1]))
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
            belt_travel=travel,
        )
        self.published += len(block)
        self.on_block(block)
        if self.on_sample is not _nothing:
            for sample in block.samples():
                self.on_sample(sample)

    # ---- diagnostics ---------------------------------------------------------------------
    def input_age(self) -> float | None:
        """Seconds since the latest good band value (None: none yet)."""
        recv = self.latest_band_recv
        return None if recv is None else self.clock() - recv

    def stale(self) -> bool:
        """Realtime modes, running: no good band input for more than stale_timeout."""
        age = self.input_age()
        return (
            self.mode != "sim"
            and not self.paused
            and (age is None or age > self.settings.stale_timeout)
        )

    def stalled(self) -> float | None:
        """Sim: seconds without a band sample while the run should progress (> STALL_S), else None."""
        age = self.input_age()
        if self.mode != "sim" or self.paused or self.complete or age is None or age <= STALL_S:
            return None
        return age

    def diagnostics(self) -> list[Status]:
        """The timing and band-input statuses; starts a new 'rejected since last report' count."""
        with self.lock:
            stalled = self.stalled()
            p50, p99 = self.latencies.percentiles()
            samples = self.ticks if self.mode != "sim" else self.sample_index
            share = self.misses / samples if samples else 0.0
            level: Level
            if stalled is not None:
                level = "error"
                message = (
                    f"stalled: no band sample for {stalled:.1f} s at rig time "
                    f"{self.integrator.time:.3f} s ({self.sample_index} of {self.total} samples); "
                    "belt_drive waits for the plant or a required consumer (flow_progress)"
                )
            else:
                overran = self.overruns - self._overruns_reported
                level = "warn" if share > MISS_SHARE_WARN or overran else "ok"
                message = (
                    f"{self.misses} deadline misses in {samples} samples"
                    if self.mode != "sim"
                    else ("complete" if self.complete else "running")
                )
                if overran:
                    message += (
                        f"; {overran} tick overrun(s) since the last report (a sample needed more "
                        f"than tick_step_attempts={self.settings.tick_step_attempts} step attempts "
                        "and was finished by further calls)"
                    )
            self._overruns_reported = self.overruns
            timing = Status(
                name="timing",  # the node prefixes its fully qualified name
                hardware_id=HARDWARE_ID,
                level=level,
                message=message,
                values=(
                    ("mode", self.mode),
                    ("rig_time_s", f"{self.integrator.time:.6f}"),
                    ("samples", str(samples)),
                    ("deadline_misses", str(self.misses)),
                    ("deadline_miss_share", f"{share:.6f}"),
                    ("max_lateness_s", f"{self.max_late:.6f}"),
                    ("latency_p50_s", f"{p50:.6f}"),
                    ("latency_p99_s", f"{p99:.6f}"),
                    ("latency_samples", str(self.latencies.count)),
                    ("integration_errors", str(self.integration_errors)),
                    ("tick_overruns", str(self.overruns)),
                    ("paused", str(self.paused).lower()),
                    ("run_complete", str(self.complete).lower()),
                ),
            )
            age = self.input_age()
            stale = self.stale()
            problems = []
            if stale:
                problems.append("stale input, holding last good value")
            if self.rejected_since_report:
                problems.append(f"{self.rejected_since_report} bad band value(s) rejected")
            band = Status(
                name="band input",
                hardware_id=HARDWARE_ID,
                level="warn" if problems else "ok",
                message="; ".join(problems) or "ok",
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
                    ("queue_overflow", str(self.rt_overflow)),
                ),
            )
            self.rejected_since_report = 0
            return [timing, band]
