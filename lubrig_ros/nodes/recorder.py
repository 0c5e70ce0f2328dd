"""`recorder` node: record the rig's topics into a rosbag2 bag (MCAP, zstd chunks).

Subscriptions are spread over worker processes (multiprocessing, forkserver: the server imports
rclpy and this module once, each worker is forked from it, so three workers cost one import,
about 0.8 s of CPU each at start-up otherwise; nothing of ROS is initialized in the server,
so forking it is safe). Each worker runs a real
rclpy node with raw subscriptions (serialized CDR bytes, no deserialization) spun by rclpy's
EventsExecutor in a spin_once loop, and ships (topic index, receive time, bytes) batches to this
process, the only writer of the bag (block messages at once, others every 20 ms).

Accounting (app/accounting.py): every RigState, RigStateBlock and BandVelocityBlock written is
counted per stream from its sample index and segment; gaps, duplicates and samples out of order
are printed at the end, written to <bag>/accounting.json, and make the exit status 1.

Flow control (sim): this process is the node ``<namespace>/lubrig_recorder`` (RECORDER_NODE) and
publishes lubrig_interfaces/FlowProgress on ``<namespace>/flow_progress``: samples 0 once its
state_block subscription has matched a publisher, after every state_block it has written the
samples of that segment taken in order, and the latest value again every 0.2 s (heartbeat);
with --progress-heartbeat-only (`lubrig rig` in the wall-clock modes, where nothing paces on
it) only on matching and as the heartbeat.

Log times: receive time (system clock, ns); with --use-sim-time the rig time: the header stamp
of every message with a header, the /clock value for /clock (in a sim rig every stamp is rig
time: the plant's samples, flow progress and diagnostics, the band blocks, the analysis outputs),
and for unstamped types, or a stamp that is not rig time (beyond WALL_CLOCK_NS: a node on the
wall clock), the latest /clock value received before the message. --use-sim-time also gives this
process's ROS nodes (flow progress, workers) use_sim_time true, as every node of a sim rig has.

Exit status: 0 after a clean stop (SIGINT/SIGTERM or --duration) with every stream complete,
2 on bad arguments or an unwritable output, 1 if writing failed while recording (the bag is then
finalized up to the last flushed chunk) or a stream has a gap, a duplicate or a sample out of
order (named on stderr).
"""

from __future__ import annotations

import argparse
import bisect
import contextlib
import json
import math
import multiprocessing as mp
import multiprocessing.forkserver as mp_forkserver
import os
import queue
import signal
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import yaml

from lubrig_ros.app.accounting import StreamAccount
from lubrig_ros.app.cdr import INDEXED_TYPES, leading_stamp_ns, sample_span
from lubrig_ros.app.contract import (
    DEFAULT_NAMESPACE,
    RECORDER_PARTICIPANT,
    QoS,
    Topic,
    documented_topics,
    resolve,
)
from lubrig_ros.app.contract import select_topics as _select_topics
from lubrig_ros.app.fileio import write_text_atomic
from lubrig_ros.app.lifetime import die_with_parent
from lubrig_ros.bag.errors import BagError
from lubrig_ros.bag.layout import ACCOUNTING_SIDECAR, cdr_string
from lubrig_ros.bag.repair import repair_bag
from lubrig_ros.bag.writer import BagWriter, has_leading_stamp, serialize_string, typestore
from lubrig_ros.nodes.script import bounded_teardown, run_script

BATCH_PERIOD_S = 0.02
SIM_HOLD_NS = 300_000_000  # wait this long for /clock before stamping an unstamped message
#: --use-sim-time: a header stamp at or beyond this (about 3 years) is wall-clock time, not rig time
#: (a wall-clock stamp is about 1.8e9 s); such a message is placed by /clock instead.
WALL_CLOCK_NS = 100_000_000 * 1_000_000_000
#: The recorder's flow-control participant: <namespace>/lubrig_recorder (app/contract.py
#: RECORDER_PARTICIPANT; `lubrig rig` puts it in belt_drive's required_consumers).
RECORDER_NODE = RECORDER_PARTICIPANT
#: The participant name (relative to the namespace) `lubrig rig` checks before pacing on it.
FLOW_PARTICIPANT = RECORDER_NODE
HEARTBEAT_S = 0.2
PROGRESS_TYPE = "lubrig_interfaces/msg/FlowProgress"
BLOCK_TYPES = ("lubrig_interfaces/msg/RigStateBlock", "lubrig_interfaces/msg/BandVelocityBlock")
#: After a stop request, wait up to this long for samples the plant announced but not yet taken.
CATCH_UP_S = 5.0
READER_DEPTH = 10_000  # samples kept by each reader while its worker is busy (reader_qos)
#: Longest a worker waits for a message before it checks shipping and stop (s); a message wakes it.
WORKER_WAIT_S = 0.02


# ----------------------------------------------------------------------------- worker process


def reader_qos(qos: QoS) -> QoS:
    """The recorder's reader QoS: the contract's, with a history of at least READER_DEPTH.

    A keep_last reader drops its oldest sample when its history is full; the DDS threads keep
    receiving while the worker's Python thread is starved of CPU, so a deep history (10 s of a
    1 kHz stream, about 1 MB of RigState) rides out a busy machine instead of losing samples.
    Reader depth plays no part in QoS compatibility. Latched topics keep their depth.
    """
    if qos.latched or qos.history != "keep_last":
        return qos
    return replace(qos, depth=max(qos.depth, READER_DEPTH))



def _context() -> Any:
    """The multiprocessing context of the workers: a fork server that has imported what they need."""
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(
        ["lubrig_ros.nodes.recorder_forkserver", "rclpy", "rclpy.experimental", "lubrig_ros.nodes.interfaces",
         __name__]
    )
    return ctx


def _sim_time_overrides(use_sim_time: bool) -> list[Any]:
    """parameter_overrides of this process's ROS nodes: use_sim_time as the recorder was asked."""
    from rclpy.parameter import Parameter

    return [Parameter("use_sim_time", Parameter.Type.BOOL, True)] if use_sim_time else []


def _worker(
    wid: int,
    specs: list[Topic],
    first_index: int,
    out: Any,
    stop: Any,
    use_sim_time: bool = False,
    namespace: str = DEFAULT_NAMESPACE,
) -> None:
    """Subscribe to specs (raw) and ship batches of (index, recv_ns, bytes) to out.

    Spun by rclpy's EventsExecutor with spin_once (its spin() fires no timer in this wheel and
    keeps a core busy: ../shared/ros2-interfaces-on-pip.md), so shipping and the stop check are
    done in the loop. A block message is shipped at once (the flow control waits for it), other
    messages every BATCH_PERIOD_S. Reports ("matched", wid, [index]) once a subscription has a
    publisher.
    """
    # the fork server (this process's parent) ends with the recorder, however the recorder ends
    # (it reads EOF on the recorder's end of its alive pipe); this worker is killed with it
    die_with_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent coordinates the stop
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    import rclpy
    from rclpy.experimental import EventsExecutor
    from rclpy.signals import SignalHandlerOptions

    from lubrig_ros.nodes.interfaces import message_class, qos_profile

    parent = os.getppid()
    rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(
        f"{RECORDER_NODE}_w{wid}", namespace=namespace, parameter_overrides=_sim_time_overrides(use_sim_time)
    )
    batch: list[tuple[int, int, bytes]] = []
    urgent = [False]
    now = time.time_ns

    def make_cb(index: int, block: bool) -> Callable[[bytes], None]:
        if block:
            def cb_block(data: bytes) -> None:
                batch.append((index, now(), data))
                urgent[0] = True

            return cb_block

        def cb(data: bytes) -> None:
            batch.append((index, now(), data))

        return cb

    subs = []
    for i, spec in enumerate(specs):  # QoS from the contract (app/contract.py), deeper history
        subs.append(
            node.create_subscription(
                message_class(spec.msgtype), spec.name,
                make_cb(first_index + i, spec.msgtype in BLOCK_TYPES), qos_profile(reader_qos(spec.qos)),
                raw=True,
            )
        )
    executor = EventsExecutor()
    executor.add_node(node)
    out.put(("ready", wid, None))
    unmatched = set(range(len(subs)))
    next_ship = time.monotonic() + BATCH_PERIOD_S
    next_check = 0.0
    try:
        while True:
            executor.spin_once(timeout_sec=WORKER_WAIT_S)
            t = time.monotonic()
            if batch and (urgent[0] or t >= next_ship):
                out.put(("data", wid, batch))
                batch = []
                urgent[0] = False
            if t >= next_ship:
                next_ship = t + BATCH_PERIOD_S
            if t >= next_check:
                next_check = t + 0.05
                if stop.is_set() or os.getppid() != parent:
                    break
                matched = [i for i in unmatched if subs[i].get_publisher_count() > 0]
                if matched:
                    unmatched.difference_update(matched)
                    out.put(("matched", wid, [first_index + i for i in matched]))
        # what arrived before the stop was seen: take it, then ship the rest
        for _ in range(1000):
            before = len(batch)
            executor.spin_once(timeout_sec=0.01)
            if len(batch) == before:
                break
    finally:
        out.put(("data", wid, batch))
        out.put(("done", wid, None))
        node.destroy_node()
        rclpy.shutdown()


# ----------------------------------------------------------------------------- writer process


@dataclass
class _Topic:
    spec: Topic
    stamped: bool
    is_clock: bool
    account: StreamAccount | None = None  # streams with sample indices (INDEXED_TYPES)


CLOCK_TYPE = "rosgraph_msgs/msg/Clock"


class SimClock:
    """Maps receive times to rig time from the stream of /clock messages."""

    def __init__(self) -> None:
        self.recv: list[int] = []
        self.sim: list[int] = []

    def add(self, recv_ns: int, sim_ns: int) -> None:
        """Record one /clock message."""
        self.recv.append(recv_ns)
        self.sim.append(sim_ns)
        if len(self.recv) > 20000:
            del self.recv[:10000], self.sim[:10000]

    def lookup(self, recv_ns: int, force: bool) -> int | None:
        """Rig time at recv_ns, or None if /clock may still arrive for it (unless force)."""
        if not self.recv or (recv_ns > self.recv[-1] and not force):
            return None
        i = bisect.bisect_right(self.recv, recv_ns) - 1
        return self.sim[max(i, 0)]


class Recorder:
    """Writer side: receives worker batches and writes them to the bag."""

    def __init__(
        self,
        output: Path,
        specs: list[Topic],
        workers: int,
        run_config: str | None,
        use_sim_time: bool,
        flush_interval: float,
        namespace: str = DEFAULT_NAMESPACE,
        flush_period: float = BagWriter.FLUSH_PERIOD_NS / 1e9,
        flush_messages: int = BagWriter.FLUSH_MESSAGES,
    ) -> None:
        config_spec = documented_topics(namespace)[resolve(namespace, "run_config")]
        if run_config is not None:  # the given configuration is written, not subscribed
            specs = [s for s in specs if s.name != config_spec.name]
        # In sim mode every header stamp is rig time (the plant's samples, flow progress and
        # diagnostics, the band blocks, the analysis outputs with use_sim_time) and so is /clock;
        # a stamp that is wall-clock time is placed by the /clock stream (_log_time).
        self.topics = [
            _Topic(
                s,
                has_leading_stamp(s.msgtype),
                s.msgtype == CLOCK_TYPE,
                StreamAccount(s.name) if s.msgtype in INDEXED_TYPES else None,
            )
            for s in specs
        ]
        self.namespace = namespace
        self.state_block = resolve(namespace, "state_block")
        self.progress_topic = resolve(namespace, "flow_progress")
        self.plant_node = resolve(namespace, "plant")  # its FlowProgress announces what it published
        self.participant = resolve(namespace, RECORDER_NODE)
        self.progress: tuple[int, int] | None = None  # (segment, samples) last reported
        self.progress_per_block = True  # False: on matching and as the 0.2 s heartbeat only
        self.progress_pub: object = None
        self.progress_node: object = None
        self.last_progress = 0.0
        self.malformed: dict[str, int] = {}
        self.use_sim_time = use_sim_time
        self.flush_interval = flush_interval
        self.writer = BagWriter(output, run_config, round(flush_period * 1e9), flush_messages)
        self.config_topic = config_spec
        if run_config is not None:
            self.writer.add_topic(config_spec.name, config_spec.msgtype, 1, True)
        for t in self.topics:
            self.writer.add_topic(t.spec.name, t.spec.msgtype, t.spec.depth, t.spec.latched)
        self.run_config = run_config
        self.config_written = False
        self.clock = SimClock()
        self.held: list[tuple[int, int, bytes]] = []
        self.n_workers = max(1, min(workers, len(specs)))
        self.queue: mp.Queue = _context().Queue()
        self.stop_event = _context().Event()
        self.procs: list[Any] = []  # forkserver-context processes

    def start_workers(self, timeout: float = 90.0, should_stop: Sequence[bool] = (False,)) -> bool:
        """Spawn the subscriber processes; True once all have created their subscriptions.

        False at once if should_stop[0] becomes true meanwhile (a Ctrl-C while a loaded machine is
        still starting the workers: the stop must not wait for them). BagError, naming the
        worker's topics, if one dies or is not ready within timeout s.
        """
        ctx = _context()
        groups = [list(range(i, len(self.topics), self.n_workers)) for i in range(self.n_workers)]
        self.index_map: list[int] = []
        for wid, group in enumerate(groups):
            first = len(self.index_map)
            self.index_map.extend(group)
            proc = ctx.Process(
                target=_worker,
                args=(wid, [self.topics[i].spec for i in group], first, self.queue, self.stop_event,
                      self.use_sim_time, self.namespace),
                daemon=True,
            )
            proc.start()
            self.procs.append(proc)
        ready: set[int] = set()
        deadline = time.monotonic() + timeout
        while len(ready) < len(self.procs):
            if should_stop[0]:
                return False
            try:
                kind, wid, payload = self.queue.get(timeout=0.2)
            except queue.Empty:
                kind, wid, payload = None, -1, None
            if kind == "ready":
                ready.add(wid)
            else:
                self._message(kind, payload)
            for wid, (proc, group) in enumerate(zip(self.procs, groups, strict=True)):
                if wid in ready:
                    continue
                names = ", ".join(self.topics[i].spec.name for i in group)
                if not proc.is_alive():
                    raise BagError(
                        f"recorder worker {wid} ({names}) exited with status {proc.exitcode} "
                        "before subscribing"
                    )
                if time.monotonic() > deadline:
                    raise BagError(f"recorder worker {wid} ({names}) not ready after {timeout:g} s")
        return True

    def _message(self, kind: str | None, payload: object) -> None:
        """A worker's "data" batch or "matched" report (anything else is ignored)."""
        if kind == "data":
            self._handle(payload)  # type: ignore[arg-type]
        elif kind == "matched":
            names = {self.topics[self.index_map[i]].spec.name for i in payload}  # type: ignore[attr-defined]
            if self.state_block in names and self.progress is None:
                self.report_progress(0, 0)  # subscribed and matched: belt_drive may start

    def _log_time(self, topic: _Topic, recv: int, data: bytes, force: bool) -> int | None:
        if not self.use_sim_time:
            return recv
        if topic.stamped:
            try:
                stamp = leading_stamp_ns(data)
            except ValueError:
                stamp = None
            if topic.is_clock and stamp is not None:
                self.clock.add(recv, stamp)
            if stamp is not None and (topic.is_clock or stamp < WALL_CLOCK_NS):
                return stamp
        t = self.clock.lookup(recv, force)
        if t is None and force:
            return 0  # before the first /clock the rig is at t = 0 (e.g. the latched run_config)
        return t

    def _write(self, topic: _Topic, t: int, data: bytes) -> None:
        if not self.config_written and self.run_config is not None:
            self._write_config(t)
        if topic.spec.name == self.config_topic.name:  # published by the launcher: keep it
            text = cdr_string(data)
            if text is not None:
                self.writer.set_run_config(text)
        self.writer.write(topic.spec.name, topic.spec.msgtype, t, data)
        if topic.account is not None:
            self._account(topic, data)
        elif topic.spec.name == self.progress_topic:
            self._announced(data)

    def _account(self, topic: _Topic, data: bytes) -> None:
        """Count the written message's samples; after a state_block, report flow progress."""
        assert topic.account is not None
        try:
            span = sample_span(topic.spec.msgtype, data)
        except ValueError:
            self.malformed[topic.spec.name] = self.malformed.get(topic.spec.name, 0) + 1
            return
        topic.account.add(
            span.segment, span.first_index, span.count, span.stamp_ns, span.period_ns, span.skipped
        )
        if topic.spec.name == self.state_block and self.progress_per_block:
            self.report_progress(span.segment, topic.account.taken(span.segment))

    def _announced(self, data: bytes) -> None:
        """A FlowProgress of the plant: the samples it has published (the state_block stream's tail)."""
        account = next((t.account for t in self.topics if t.spec.name == self.state_block), None)
        if account is None:
            return
        try:
            msg: Any = typestore().deserialize_cdr(data, PROGRESS_TYPE)
        except Exception:  # a malformed message is counted, never fatal
            self.malformed[self.progress_topic] = self.malformed.get(self.progress_topic, 0) + 1
            return
        if msg.participant == self.plant_node:
            account.announce(int(msg.segment), int(msg.samples))

    # ------------------------------------------------------------------ flow progress (sim)
    def start_progress(self) -> None:
        """Create the FlowProgress publisher (this process's node <namespace>/lubrig_recorder)."""
        if not any(t.spec.name == self.state_block for t in self.topics):
            return
        import rclpy
        from rclpy.signals import SignalHandlerOptions

        from lubrig_ros.nodes.interfaces import message_class, qos_profile

        rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
        overrides = _sim_time_overrides(self.use_sim_time)
        node = rclpy.create_node(RECORDER_NODE, namespace=self.namespace, parameter_overrides=overrides)
        spec = documented_topics(self.namespace)[self.progress_topic]
        self.progress_cls = message_class(spec.msgtype)
        self.progress_pub = node.create_publisher(
            self.progress_cls, self.progress_topic, qos_profile(spec.qos)
        )
        self.progress_node = node
        self.participant = node.get_fully_qualified_name()

    def report_progress(self, segment: int, samples: int) -> None:
        """Publish FlowProgress(segment, samples) (once the state_block stream has a publisher)."""
        if self.progress_pub is None:
            return
        self.progress = (segment, samples)
        msg = self.progress_cls()
        msg.participant, msg.segment, msg.samples = self.participant, segment, samples
        t = self.newest_rig_ns
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(max(t, 0), 1_000_000_000)
        self.progress_pub.publish(msg)  # type: ignore[attr-defined]
        self.last_progress = time.monotonic()

    def _heartbeat(self) -> None:
        if self.progress is not None and time.monotonic() - self.last_progress >= HEARTBEAT_S:
            account = next((t.account for t in self.topics if t.spec.name == self.state_block), None)
            if account is None or account.newest_segment < 0:
                self.report_progress(*self.progress)
            else:  # what is taken now (with progress per block: the same value again)
                segment = account.newest_segment
                self.report_progress(segment, account.taken(segment))

    def error(self, text: str) -> None:
        """An error line: on stderr (`recorder: error: ...`) and, once the node is up, on /rosout."""
        print(f"recorder: error: {text}", file=sys.stderr, flush=True)
        if self.progress_node is not None:
            with contextlib.suppress(Exception):  # a context already shut down: stderr has it
                self.progress_node.get_logger().error(text)  # type: ignore[attr-defined]

    def stop_progress(self) -> None:
        """Destroy the progress node (and rclpy's context of this process)."""
        if self.progress_node is None:
            return
        import rclpy

        with contextlib.suppress(Exception):
            self.progress_node.destroy_node()  # type: ignore[attr-defined]
            rclpy.shutdown()
        self.progress_node = self.progress_pub = None

    @property
    def newest_rig_ns(self) -> int:
        """Rig time of the newest state_block sample written (0 before the first)."""
        account = next((t.account for t in self.topics if t.spec.name == self.state_block), None)
        seg = None if account is None else account.segments.get(account.newest_segment)
        return 0 if seg is None or seg.last_time_ns is None else seg.last_time_ns  # announced only: 0

    # ------------------------------------------------------------------ accounting results
    @property
    def accounts(self) -> dict[str, StreamAccount]:
        """The accounts of the recorded sample streams, by topic (those that got messages)."""
        return {t.spec.name: t.account for t in self.topics if t.account is not None and t.account.messages}

    def behind(self) -> int:
        """Samples the plant announced that are not written yet."""
        return sum(a.behind() for a in self.accounts.values())

    def problems(self) -> list[str]:
        """One line per problem of every stream (gap, duplicate, out of order, malformed)."""
        lines = [line for a in self.accounts.values() for line in a.problems()]
        lines += [f"{name}: {n} malformed messages (no sample index read)"
                  for name, n in self.malformed.items()]
        return lines

    def write_accounting(self) -> Path:
        """<bag>/accounting.json: per-stream accounts and the problems (written atomically)."""
        path = self.writer.path / ACCOUNTING_SIDECAR
        data = {
            "participant": self.participant,
            "streams": {name: a.summary() for name, a in self.accounts.items()},
            "malformed": self.malformed,
            "problems": self.problems(),
            "complete": not self.problems(),
        }
        write_text_atomic(path, json.dumps(data, indent=2) + "\n")
        return path

    def _write_config(self, t: int) -> None:
        assert self.run_config is not None
        spec = self.config_topic
        self.writer.write(spec.name, spec.msgtype, t, serialize_string(self.run_config))
        self.config_written = True

    def _handle(self, batch: list[tuple[int, int, bytes]], force: bool = False) -> None:
        if self.use_sim_time:  # /clock first, so that unstamped messages can be resolved
            for idx, recv, data in batch:
                topic = self.topics[self.index_map[idx]]
                if topic.is_clock:
                    t = self._log_time(topic, recv, data, True)
                    self._write(topic, recv if t is None else t, data)  # t = 0 is a valid rig time
            batch = [m for m in batch if not self.topics[self.index_map[m[0]]].is_clock]
            pending, self.held = self.held + batch, []
            now = time.time_ns()
            for idx, recv, data in pending:
                topic = self.topics[self.index_map[idx]]
                t = self._log_time(topic, recv, data, force or now - recv > SIM_HOLD_NS)
                if t is None:
                    self.held.append((idx, recv, data))
                else:
                    self._write(topic, t, data)
            return
        for idx, recv, data in batch:
            self._write(self.topics[self.index_map[idx]], recv, data)

    def run(self, should_stop: list[bool], duration: float | None) -> None:
        """Write batches until should_stop[0] or duration elapses, then drain the workers."""
        if self.run_config is not None and not self.use_sim_time:
            self._write_config(time.time_ns())
            self.writer.flush()
        end = time.monotonic() + duration if duration else math.inf
        catch_up = math.inf
        while time.monotonic() < min(end, catch_up):
            if should_stop[0] and catch_up == math.inf:
                catch_up = time.monotonic() + CATCH_UP_S  # take what the plant announced first
            if should_stop[0] and not self.behind():
                break
            try:
                kind, _wid, payload = self.queue.get(timeout=0.05)
            except queue.Empty:
                kind = ""
            if kind:
                self._message(kind, payload)
            elif self.held:
                self._handle([])
            self._heartbeat()
            if time.monotonic() - self.writer.last_flush > self.flush_interval:
                self.writer.flush()
            if any(not p.is_alive() for p in self.procs):
                raise BagError("a recorder worker process died; recording stopped")
        self.drain()

    def drain(self) -> None:
        """Stop the workers and write everything they received."""
        self.stop_event.set()
        done = 0
        deadline = time.monotonic() + 10
        while done < len(self.procs) and time.monotonic() < deadline:
            try:
                kind, _wid, payload = self.queue.get(timeout=0.2)
            except queue.Empty:
                if not any(p.is_alive() for p in self.procs):
                    break
                continue
            if kind == "data" and not self.writer.failed:
                self._handle(payload)
            elif kind == "done":
                done += 1
        if self.held and not self.writer.failed:
            self._handle([], force=True)

    def shutdown(self) -> None:
        """Stop workers (if still running) and finalize the bag; after a write failure, repair it.

        BagWriter.close only closes a failed bag; the repair (what was flushed, finalized) is run
        here explicitly. If it fails too (e.g. the disk is still full) the bag stays unfinalized
        and `lubrig bag repair DIR` can retry.
        """
        self.stop_event.set()
        for p in self.procs:
            p.join(timeout=3)
            if p.is_alive():
                p.kill()
        try:
            self.writer.close()
        finally:
            if self.writer.failed:
                with contextlib.suppress(BagError, OSError):
                    repair_bag(self.writer.path, backup=False)


# ----------------------------------------------------------------------------- command line


def build_parser() -> argparse.ArgumentParser:
    """Arguments of the recorder node."""
    p = argparse.ArgumentParser(prog="recorder", description=__doc__.splitlines()[0])
    p.add_argument("-o", "--output", type=Path, help="new bag directory (default: lubrig_<time>)")
    p.add_argument("--namespace", default=DEFAULT_NAMESPACE, help="rig namespace (default /lubrig)")
    p.add_argument(
        "--topics", nargs="+", metavar="TOPIC",
        help="topics to record (relative names go under the namespace; default: all documented)",
    )
    p.add_argument("--config", type=Path, help="YAML file of the run configuration to store")
    p.add_argument("--use-sim-time", action="store_true", help="log times from rig time (/clock)")
    p.add_argument("--workers", type=int, default=0, help="subscriber processes (0: auto)")
    p.add_argument("--flush-interval", type=float, default=0.5,
                   help="wall-clock seconds between flushes to the disk (fsync)")
    p.add_argument("--flush-period", type=float, default=BagWriter.FLUSH_PERIOD_NS / 1e9,
                   help="close a chunk once its messages span this many seconds of log (rig) time: "
                   "the most a SIGKILL or a full disk loses (default 0.2)")
    p.add_argument("--flush-messages", type=int, default=BagWriter.FLUSH_MESSAGES,
                   help=f"... or once it holds this many messages (default {BagWriter.FLUSH_MESSAGES})")
    p.add_argument("--duration", type=float, help="stop after this many seconds")
    p.add_argument(
        "--progress-heartbeat-only", dest="progress_per_block", action="store_false",
        help="FlowProgress once the state_block subscription has matched and then every 0.2 s, "
        "not after every block (a wall-clock rig is not paced on it; its plant starts once it "
        "has heard the recorder, so no sample is published before the recorder takes them)",
    )
    return p


def select_topics(namespace: str, topics: Sequence[str] | None) -> list[Topic]:
    """Topics of the selection (all documented ones if none); every name must be in the contract."""
    return _select_topics(namespace, list(topics) if topics else None)


def auto_workers(specs: Sequence[Topic]) -> int:
    """Two high-rate (depth 1000) topics per worker; low-rate topics go along."""
    fast = sum(1 for s in specs if s.depth >= 1000)
    return max(1, min(4, math.ceil(fast / 2)))


def run(args: argparse.Namespace) -> int:
    """Record until SIGINT/SIGTERM or --duration; see the module docstring for exit codes."""
    specs = select_topics(args.namespace, args.topics)
    if args.workers < 0 or args.flush_interval <= 0:
        raise ValueError(
            f"--workers {args.workers} / --flush-interval {args.flush_interval}: "
            "expected workers >= 0 and flush interval > 0"
        )
    if not args.flush_period > 0 or args.flush_messages < 1:
        raise ValueError(
            f"--flush-period {args.flush_period} / --flush-messages {args.flush_messages}: "
            "expected seconds > 0 and messages >= 1"
        )
    if args.duration is not None and args.duration <= 0:
        raise ValueError(f"--duration {args.duration} is invalid: expected seconds > 0")
    run_config = None
    if args.config is not None:
        run_config = args.config.read_text(encoding="utf-8")
        try:
            yaml.safe_load(run_config)
        except yaml.YAMLError as exc:
            raise ValueError(f"--config {str(args.config)!r} is not valid YAML: {exc}") from exc
    output = args.output or Path(time.strftime("lubrig_%Y%m%d_%H%M%S"))
    should_stop = [False]

    def on_signal(_signum: int, _frame: object) -> None:
        should_stop[0] = True

    # before the bag exists: a Ctrl-C while it is being created must still leave it finalized
    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    # the fork server imports rclpy and this module while this process sets up its own node and
    # the bag, instead of after (start-up of a recorded run is on the critical path, issue 12)
    _context()
    mp_forkserver.ensure_running()
    recorder = Recorder(
        output, specs, args.workers or auto_workers(specs), run_config, args.use_sim_time,
        args.flush_interval, args.namespace, args.flush_period, args.flush_messages,
    )
    status = 0
    try:
        recorder.progress_per_block = args.progress_per_block
        recorder.start_progress()
        started = recorder.start_workers(should_stop=should_stop)
    except BagError:  # nothing recorded yet: one error line, exit 2 (run_script)
        with contextlib.suppress(BagError):
            recorder.shutdown()
        with bounded_teardown("recorder", lambda: 2):
            recorder.stop_progress()
        raise
    try:
        if started:
            print(
                f"recorder: recording {len(specs)} topics with {len(recorder.procs)} workers to {output}",
                flush=True,
            )
        else:
            print("recorder: stop requested while the workers were starting", flush=True)
        recorder.run(should_stop, args.duration)
    except BagError as exc:
        recorder.error(f"{exc}; recording stopped")
        status = 1
    finally:
        try:
            recorder.shutdown()
        except BagError as exc:
            recorder.error(str(exc))
            status = 1
    counts = ", ".join(f"{k}={v}" for k, v in recorder.writer.counts.items() if v)
    print(f"recorder: stopped; bag {output}: {counts}", flush=True)
    for name, account in recorder.accounts.items():
        print(f"recorder: samples {name}: {account.samples} in {account.messages} messages, "
              f"{account.missing} missing, {account.duplicates} duplicates, "
              f"{account.out_of_order} out of order", flush=True)
        if account.skipped:
            gaps = account.declared_gaps
            print(f"recorder: {name}: {account.skipped} samples skipped by the plant in "
                  f"{len(gaps)} declared gap(s) (it fell behind real time); first: {gaps[0].count} "
                  f"from index {gaps[0].first_index} of segment {gaps[0].segment}", flush=True)
    with contextlib.suppress(OSError):
        recorder.write_accounting()
    problems = recorder.problems()
    for line in problems:
        recorder.error(f"incomplete recording: {line}")
    status = 1 if problems else status
    # last, once the bag is final and the verdict printed: a hung teardown cannot cost either
    with bounded_teardown("recorder", lambda: status):
        recorder.stop_progress()
    return status


def main(argv: Sequence[str] | None = None) -> int:
    """Console script `recorder` (ROS arguments after --ros-args are ignored)."""
    return run_script("recorder", build_parser, run, argv, (ValueError, OSError, BagError))


if __name__ == "__main__":
    sys.exit(main())
