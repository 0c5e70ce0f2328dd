"""The plant's rules without ROS: band sample sequencing, pause/reset, input checks, timing.

`PlantSession` is everything the plant node does that is not ROS. The node feeds it band values
(`band_input`, one value; `band_block`, consecutive values), runs `run_realtime` on its loop
thread in the realtime modes, forwards reset/pause requests and parameter updates, and publishes
what the session hands to its sinks (`on_sample` per sample, `on_block` per block of samples,
`on_complete`, `on_fault`, `on_failure`, `log`).

Modes (app/interface/contract.MODES), in two families:

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
mode: counted, the last one reported, never integrated.

Integration failure: a sample that cannot be integrated (an exception of the integrator, or a
non-finite state) is never emitted, and nothing is made up in its place. The session goes to a
fault (`fault`: the rig time, the band value and the parameters that made it fail), logs it once
(ERROR) and calls `on_failure` once; the timing status is ERROR with it. Stepped modes: the
samples before it are emitted, band input after it is counted (`ignored_after_end`) and dropped,
the run does not complete (the sim plant node then ends with EXIT_INTEGRATION_FAILED). Wall-clock
modes: no output until a reset, which clears the fault (docs/nodes.md).

Shadow (``rig_in_loop`` with the `shadow` setting; app/plant/shadow_rules.py, app/plant/shadow.py): the real
rig also sends its measured displacement, one value per message (`measured_input`), and each is
paired with the published sample it answers, by the band value both belong to. Band values are
numbered as the rig sent them in the segment: a Float64 band value by its message's place (0, 1,
2, ...; rejected ones keep their number), a block's value i by the block's first_sample_index + i.
Measured values are numbered by their message's place in the segment (rejected ones too). A
published sample carries the number of the band value it was integrated with; a sample integrated
with a held value (no new value came for it), and the initial state, carry none and are not
paired. The measured value numbered n pairs with the sample integrated with band value n,
whichever of the two arrives first (a measured value normally comes after its sample); the
residual is measured − simulated displacement, and its running RMS is over every pair of the
segment so far. So the pairing does not depend on when the messages arrive: a rig that sends its
band ahead in blocks (the plant takes one value per tick, in order) and its measured values in the
same order gets the residual of the very same band history. A value not paired within one second
of numbers (a band value replaced before a tick took it, a skipped sample) is dropped and counted
(`unpaired`); a measured value that is not finite or exceeds app/plant/shadow.MEASURED_LIMIT (1 m) in
magnitude is rejected and counted, never paired. A reset restarts both numberings and the RMS (the
rig restarts its numbering on the new segment, as belt_drive does). The pairs made are handed to
the node with every block (`shadow_take`: a ShadowBlock beside each state_block); the "shadow"
status counts them. Without `shadow` the rules are WallClockRules unchanged.

Thread safety: every public method takes the session's lock, so the real-time loop thread and the
executor's callbacks may call it concurrently; sinks are called with the lock held (in order).

Where it lives: this module holds the shared state, configuration, input checks and output; what
differs by mode is a `ModeRules` object from MODE_RULES (app/plant/modes.py: sim, lockstep;
app/plant/wallclock.py: realtime, rig_in_loop); the statuses are app/plant/diagnostics.py.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from ...core.params import ParameterError
from ...core.presets import RunConfig
from ...core.run import integrator_for
from ..interface.diagnostics import Status
from .config import (
    CONFIG_PARAMETERS,
    RUNTIME_PARAMETERS,
    config_from,
    config_parameters,
    law_of,
    parameter_defaults,
    runtime_parameters,
)
from .diagnostics import STALL_S, diagnostics
from .modes import LockstepRules, ModeRules, SteppedRules
from .output import BeltTravel, PlantBlock, PlantSample
from .shadow import ShadowSamples
from .shadow_rules import ShadowRules
from .state import PlantSettings, PlantState
from .wallclock import IndexedRules, WallClockRules

__all__ = [
    "CONFIG_PARAMETERS",
    "MODE_RULES",
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

#: The rules of each mode of app/interface/contract.MODES (a class taking the session).
MODE_RULES: dict[str, Callable[[PlantState], ModeRules]] = {
    "sim": SteppedRules,
    "lockstep": LockstepRules,
    "realtime": IndexedRules,
    "rig_in_loop": WallClockRules,
}


class PlantSession(PlantState):
    """The plant's rules over its state (see the module docstring)."""

    @functools.cached_property
    def rules(self) -> ModeRules:
        """The rules of this session's mode (MODE_RULES; rig_in_loop with shadow: ShadowRules)."""
        if self.settings.shadow and self.mode == "rig_in_loop":
            return ShadowRules(self)
        return MODE_RULES[self.mode](self)

    @property
    def stepped(self) -> bool:
        """Rig time is the session's own (sim, lockstep), not the wall clock's."""
        return self.rules.stepped

    # ---- configuration -------------------------------------------------------------------
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
        restarts at equilibrium for the band value it holds (at rest, with a warning, when that
        value is below the velocity the integrator resolves: a band at rest in all but name), the
        loop restarts its deadlines (`restart_clock`) and emits the initial state; a `stop` fault
        is cleared.
        """
        with self.lock:
            self.flush_block()
            self.config = config
            self.integrator = integrator_for(config)
            self.total = config.samples
            self.sample_index = 0
            self.segment += 1
            self.published = 0
            self.complete = False
            self.blocks.clear()
            self.emitted_initial = False
            self.fault = None
            self.travel = BeltTravel()
            self.on_complete(False)
            self.rules.reset()

    def set_paused(self, paused: bool) -> str:
        """Pause (True) or resume; returns 'paused' or 'running'. Stepped: resuming drains the queue."""
        with self.lock:
            was = self.paused
            self.paused = bool(paused)
            self.rules.set_paused(self.paused, was)
            return "paused" if self.paused else "running"

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
            self.rules.band_value(value, now)
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
        realtime: the values are kept for their sample indices (a block of another segment is
        dropped too); rig_in_loop: they serve one per tick, in order.
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
            return self.rules.band_values(band, good, segment, first_sample_index, now)

    def measured_input(self, value: float) -> bool:
        """Shadow: the rig's next measured displacement (m); False if rejected or not in shadow."""
        with self.lock:
            rules = self.rules
            return isinstance(rules, ShadowRules) and rules.measured_value(value)

    def shadow_take(self) -> ShadowSamples | None:
        """Shadow: the pairs made since the last call, in sample order (None: none, or no shadow)."""
        with self.lock:
            rules = self.rules
            return rules.take() if isinstance(rules, ShadowRules) else None

    # ---- the modes' entry points ---------------------------------------------------------
    def emit_initial(self) -> None:
        """Emit the current state once (sim: done with the first block; other modes: at start)."""
        with self.lock:
            if not self.emitted_initial:
                self.emitted_initial = True
                self.rules.emit_initial()

    def run_realtime(self, stopped: Callable[[], bool]) -> None:
        """Wall-clock modes: emit the initial state, then tick at the sample rate until stopped().

        Absolute deadlines (app.timing.DeadlineLoop, no spinning); paused: wait; after a reset or
        a resume the deadlines restart from now. An overrun tick is retried at once for the same
        deadline (the loop sees stop, pause and reset between the calls, and other threads get
        the GIL, which the compiled integrator holds). Past max_lag: `fell_behind`. Exceptions
        of a tick propagate to the caller.
        """
        self._wall_clock().run(stopped)

    def tick(self, deadline: float | None = None, late: float = 0.0) -> bool:
        """Wall-clock modes: advance one sample and emit it; True if emitted.

        `deadline` (clock() time the sample was due) feeds the timing statistics: the sample's
        lateness is the time from its deadline to its completion; more than one period is a
        deadline miss. `late` is how late the tick started (kept for callers without a
        deadline). At most `tick_step_attempts` integrator steps per call: a sample that needs
        more is an overrun (False, nothing emitted), and the next call carries on with it.
        """
        return self._wall_clock().tick(deadline, late)

    def fell_behind(self, k: int, late: float, due_index: int) -> int:
        """Wall-clock modes: sample k starts `late` s after its due time (see WallClockRules.fell_behind)."""
        return self._wall_clock().fell_behind(k, late, due_index)

    def _wall_clock(self) -> WallClockRules:
        if not isinstance(self.rules, WallClockRules):
            raise RuntimeError(f"mode {self.mode!r} steps with its band input; it has no real-time loop")
        return self.rules

    # ---- diagnostics ---------------------------------------------------------------------
    def stale(self) -> bool:
        """Wall-clock modes, running, once band input has started: none for more than stale_timeout."""
        age = self.input_age()
        return not self.stepped and not self.paused and age is not None and age > self.settings.stale_timeout

    def stalled(self) -> float | None:
        """Sim: seconds without a band sample while the run should progress (> STALL_S), else None."""
        age = self.input_age()
        if not self.rules.reports_stall or self.paused or self.complete or age is None or age <= STALL_S:
            return None
        return age

    def diagnostics(self) -> list[Status]:
        """The timing and band-input statuses (app/plant/diagnostics); a new 'since last report' count."""
        with self.lock:
            statuses = diagnostics(self, self.rules, stale=self.stale(), stalled=self.stalled())
            if isinstance(self.rules, ShadowRules):
                statuses.append(self.rules.status())
            return statuses
