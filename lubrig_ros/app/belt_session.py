"""The belt_drive's session: the band profile, its updates, and which band samples go out when.

ROS-free: the belt_drive node (nodes/belt_drive.py) declares the parameters, feeds the plant's
flow progress in and publishes the band blocks this module returns.

- `ProfileState`: the running band profile from the `profile.*` parameters (every registered
  kind's fields, core/profiles.py), an update taken as a whole or refused with the reason (the
  running profile kept), and the cross-check with the plant's `band_velocity_limit` over the run.
- `SimSchedule` (mode sim): samples k = 1 … N of the current plant segment, v_band(k / rate),
  never beyond what the flow gate (app/flow.py) allows; a plant reset restarts the profile for the
  new segment; each block is stamped with the rig time of its first sample on the plant's clock
  (the plant's flow_progress stamps give the segment's origin: that clock goes on across resets).
- `AheadSchedule` (realtime modes): on every flow_progress of the plant, the band samples that keep
  `lookahead` samples ahead of it, each with its sample index, every index once and in order.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..core.params import ParameterError
from ..core.profiles import BandProfile, ProfileParameters, band_range_problem, profile_to_dict
from .flow import FlowGate
from .interface import cdr


@dataclass(frozen=True)
class BandBlock:
    """Band samples to publish: index `first_sample_index` and on, of `segment`, from `stamp_ns`."""

    segment: int
    first_sample_index: int  # the band index of the first value (plant sample index − 1)
    stamp_ns: int  # rig time (sim) or due time (realtime) of the first value, ns
    band_velocity: np.ndarray  # m/s


class ProfileState:
    """The band profile and its parameters (see the module docstring)."""

    def __init__(
        self, band: BandProfile, sample_rate: float, duration: float, band_velocity_limit: float
    ) -> None:
        self.parameters = ProfileParameters(band)
        self.sample_rate = sample_rate
        self.duration = duration
        self.band_velocity_limit = band_velocity_limit
        self.profile: BandProfile = band  # until start() applies what was given at start-up

    def start(self, given: Mapping[str, object]) -> None:
        """The values given at start-up (parameter file, command line) as one update.

        ParameterError naming the profile and the problem if they are refused.
        """
        profile = self.parameters.apply(dict(given))
        problem = self.problem(profile)
        if problem is not None:
            raise ParameterError(f"profile {profile_to_dict(profile)} refused: {problem}")
        self.profile = profile

    def problem(self, profile: BandProfile) -> str | None:
        """Cross-check with the plant: the profile over the run within band_velocity_limit."""
        return band_range_problem(profile, self.sample_rate, self.duration, self.band_velocity_limit)

    def completed(self, updates: Mapping[str, object]) -> dict[str, object]:
        """A change of kind also sets the new kind's own fields (ProfileParameters.completed)."""
        return self.parameters.completed(dict(updates))

    def update(self, updates: Mapping[str, object]) -> str | None:
        """Apply profile field updates as a whole; None if taken, else the reason (nothing changed)."""
        declared = self.parameters.flat()
        for name, value in updates.items():
            if name == "kind" or isinstance(declared.get(name), str):
                if not isinstance(value, str):
                    return f"profile.{name}={value!r} is not valid; expected a string"
            elif not isinstance(value, float | int) or isinstance(value, bool) or not math.isfinite(value):
                return f"profile.{name}={value!r} is not valid; expected a finite number"
        given = ", ".join(f"profile.{k}={v!r}" for k, v in updates.items())
        before = copy.deepcopy(self.parameters)  # a refused update leaves no trace
        try:
            profile = self.parameters.apply(dict(updates))
        except (ParameterError, ValueError, TypeError) as exc:
            self.parameters = before
            return f"{given} refused: {exc}"
        problem = self.problem(profile)
        if problem is not None:
            self.parameters = before
            return f"{given} refused: profile {profile_to_dict(profile)}: {problem}"
        self.profile = profile
        return None

    def samples(self, first_k: int, last_k: int) -> np.ndarray:
        """v_band(k / sample_rate) for k = first_k … last_k (m/s).

        The profile is checked over the run (`problem`), so its values are finite there; a
        non-finite value would be a profile outside its checked range and is sent as 0 m/s.
        """
        k = np.arange(first_k, last_k + 1, dtype=float)
        values = np.asarray(self.profile(k / self.sample_rate), dtype=float)
        return np.where(np.isfinite(values), values, 0.0)


def _stamp_ns(seconds: float) -> int:
    sec, nanosec = cdr.stamp_of(seconds)
    return sec * 1_000_000_000 + nanosec


class SimSchedule:
    """Sim mode: band blocks of the plant's current segment as far as the flow gate allows."""

    def __init__(self, gate: FlowGate, sample_rate: float, duration: float, block_length: int) -> None:
        self.gate = gate
        self.sample_rate = sample_rate
        self.total = round(duration * sample_rate)
        self.block_length = block_length
        self.segment: int | None = None
        self.next_k = 1  # next band sample of the current segment
        self._origin: tuple[int, int] = (0, 0)  # (segment, ROS time in ns of its t = 0)

    def progress(self, participant: str, segment: int, samples: int, stamp_ns: int) -> bool:
        """A flow_progress; True if it moved the gate (there may be more to send)."""
        if participant == self.gate.plant and segment > self._origin[0]:
            # the plant stamps flow_progress with the time of its newest sample, (samples − 1) /
            # rate into the segment (0 before the first), on its clock that runs on across resets
            self._origin = (segment, stamp_ns - _stamp_ns(max(samples - 1, 0) / self.sample_rate))
        return self.gate.report(participant, segment, samples)

    def restarted(self) -> int | None:
        """If the plant moved to another segment since the last call: its number (profile restarts)."""
        segment = self.gate.segment
        if segment is None or segment == self.segment:
            return None
        previous, self.segment, self.next_k = self.segment, segment, 1
        return segment if previous is not None else None

    @property
    def done(self) -> bool:
        """Every band sample of the current segment sent."""
        return self.next_k > self.total

    def blocks(self, profile: ProfileState) -> list[BandBlock]:
        """The blocks the gate allows now (at most block_length samples each, never beyond N)."""
        segment = self.gate.segment
        if segment is None:
            return []
        limit = self.gate.limit(self.total)
        out = []
        while self.next_k <= limit:
            n = min(self.block_length, limit - self.next_k + 1)
            origin = self._origin[1] if self._origin[0] == segment else 0
            stamp = max(0, origin + _stamp_ns(self.next_k / self.sample_rate))
            values = profile.samples(self.next_k, self.next_k + n - 1)
            out.append(BandBlock(segment, self.next_k - 1, stamp, values))
            self.next_k += n
        return out


class AheadSchedule:
    """Realtime modes: the band samples that keep `lookahead` ahead of the plant."""

    def __init__(self, plant: str, sample_rate: float, lookahead: int) -> None:
        self.plant = plant
        self.sample_rate = sample_rate
        self.lookahead = lookahead
        self.segment: int | None = None
        self.next_k = 1
        self.restarted_segment: int | None = None  # set when a progress moved to a new segment

    def progress(
        self, participant: str, segment: int, samples: int, stamp_ns: int, profile: ProfileState
    ) -> BandBlock | None:
        """A flow_progress of the plant: the next block to send, if any.

        The plant's next output sample is `samples`; band index j = k − 1 integrates its sample
        k, so it needs index samples − 1 next. Every index is sent once, in order, from 0: those
        the plant has passed are late (it counts them) but the band stream stays whole. The
        block's stamp is the due time of the plant sample its first value integrates (band index
        + 1), from the progress stamp: the due time of plant sample samples − 1.
        """
        if participant != self.plant:
            return None
        self.restarted_segment = None
        if segment != self.segment:
            if self.segment is not None:
                self.restarted_segment = segment
            self.segment, self.next_k = segment, 1
        first_k, last_k = self.next_k, samples + self.lookahead - 1
        if last_k < first_k:
            return None
        stamp = stamp_ns + _stamp_ns((first_k - samples + 1) / self.sample_rate)
        self.next_k = last_k + 1
        return BandBlock(segment, first_k - 1, stamp, profile.samples(first_k, last_k))
