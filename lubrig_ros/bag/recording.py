"""A recording session: batches of received messages (stream, receive time, CDR bytes) → one bag.

ROS-free and process-free: the recorder node (nodes/recorder.py) feeds it what its subscriber
processes (nodes/recorder_workers.py) received and publishes the flow progress it reports; this
module decides everything else.

- **Log time** of each message: its receive time (system clock, ns), or with ``use_sim_time`` the
  rig time: the header stamp of every stamped message, the /clock value for /clock, and for an
  unstamped message, or a stamp that is not rig time (at or beyond `WALL_CLOCK_NS`: a node on the
  wall clock), the latest /clock value received before it. Such a message waits (`SIM_HOLD_NS` at
  most) for the /clock that places it.
- **Accounting** (app/recording/accounting.py): every message of an indexed type (RigState, RigStateBlock,
  BandVelocityBlock) written is counted per stream from its sample index and segment; the plant's
  FlowProgress announces what it published, so samples not yet taken are known (`behind`).
- **Flow progress**: after every state_block written (or, with ``progress_per_block`` false, only
  as the heartbeat) the samples of its segment taken in order go to the ``on_progress`` sink.
- **The run configuration** given to the recorder is written first, at the first log time.
"""

from __future__ import annotations

import bisect
import contextlib
import json
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from lubrig_ros.app.fileio import write_text_atomic
from lubrig_ros.app.flow import band_samples_of_state, state_samples_of_band
from lubrig_ros.app.interface.cdr import INDEXED_TYPES, leading_stamp_ns, sample_span
from lubrig_ros.app.interface.contract import DEFAULT_NAMESPACE, Topic, documented_topics, resolve
from lubrig_ros.app.recording.accounting import StreamAccount
from lubrig_ros.bag.errors import BagError
from lubrig_ros.bag.layout import ACCOUNTING_SIDECAR, cdr_string, typestore
from lubrig_ros.bag.repair import repair_bag
from lubrig_ros.bag.writer import BagWriter, has_leading_stamp, serialize_string
from lubrig_ros.core.errors import InputError

#: With use_sim_time, an unstamped message waits at most this long (receive time) for /clock.
SIM_HOLD_NS = 300_000_000
#: A header stamp at or beyond this (about 3 years) is wall-clock time, not rig time (a wall-clock
#: stamp is about 1.8e9 s); such a message is placed by /clock instead.
WALL_CLOCK_NS = 100_000_000 * 1_000_000_000
#: The flow-progress heartbeat: the latest value again after this long without a report (s).
HEARTBEAT_S = 0.2
#: s after state_block's reader has matched that the first report waits for the required streams'
#: readers and for the readers of streams with a publisher on the graph; then it is sent without
#: them, named in `ready_without` and `ready_lagging` (nothing publishes them yet, or a publisher
#: of another type or QoS that never matches: the run must not wait for ever).
REQUIRED_MATCH_WAIT_S = 5.0
CLOCK_TYPE = "rosgraph_msgs/msg/Clock"

#: One received message: (index of its stream in `RecordingSession.streams`, receive time ns, CDR).
Received = tuple[int, int, bytes]
#: Where flow progress goes: (segment, samples taken in order, rig time of the newest sample ns).
ProgressSink = Callable[[int, int, int], None]


@dataclass
class RecordedStream:
    """One recorded topic and how its messages are placed and counted."""

    spec: Topic
    stamped: bool  # its type starts with a std_msgs/Header
    is_clock: bool
    account: StreamAccount | None = None  # streams with sample indices (INDEXED_TYPES)


class SimClock:
    """Maps receive times to rig time from the stream of /clock messages."""

    KEEP = 20_000  # newest /clock values kept (half are dropped when full)

    def __init__(self) -> None:
        self.recv: list[int] = []
        self.sim: list[int] = []

    def add(self, recv_ns: int, sim_ns: int) -> None:
        """Record one /clock message."""
        self.recv.append(recv_ns)
        self.sim.append(sim_ns)
        if len(self.recv) > self.KEEP:
            del self.recv[: self.KEEP // 2], self.sim[: self.KEEP // 2]

    def lookup(self, recv_ns: int, force: bool) -> int | None:
        """Rig time at recv_ns, or None if /clock may still arrive for it (unless force)."""
        if not self.recv or (recv_ns > self.recv[-1] and not force):
            return None
        i = bisect.bisect_right(self.recv, recv_ns) - 1
        return self.sim[max(i, 0)]


def required_streams(specs: Sequence[Topic], names: Sequence[str]) -> tuple[str, ...]:
    """The names (full) if each is a recorded sample stream; InputError naming one that is not."""
    indexed = [s.name for s in specs if s.msgtype in INDEXED_TYPES]
    for name in names:
        if name not in indexed:
            raise InputError(
                f"--require-samples {name!r} is invalid: expected a recorded sample stream, one of "
                f"{', '.join(indexed) or 'none'}"
            )
    return tuple(names)


class RecordingSession:
    """Writes received messages of `specs` into a new bag at `output` (see the module docstring)."""

    def __init__(
        self,
        output: Path,
        specs: Sequence[Topic],
        run_config: str | None,
        use_sim_time: bool,
        namespace: str = DEFAULT_NAMESPACE,
        flush_period: float = BagWriter.FLUSH_PERIOD_NS / 1e9,
        flush_messages: int = BagWriter.FLUSH_MESSAGES,
    ) -> None:
        topics = documented_topics(namespace)
        self.config_topic = topics[resolve(namespace, "run_config")]
        if run_config is not None:  # the given configuration is written, not subscribed
            specs = [s for s in specs if s.name != self.config_topic.name]
        self.streams = [
            RecordedStream(
                s,
                has_leading_stamp(s.msgtype),
                s.msgtype == CLOCK_TYPE,
                StreamAccount(s.name) if s.msgtype in INDEXED_TYPES else None,
            )
            for s in specs
        ]
        self.state_block = resolve(namespace, "state_block")
        self.band_block = resolve(namespace, "band_velocity_block")
        self.progress_topic = topics[resolve(namespace, "flow_progress")]
        self.plant_node = resolve(namespace, "plant")  # its FlowProgress announces what it published
        self.participant = ""  # this recorder's flow-control participant (set by the node)
        #: sample streams this recording must hold samples of: one that got none is a problem
        #: (a stream lost whole has no gap to show); full names, checked by `required_streams`
        self.required: tuple[str, ...] = ()
        self.matched_streams: set[str] = set()  # streams whose reader has matched a publisher
        self.state_matched_at: float | None = None  # monotonic s: state_block's reader matched
        self.ready_without: tuple[str, ...] = ()  # required streams the first report did not wait for
        #: per worker: publishers it sees on the graph per recorded topic (`graph`)
        self.seen_publishers: dict[int, dict[str, int]] = {}
        self.reader_matches: dict[str, int] = {}  # stream -> publishers its reader has matched
        self.ready_lagging: tuple[str, ...] = ()  # lagging streams the first report did not wait for
        self.use_sim_time = use_sim_time
        self.run_config = run_config
        self.config_written = False
        self.clock = SimClock()
        self.held: list[Received] = []
        self.malformed: dict[str, int] = {}
        self.on_progress: ProgressSink | None = None
        self.progress_per_block = True  # False: on matching and as the heartbeat only
        self.progress: tuple[int, int] | None = None  # (segment, samples) last reported
        self.last_progress = 0.0
        self.writer = BagWriter(output, run_config, round(flush_period * 1e9), flush_messages)
        if run_config is not None:
            self.writer.add_topic(self.config_topic.name, self.config_topic.msgtype, 1, True)
        for s in self.streams:
            self.writer.add_topic(s.spec.name, s.spec.msgtype, s.spec.depth, s.spec.latched)

    # ------------------------------------------------------------------ input
    def handle(self, batch: Sequence[Received], force: bool = False) -> None:
        """Write a batch (with use_sim_time: /clock first, unplaced messages held unless force)."""
        if not self.use_sim_time:
            for idx, recv, data in batch:
                self._write(self.streams[idx], recv, data)
            return
        for idx, recv, data in batch:  # /clock first, so that unstamped messages can be placed
            stream = self.streams[idx]
            if stream.is_clock:
                t = self._log_time(stream, recv, data, True)
                self._write(stream, recv if t is None else t, data)  # t = 0 is a valid rig time
        pending = self.held + [m for m in batch if not self.streams[m[0]].is_clock]
        self.held = []
        now = time.time_ns()
        for idx, recv, data in pending:
            stream = self.streams[idx]
            t = self._log_time(stream, recv, data, force or now - recv > SIM_HOLD_NS)
            if t is None:
                self.held.append((idx, recv, data))
            else:
                self._write(stream, t, data)

    def matched(self, streams: Sequence[int]) -> None:
        """These streams' subscriptions have matched a publisher; report (0, 0) once ready.

        Ready: state_block and every `required` stream have matched a publisher, and no stream
        has a publisher on the graph that its reader has not matched (`graph`). A publisher's
        own count of matched subscriptions is half of a match: its reader drops what arrives
        before the reader has matched the writer in turn (a volatile reader starts at the
        writer's next sample), so belt_drive, the plant and a lossless replay send nothing before
        this report.
        """
        self.matched_streams.update(self.streams[i].spec.name for i in streams)
        if self.state_block in self.matched_streams and self.state_matched_at is None:
            self.state_matched_at = time.monotonic()
        self._report_if_ready()

    def graph(self, worker: int, seen: Mapping[str, int], matched: Mapping[int, int]) -> None:
        """Worker `worker`'s view: publishers it sees per recorded topic, its readers' matched ones.

        `seen`: topic -> publishers on the worker's graph (every recorded topic); `matched`: stream
        index -> publishers its reader (one of this worker's) has matched.
        """
        self.seen_publishers[worker] = dict(seen)
        self.reader_matches.update({self.streams[i].spec.name: n for i, n in matched.items()})
        self._report_if_ready()

    def _report_if_ready(self) -> None:
        if self.progress is not None or self.state_matched_at is None:
            return
        if not self.unmatched_required() and not self.unmatched_publishers():
            self.report_progress(0, 0)  # subscribed and matched both ways: the run may start

    def unmatched_required(self) -> list[str]:
        """Required streams whose reader has not matched a publisher yet."""
        return [name for name in self.required if name not in self.matched_streams]

    def unmatched_publishers(self) -> list[str]:
        """Streams whose reader has matched fewer publishers than a worker sees on the graph (sorted).

        Each worker is a participant of its own, and each discovers each publisher on its own (a
        discovery message lost on the way is sent again later): the worker that reads a stream may
        not yet know a publisher the others see, and has then not matched it either. So every
        worker's view counts, not only the reading worker's.
        """
        lagging = []
        for stream in self.streams:
            name = stream.spec.name
            most = max((seen.get(name, 0) for seen in self.seen_publishers.values()), default=0)
            if self.reader_matches.get(name, 0) < most:
                lagging.append(name)
        return sorted(lagging)

    def start(self) -> None:
        """Without use_sim_time the run configuration is written now (receive-time log times)."""
        if self.run_config is not None and not self.use_sim_time:
            self._write_config(time.time_ns())
            self.writer.flush()

    def _log_time(self, stream: RecordedStream, recv: int, data: bytes, force: bool) -> int | None:
        if not self.use_sim_time:
            return recv
        if stream.stamped:
            try:
                stamp: int | None = leading_stamp_ns(data)
            except ValueError:
                stamp = None
            if stream.is_clock and stamp is not None:
                self.clock.add(recv, stamp)
            if stamp is not None and (stream.is_clock or stamp < WALL_CLOCK_NS):
                return stamp
        t = self.clock.lookup(recv, force)
        if t is None and force:
            return 0  # before the first /clock the rig is at t = 0 (e.g. the latched run_config)
        return t

    def _write(self, stream: RecordedStream, t: int, data: bytes) -> None:
        if not self.config_written and self.run_config is not None:
            self._write_config(t)
        if stream.spec.name == self.config_topic.name:  # published by the launcher: keep it
            text = cdr_string(data)
            if text is not None:
                self.writer.set_run_config(text)
        self.writer.write(stream.spec.name, stream.spec.msgtype, t, data)
        if stream.account is not None:
            self._account(stream, data)
        elif stream.spec.name == self.progress_topic.name:
            self._announced(data)

    def _write_config(self, t: int) -> None:
        assert self.run_config is not None
        spec = self.config_topic
        self.writer.write(spec.name, spec.msgtype, t, serialize_string(self.run_config))
        self.config_written = True

    def _count_malformed(self, name: str) -> None:
        self.malformed[name] = self.malformed.get(name, 0) + 1

    def _account(self, stream: RecordedStream, data: bytes) -> None:
        """Count the written message's samples; after a state_block, report flow progress."""
        assert stream.account is not None
        try:
            span = sample_span(stream.spec.msgtype, data)
        except ValueError:
            self._count_malformed(stream.spec.name)
            return
        stream.account.add(
            span.segment, span.first_index, span.count, span.stamp_ns, span.period_ns, span.skipped
        )
        if stream.spec.name == self.state_block and self.progress_per_block:
            self.report_progress(span.segment, self.reach(span.segment))
        elif stream.spec.name == self.band_block and self.band_paced and self.progress is not None:
            reach = self.reach(span.segment)  # a band block that came late may move it
            if (span.segment, reach) > self.progress:
                self.report_progress(span.segment, reach)

    def _announced(self, data: bytes) -> None:
        """A FlowProgress of the plant: the samples it has published (the state_block stream's tail)."""
        account = self._state_account()
        if account is None:
            return
        try:
            msg: Any = typestore().deserialize_cdr(data, self.progress_topic.msgtype)
        except Exception:  # a malformed message is counted, never fatal
            self._count_malformed(self.progress_topic.name)
            return
        if msg.participant == self.plant_node:
            account.announce(int(msg.segment), int(msg.samples))
            band = self._account_of(self.band_block) if self.band_paced else None
            if band is not None:  # the band samples the plant took exist too
                band.announce(int(msg.segment), band_samples_of_state(int(msg.samples)))

    # ------------------------------------------------------------------ flow progress
    def _state_account(self) -> StreamAccount | None:
        return self._account_of(self.state_block)

    def _account_of(self, name: str) -> StreamAccount | None:
        return next((s.account for s in self.streams if s.spec.name == name), None)

    @property
    def band_paced(self) -> bool:
        """True when the band stream counts in flow progress: reported per block (sim) and required.

        A sim rig's band blocks and state blocks are one stream of samples: band sample k becomes
        state sample k (app/flow.py), and the rig's recorder must hold both whole.
        """
        return self.progress_per_block and self.band_block in self.required

    def reach(self, segment: int) -> int:
        """State samples of `segment` the bag holds whole: FlowProgress.samples of this recorder.

        state_block's samples taken in order; with `band_paced`, no more than the band samples
        taken in order make (a copy of a band block lost on the way holds the count back until it
        is sent again, so that `lubrig rig` stops no writer before the bag has every sample).
        """
        state = self._state_account()
        taken = 0 if state is None else state.taken(segment)
        band = self._account_of(self.band_block) if self.band_paced else None
        if band is not None:
            taken = min(taken, state_samples_of_band(band.taken(segment)))
        return taken

    @property
    def records_state_block(self) -> bool:
        """True if the state_block stream is recorded (only then is flow progress reported)."""
        return any(s.spec.name == self.state_block for s in self.streams)

    def report_progress(self, segment: int, samples: int) -> None:
        """Report (segment, samples) to the progress sink (none yet: nothing is reported)."""
        if self.on_progress is None:
            return
        self.progress = (segment, samples)
        self.on_progress(segment, samples, self.newest_rig_ns)
        self.last_progress = time.monotonic()

    def heartbeat(self) -> None:
        """Report again after HEARTBEAT_S without a report: what is taken now.

        Before the first report: once REQUIRED_MATCH_WAIT_S have passed since state_block's
        reader matched, the first report, without the required streams still unmatched
        (`ready_without` names them) and the streams still lagging (`ready_lagging`).
        """
        since = None if self.state_matched_at is None else time.monotonic() - self.state_matched_at
        if self.progress is None and since is not None and since >= REQUIRED_MATCH_WAIT_S:
            self.ready_without = tuple(self.unmatched_required())
            self.ready_lagging = tuple(self.unmatched_publishers())
            self.report_progress(0, 0)
            return
        if self.progress is None or time.monotonic() - self.last_progress < HEARTBEAT_S:
            return
        account = self._state_account()
        if account is None or account.newest_segment < 0:
            self.report_progress(*self.progress)
        else:  # with progress per block: the same value again
            segment = account.newest_segment
            self.report_progress(segment, self.reach(segment))

    @property
    def newest_rig_ns(self) -> int:
        """Rig time of the newest state_block sample written (0 before the first)."""
        account = self._state_account()
        seg = None if account is None else account.segments.get(account.newest_segment)
        return 0 if seg is None or seg.last_time_ns is None else seg.last_time_ns  # announced only: 0

    # ------------------------------------------------------------------ results
    @property
    def accounts(self) -> dict[str, StreamAccount]:
        """The accounts of the recorded sample streams, by topic (those that got messages)."""
        return {s.spec.name: s.account for s in self.streams if s.account is not None and s.account.messages}

    def behind(self) -> int:
        """Samples the plant announced that are not written yet."""
        return sum(a.behind() for a in self.accounts.values())

    def problems(self) -> list[str]:
        """One line per problem of every stream (gap, duplicate, out of order, malformed)."""
        accounts = self.accounts
        lines = [
            f"{name}: no samples recorded (the run publishes this stream)"
            for name in self.required
            if name not in accounts
        ]
        lines += [line for a in accounts.values() for line in a.problems()]
        lines += [
            f"{name}: {n} malformed messages (no sample index read)" for name, n in self.malformed.items()
        ]
        return lines

    def write_accounting(self) -> Path:
        """<bag>/accounting.json: per-stream accounts and the problems (written atomically)."""
        path = self.writer.path / ACCOUNTING_SIDECAR
        problems = self.problems()
        data = {
            "participant": self.participant,
            "streams": {name: a.summary() for name, a in self.accounts.items()},
            "malformed": self.malformed,
            "problems": problems,
            "complete": not problems,
        }
        write_text_atomic(path, json.dumps(data, indent=2) + "\n")
        return path

    def flush_if_due(self, interval_s: float) -> None:
        """Flush to the disk (fsync) if the last flush is older than interval_s of wall time."""
        if time.monotonic() - self.writer.last_flush > interval_s:
            self.writer.flush()

    def close(self) -> None:
        """Finalize the bag; after a write failure, repair it.

        BagWriter.close only closes a failed bag; the repair (what was flushed, finalized) is run
        here explicitly. If it fails too (e.g. the disk is still full) the bag stays unfinalized
        and `lubrig bag repair DIR` can retry.
        """
        try:
            self.writer.close()
        finally:
            if self.writer.failed:
                with contextlib.suppress(BagError, OSError):
                    repair_bag(self.writer.path, backup=False)
