"""Sim-mode flow control without ROS: how far belt_drive may send band samples.

Every participant of a sim run reports on <ns>/flow_progress (lubrig_interfaces/FlowProgress)
how many samples of the rig's output it has taken in which segment:

* the plant: the state samples it has published in the current segment (the initial state,
  sample_index 0, counts as one; so after the first band block of n samples it reports n + 1);
* every required consumer (the recorder, a test probe, any node named in belt_drive's
  ``required_consumers``): the state samples it has taken in that segment (0 before the first);
  it reports once when it is ready (samples 0), after every block it took, and as a heartbeat.

`FlowGate` turns these reports into the highest band sample index belt_drive may send:
band sample k (1, 2, …) of a segment becomes state sample k, so a participant that has taken
s ≥ 1 state samples has covered band samples up to s − 1. The limit is the slowest participant's
covered band sample plus ``flow_window``. Nothing is sent until the plant and every required
consumer have reported. The result: at most ``flow_window`` + one block of samples are ever in
flight towards the slowest participant, whatever its speed, so a slow consumer slows the run
instead of losing samples (with reliable QoS and a history deep enough for that many blocks).

Segments: the plant's segment is the current one (it increments at every reset). A consumer
still reporting an older segment has taken nothing of the current one yet and still has the rest
of its old segment in flight (the plant's last count of that segment minus what it took): that
backlog is subtracted from what it may be sent, so the bound holds across a reset too.

Participant names are fully qualified node names (``/lubrig/lubrig_recorder``); a required
consumer may be given relative to belt_drive's namespace (``lubrig_recorder``) or absolute.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..core.params import ParameterError
from .interface.contract import BLOCK_QOS, resolve, validate_namespace


def qualified_name(namespace: str, name: str) -> str:
    """The fully qualified node name of `name` (relative to `namespace`, or absolute).

    ParameterError naming the value for a name ROS 2 would not accept.
    """
    if not isinstance(name, str) or not name or name.endswith("/"):
        raise ParameterError(
            f"required consumer {name!r} is not valid; expected a node name such as "
            "'lubrig_recorder' (relative to the namespace) or '/lubrig/lubrig_recorder'"
        )
    validate_namespace(namespace)
    try:
        return resolve(namespace, name)
    except ParameterError as exc:
        raise ParameterError(f"required consumer {name!r} is not valid: {exc}") from None


def band_samples_of_state(state_samples: int) -> int:
    """Band samples of a segment (indices 0 … b − 1) that its first `state_samples` state samples took.

    Band sample k = 1, 2, … travels with index k − 1 and becomes state sample k; state sample 0
    is the initial state, taken from no band sample. So s ≥ 1 state samples took s − 1.
    """
    return max(0, state_samples - 1)


def state_samples_of_band(band_samples: int) -> int:
    """State samples of a segment that its first `band_samples` band samples make: b + 1 (see above)."""
    return band_samples + 1


@dataclass
class Progress:
    """The latest report of one participant."""

    segment: int
    samples: int


@dataclass
class FlowGate:
    """Send limit of belt_drive from the participants' progress reports (see module docstring).

    `plant`: the plant's fully qualified node name (its reports set the current segment).
    `required`: fully qualified names of the required consumers.
    """

    window: int
    plant: str
    required: tuple[str, ...] = ()
    reports: dict[str, Progress] = field(default_factory=dict)
    #: the plant's last count per segment (backlog of a consumer still in an older segment)
    plant_totals: dict[int, int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.plant:
            raise ParameterError("the plant's node name must not be empty")
        if isinstance(self.window, bool) or not isinstance(self.window, int) or self.window < 1:
            raise ParameterError(f"flow_window={self.window!r} is not valid; expected an integer >= 1")
        self.required = tuple(n for n in dict.fromkeys(self.required) if n != self.plant)

    # ---- input ---------------------------------------------------------------------------
    def report(self, participant: str, segment: int, samples: int) -> bool:
        """One FlowProgress message; True when it changed what the gate knows.

        Reports of participants that are neither the plant nor required are ignored (False), as
        are reports that go backwards within a segment (a late duplicate) or to an older segment.
        """
        if segment < 0 or samples < 0:
            return False
        if participant != self.plant and participant not in self.required:
            return False
        old = self.reports.get(participant)
        if old is not None and (segment, samples) <= (old.segment, old.samples):
            return False
        self.reports[participant] = Progress(segment, samples)
        if participant == self.plant:
            self.plant_totals[segment] = samples
        return True

    # ---- state ---------------------------------------------------------------------------
    @property
    def segment(self) -> int | None:
        """The plant's current segment (None before its first report)."""
        plant = self.reports.get(self.plant)
        return None if plant is None else plant.segment

    def missing(self) -> list[str]:
        """Participants that have not reported yet (the plant first)."""
        names = [self.plant] if self.segment is None else []
        return names + [name for name in self.required if name not in self.reports]

    def ready(self) -> bool:
        """True once the plant and every required consumer have reported."""
        return not self.missing()

    def covered(self, participant: str) -> int:
        """Band samples of the current segment `participant` has covered (negative: backlog)."""
        segment = self.segment
        report = self.reports[participant]
        if segment is None or report.segment == segment:
            return band_samples_of_state(report.samples)
        if report.segment > segment:  # ahead of the plant's last report: nothing to hold back
            return 0
        backlog = max(0, self.plant_totals.get(report.segment, report.samples) - report.samples)
        backlog += sum(self.plant_totals.get(s, 0) for s in range(report.segment + 1, segment))
        return -backlog

    def slowest(self) -> tuple[str, int] | None:
        """(participant, covered band samples) of the slowest participant; None until ready."""
        if not self.ready():
            return None
        names = [self.plant, *self.required]
        covered = {name: self.covered(name) for name in names}
        name = min(names, key=lambda n: covered[n])
        return name, covered[name]

    def limit(self, total: int | None = None) -> int:
        """Highest band sample index (1-based, current segment) that may be sent; 0: none yet.

        `total`: the segment's last band sample (the run's length); the limit never exceeds it.
        """
        slowest = self.slowest()
        if slowest is None:
            return 0
        limit = max(0, slowest[1] + self.window)
        return limit if total is None else min(limit, total)


def flow_window_problem(flow_window: int, block_length: int) -> str | None:
    """Why this window could lose blocks with this block length, or None.

    Reliable keep_last QoS keeps BLOCK_QOS.depth unacknowledged messages per reader: a window
    of w samples puts at most ceil(w / block_length) + 1 blocks in flight towards the slowest
    participant (plus its progress message); keep that below the depth with a margin of 2.
    """
    most = (BLOCK_QOS.depth - 2) * block_length
    if flow_window > most:
        return (
            f"flow_window={flow_window} is too large for block_length={block_length}: at most "
            f"{most} samples ({BLOCK_QOS.depth - 2} blocks, the block topics' QoS depth "
            f"{BLOCK_QOS.depth} minus 2) may be in flight without a risk of losing a block"
        )
    return None
