"""The plant's shared state without ROS: settings, counters, the integrator, and sample emission.

`PlantState` is what every mode of the plant works on: the run configuration and its
integrator, the segment and sample counters, the band input's bookkeeping, the timing
statistics, and the emission of samples to the sinks (`emit`: one sample of a wall-clock mode,
into the block buffer; `emit_block`: a stepped mode's block; `advance`: one sample, restarted
at equilibrium when its integration fails). app/plant/session.py builds the session on it and
documents the rules; the mode rules (app/plant/modes.py, app/plant/wallclock.py) change it.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...core.integrator import RigIntegrator
from ...core.params import ParameterError
from ...core.presets import RunConfig
from ...core.run import integrator_for
from ...core.trajectory import Trajectory, TrajectorySample
from ..interface.contract import (
    DEFAULT_LAG_POLICY,
    DEFAULT_MAX_LAG,
    DEFAULT_OUTPUT_BLOCK_LENGTH,
    DEFAULT_TICK_STEP_ATTEMPTS,
    LAG_POLICIES,
    MODES,
)
from ..timing import LatencyHistogram
from .output import (
    BeltTravel,
    BlockBuffer,
    PlantBlock,
    PlantSample,
    derive,
    trajectory_columns,
)


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
    shadow: bool = False  # rig_in_loop: pair the rig's measured displacement (app/plant/shadow_rules.py)

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
        if not isinstance(self.shadow, bool):
            raise ParameterError(f"shadow={self.shadow!r} is not valid; expected true or false")
        for name in ("band_velocity_limit", "stale_timeout", "max_lag"):
            value = getattr(self, name)
            if not (isinstance(value, float | int) and math.isfinite(value) and value > 0.0):
                raise ParameterError(f"{name}={value!r} is not valid; expected a finite number > 0")


def nothing(*_args: Any) -> None:
    """The default sink: drops what it is given."""
    return None


class PlantState:
    """The state every mode shares, and the emission of samples (see the module docstring)."""

    def __init__(
        self,
        base: RunConfig,
        settings: PlantSettings | None = None,
        *,
        on_sample: Callable[[PlantSample], None] = nothing,
        on_block: Callable[[PlantBlock], None] = nothing,
        on_complete: Callable[[bool], None] = nothing,
        on_fault: Callable[[str], None] = nothing,
        on_failure: Callable[[str], None] = nothing,
        log: Callable[[str, str], None] = nothing,
        clock: Callable[[], float] = time.monotonic,
        config: RunConfig | None = None,
    ) -> None:
        self.base = base
        self.settings = settings or PlantSettings()
        self.mode = self.settings.mode
        self.on_sample, self.on_complete, self.log, self.clock = on_sample, on_complete, log, clock
        self.on_block, self.on_fault, self.on_failure = on_block, on_fault, on_failure
        self.lock = threading.RLock()
        self.config = config if config is not None else base
        self.integrator: RigIntegrator = integrator_for(self.config)
        self.total = self.config.samples
        self.sample_index = 0  # band samples integrated in this segment
        self.segment = 0
        self.published = 0  # index of the next sample to emit in this segment
        self.paused = False
        self.complete = False
        self.restart_clock = False  # wall-clock modes: the loop restarts its deadlines (reset, resume)
        self.stale_blocks = 0  # blocks of another segment than the current one (dropped)
        self.index_gaps = 0  # stepped: blocks whose first_sample_index was not the next expected
        self.repeated_blocks = 0  # lockstep: blocks of samples already integrated (dropped)
        self.emitted_initial = False
        # band input bookkeeping
        self.latest_band = float(self.config.band(0.0))
        self.latest_band_recv: float | None = None  # clock() of the latest good value
        self.received = 0
        self.rejected = 0
        self.last_rejected: float | None = None
        self.rejected_since_report = 0
        self.ignored_after_end = 0
        self.integration_errors = 0
        self.held_samples = 0  # realtime: samples integrated with a held value (none sent for them)
        self.overruns = 0  # wall-clock: ticks whose sample ran out of step budget (nothing emitted)
        self.overruns_reported = 0
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
        self.skipped_reported = 0
        self.fault: str | None = None  # why nothing is emitted (lag_policy stop, integration failure)
        self.segment_start: float | None = None  # clock() due time of sample 0 of the segment
        self.held_real_time = True
        self.round_trips = LatencyHistogram()  # lockstep: state emitted -> next band value

    @property
    def time(self) -> float:
        """Rig time of the latest sample, s."""
        return float(self.integrator.time)

    @property
    def normal_force(self) -> float:
        """N of the run's configuration, N (friction force = μ · N)."""
        return float(self.config.rig.friction.normal_force)

    @property
    def period(self) -> float:
        """Sample period, s."""
        return 1.0 / self.config.sample_rate

    def take_restart_clock(self) -> bool:
        """True once after a reset or a resume in realtime modes (the caller restarts its loop)."""
        with self.lock:
            restart, self.restart_clock = self.restart_clock, False
            return restart

    # ---- integration and output ----------------------------------------------------------
    def advance(self, band: float, max_attempts: int | None = None) -> TrajectorySample | None:
        """One sample, or None: unfinished (its step budget ran out) or failed (`fail`).

        With `max_attempts` (wall-clock ticks) an unfinished sample carries on at the next call
        with the same band value. A failed one (an exception of the integrator, or a non-finite
        state) is never emitted: the integrator stays where it was and `fault` says why.
        """
        t_next = self.integrator.time + self.integrator.dt
        try:
            if max_attempts is None:
                sample = self.integrator.advance(np.array([band])).sample(0)
            else:
                bounded = self.integrator.advance_bounded(band, max_attempts)
                if bounded is None:
                    return None
                sample = bounded
            if math.isfinite(sample.displacement) and math.isfinite(sample.velocity):
                return sample
            problem = "non-finite state"
        except (ValueError, ArithmeticError, RuntimeError) as exc:
            problem = str(exc)
        self.fail(t_next, band, problem)
        return None

    def fail(self, t: float, band: float, problem: str) -> None:
        """The sample due at rig time t could not be integrated: the fault, ERROR once, on_failure.

        Nothing more is emitted until a reset (which clears the fault); the message names the
        time, the band value and the parameters that made it fail.
        """
        self.integration_errors += 1
        rig = self.config.rig
        self.fault = (
            f"integration failed at t = {t:.6g} s (sample {round(t * self.config.sample_rate)} of "
            f"segment {self.segment}) for band velocity {band!r} m/s: {problem}; parameters: "
            f"mass {rig.mass:g} kg, "
            f"natural_frequency {rig.natural_frequency:g} Hz, damping_ratio {rig.damping_ratio:g}, "
            f"{rig.coupling_label}, friction {rig.friction!r}, rtol {self.config.rtol:g}"
        )
        self.log("error", self.fault + "; no more output until a reset")
        self.on_failure(self.fault)

    def emit(self, sample: TrajectorySample, lateness: float) -> None:
        """Emit one sample (wall-clock modes): on_sample, and into the block buffer."""
        t = sample.time
        if not (
            math.isfinite(sample.displacement)
            and math.isfinite(sample.velocity)
            and math.isfinite(sample.friction_coefficient)
        ):
            return  # never published (cannot happen after advance's check; kept as the last guard)
        travel = self.travel.add(t, sample.band_velocity)
        values = derive(*sample[1:], travel, self.normal_force)
        out = PlantSample(t, values, self.published, self.segment)
        self.published += 1
        self.lag = lateness
        if lateness > self.max_late:
            self.max_late = lateness
        self.on_sample(out)
        block = self.blocks.add(out, lateness)
        if block is not None:
            self.on_block(block)

    def flush_block(self) -> None:
        """Emit the samples the block buffer holds (wall-clock modes; nothing otherwise)."""
        block = self.blocks.flush()
        if block is not None:
            self.on_block(block)

    def emit_block(self, traj: Trajectory) -> None:
        """Stepped modes: emit consecutive samples as one PlantBlock, then each by on_sample."""
        keep = np.isfinite(traj.displacement) & np.isfinite(traj.velocity)
        keep &= np.isfinite(traj.friction_coefficient)
        if not keep.all():  # never published (cannot happen after advance's check; last guard)
            traj = Trajectory(**{name: getattr(traj, name)[keep] for name, _ in Trajectory.COLUMNS})
        if not len(traj):
            return
        # rig time from the sample index, k / sample_rate as core.run.simulate has it (the
        # integrator's own clock adds dt per sample and so depends on where blocks start)
        t = (self.published + np.arange(len(traj), dtype=float)) * self.integrator.dt
        band = traj.band_velocity
        columns = trajectory_columns(traj, self.travel.add_many(t, band), self.normal_force)
        block = PlantBlock(
            segment=self.segment,
            first_sample_index=self.published,
            sample_period=self.period,
            time=t,
            columns=columns,
        )
        self.published += len(block)
        self.on_block(block)
        if self.on_sample is not nothing:
            for sample in block.samples():
                self.on_sample(sample)

    def input_age(self) -> float | None:
        """Seconds since the latest good band value (None: none yet)."""
        recv = self.latest_band_recv
        return None if recv is None else self.clock() - recv
