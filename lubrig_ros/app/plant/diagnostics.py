"""The plant's diagnostics without ROS: its timing and band-input statuses, read off a PlantSession.

Two statuses (app.interface.diagnostics.Status, /diagnostics on the node): "timing" (rig time, deadline
misses, lateness, lag and the lag policy, skipped samples, tick overruns, the stall of a sim
run, the lockstep round trip) and "band input" (received, rejected, stale or held input, the
indexed and queued input's counters). Each report starts a new "since the last report" count.
"""

from __future__ import annotations

from ..interface.diagnostics import Level, Status
from .modes import ModeRules
from .state import PlantState

HARDWARE_ID = "lubrig_plant"
#: Sim: a run that has started, is neither paused nor complete, and got no band sample for this
#: long is reported as stalled (timing status ERROR); back to ok when samples flow again.
STALL_S = 1.0
#: Share of deadline misses above which the timing status is WARN.
MISS_SHARE_WARN = 1e-3


def timing_status(s: PlantState, rules: ModeRules, stalled: float | None) -> tuple[Level, str]:
    """The timing status's level and message (reads, does not reset, the since-last counts)."""
    if stalled is not None:
        return "error", (
            f"stalled: no band sample for {stalled:.1f} s at rig time "
            f"{s.integrator.time:.3f} s ({s.sample_index} of {s.total} samples); "
            "belt_drive waits for the plant or a required consumer (flow_progress)"
        )
    if s.fault is not None:
        return "error", s.fault
    if rules.stepped:
        return "ok", "complete" if s.complete else "running"
    samples = s.ticks
    share = s.misses / samples if samples else 0.0
    skipped = s.skipped - s.skipped_reported
    level: Level = "warn" if share > MISS_SHARE_WARN else "ok"
    message = f"{s.misses} deadline misses in {samples} samples"
    if skipped:
        level = "error"
        message = (
            f"fell behind real time by more than max_lag {1e3 * s.settings.max_lag:g} ms: "
            f"{skipped} samples skipped since the last report ({s.skipped} in "
            f"{s.skip_events} gaps so far); " + message
        )
    overran = s.overruns - s.overruns_reported
    if overran:
        level = "warn" if level == "ok" else level
        message += (
            f"; {overran} tick overrun(s) since the last report (a sample needed more "
            f"than tick_step_attempts={s.settings.tick_step_attempts} step attempts "
            "and was finished by further calls)"
        )
    return level, message


def _timing_values(s: PlantState, rules: ModeRules) -> list[tuple[str, str]]:
    p50, p99 = s.latencies.percentiles()
    samples = s.sample_index if rules.stepped else s.ticks
    share = s.misses / samples if samples else 0.0
    values = [
        ("mode", s.mode),
        ("rig_time_s", f"{s.integrator.time:.6f}"),
        ("samples", str(samples)),
        ("deadline_misses", str(s.misses)),
        ("deadline_miss_share", f"{share:.6f}"),
        ("max_lateness_s", f"{s.max_late:.6f}"),
        ("lag_s", f"{s.lag:.6f}"),
        ("lag_bound_s", f"{s.settings.max_lag:g}"),
        ("lag_policy", s.settings.lag_policy),
        ("skipped_samples", str(s.skipped)),
        ("skip_events", str(s.skip_events)),
        ("held_real_time", str(s.held_real_time).lower()),
        ("latency_p50_s", f"{p50:.6f}"),
        ("latency_p99_s", f"{p99:.6f}"),
        ("latency_samples", str(s.latencies.count)),
        ("integration_errors", str(s.integration_errors)),
        ("tick_overruns", str(s.overruns)),
        ("paused", str(s.paused).lower()),
        ("run_complete", str(s.complete).lower()),
    ]
    return values + rules.timing_values()


def _band_status(s: PlantState, rules: ModeRules, stale: bool) -> Status:
    age = s.input_age()
    problems = []
    if stale:
        problems.append("stale input, holding last good value")
    if s.rejected_since_report:
        problems.append(f"{s.rejected_since_report} bad band value(s) rejected")
    waiting = not rules.stepped and age is None
    return Status(
        name="band input",
        hardware_id=HARDWARE_ID,
        level="warn" if problems else "ok",
        message="; ".join(problems) or ("waiting for band input" if waiting else "ok"),
        values=(
            ("received", str(s.received)),
            ("rejected", str(s.rejected)),
            ("rejected_since_last_report", str(s.rejected_since_report)),
            ("last_rejected_value", repr(s.last_rejected)),
            ("valid_range_m_s", f"finite, |v| <= {s.settings.band_velocity_limit:g}"),
            ("held_band_velocity_m_s", repr(s.latest_band)),
            ("stale", str(stale).lower()),
            ("input_age_s", "none" if age is None else f"{age:.4f}"),
            ("stale_timeout_s", f"{s.settings.stale_timeout:g}"),
            ("ignored_after_run_end", str(s.ignored_after_end)),
            ("segment", str(s.segment)),
            ("stale_blocks", str(s.stale_blocks)),
            ("index_gaps", str(s.index_gaps)),
            ("repeated_blocks", str(s.repeated_blocks)),
            ("held_samples", str(s.held_samples)),
            ("late_band_samples", str(rules.late_band())),
            ("queue_overflow", str(rules.queue_overflow())),
        ),
    )


def diagnostics(s: PlantState, rules: ModeRules, *, stale: bool, stalled: float | None) -> list[Status]:
    """The timing and band-input statuses; starts a new "since the last report" count.

    `stale`: wall-clock input stopped for longer than stale_timeout; `stalled`: seconds a sim run
    has waited for band input past STALL_S (None: not stalled).
    """
    level, message = timing_status(s, rules, stalled)
    timing = Status(
        name="timing",
        hardware_id=HARDWARE_ID,
        level=level,
        message=message,
        values=tuple(_timing_values(s, rules)),
    )
    band = _band_status(s, rules, stale)
    s.overruns_reported = s.overruns
    s.skipped_reported = s.skipped
    s.rejected_since_report = 0
    return [timing, band]
