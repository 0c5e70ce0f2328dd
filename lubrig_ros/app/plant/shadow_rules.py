"""``rig_in_loop`` with shadow: the wall-clock rules plus the numbering that pairs measured values.

`ShadowRules` is `WallClockRules` (app/plant/wallclock.py) that also numbers the band values as
the rig sent them, remembers the number of the value each published sample was integrated with,
and hands both sides to an app.plant.shadow.ShadowPairing. The session uses it instead of
WallClockRules only when the plant's `shadow` setting is on, so without shadow the real-time path
is unchanged. The rules (numbering, pairing) are documented once, in app/plant/session.py
("Shadow"). Every method is called with the session's lock held.
"""

from __future__ import annotations

from collections import deque

import numpy as np
from typing_extensions import override

from ..interface.diagnostics import Status
from .diagnostics import HARDWARE_ID
from .output import PlantSample
from .shadow import ShadowPairing, ShadowSamples
from .state import PlantState
from .wallclock import WallClockRules


class ShadowRules(WallClockRules):
    """``rig_in_loop`` whose published samples are paired with the rig's measured displacement."""

    def __init__(self, session: PlantState) -> None:
        super().__init__(session)
        # one second of numbers waits for its partner (a measured value comes after its sample)
        self.pairing = ShadowPairing(self.queue.maxlen or 1)
        self.numbers: deque[int] = deque(maxlen=self.queue.maxlen)  # of the queued block values
        self.latest_number: int | None = None  # of the newest Float64 value, until a tick takes it
        self.used_number: int | None = None  # of the band value of the sample in progress
        self.received_before = 0  # band values received before this segment (the first: none)
        self.rejected_reported = 0
        # the session's per-sample sink, wrapped to keep the newest sample emitted (what a tick
        # published: its index, displacement and band value), cheaper than asking the integrator
        self.emitted: PlantSample | None = None
        self._sink = session.on_sample
        session.on_sample = self._on_sample

    def _on_sample(self, sample: PlantSample) -> None:
        self.emitted = sample
        self._sink(sample)

    # ---- input ---------------------------------------------------------------------------
    @override
    def band_value(self, value: float, now: float) -> None:
        super().band_value(value, now)
        self.numbers.clear()
        # every band message of the segment counts, rejected ones too (the session counted it)
        self.latest_number = self.s.received - 1 - self.received_before

    @override
    def band_values(
        self, band: np.ndarray, good: np.ndarray, segment: int | None, first: int | None, now: float
    ) -> int:
        kept = super().band_values(band, good, segment, first, now)
        start = first if first is not None else self.s.received - band.size - self.received_before
        self.numbers.extend((int(start) + np.flatnonzero(good)).tolist())
        return kept

    def measured_value(self, value: float) -> bool:
        """The rig's next measured displacement (m); False if rejected."""
        return self.pairing.measured_value(value)

    @override
    def next_band(self) -> tuple[float, float | None]:
        from_queue, fresh = bool(self.queue), self.new_band
        value, recv = super().next_band()
        if from_queue:
            self.used_number = self.numbers.popleft() if self.numbers else None
        elif fresh:
            self.used_number, self.latest_number = self.latest_number, None
        else:  # a held value: no band value of the rig's answers this sample
            self.used_number = None
        return value, recv

    # ---- output --------------------------------------------------------------------------
    @override
    def tick(self, deadline: float | None = None, late: float = 0.0) -> bool:
        s = self.s
        with s.lock:
            emitted = super().tick(deadline, late)
            sample = self.emitted
            if emitted and sample is not None and self.used_number is not None:
                self.pairing.simulated(
                    self.used_number, sample.sample_index, sample.displacement, sample.band_velocity
                )
                self.used_number = None
            return emitted

    def take(self) -> ShadowSamples | None:
        """The pairs made since the last call (app.plant.shadow.ShadowPairing.take)."""
        return self.pairing.take()

    @override
    def reset(self) -> None:
        super().reset()
        self.numbers.clear()
        self.latest_number = self.used_number = None
        self.received_before = self.s.received
        self.pairing.reset(self.s.segment)

    def status(self) -> Status:
        """The "shadow" diagnostic status: measured values taken, rejected, paired, residual RMS."""
        p = self.pairing
        new_rejects = p.rejected - self.rejected_reported
        self.rejected_reported = p.rejected
        waiting = p.measured_count == 0
        problem = f"{new_rejects} bad measured value(s) rejected" if new_rejects > 0 else ""
        return Status(
            name="shadow",
            hardware_id=HARDWARE_ID,
            level="warn" if problem else "ok",
            message=problem or ("waiting for measured displacement" if waiting else "ok"),
            values=(
                ("measured_received", str(p.measured_count)),
                ("measured_rejected", str(p.rejected)),
                ("last_rejected_value", repr(p.last_rejected)),
                ("paired", str(p.paired)),
                ("unpaired", str(p.unpaired)),
                ("residual_rms_m", repr(p.rms)),
                ("segment", str(self.s.segment)),
            ),
        )
