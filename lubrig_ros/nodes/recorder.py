"""`recorder` node: record the rig's topics into a rosbag2 bag (MCAP, zstd chunks).

The node is glue: subscriber processes (nodes/recorder_workers.py: raw subscriptions, batches of
serialized messages) feed a recording session (bag/recording.py: log times, the bag, accounting,
what flow progress to report), and this process's own node publishes that progress.

Accounting (app/recording/accounting.py): every RigState, RigStateBlock and BandVelocityBlock written is
counted per stream from its sample index and segment; gaps, duplicates and samples out of order
are printed at the end, written to <bag>/accounting.json, and make the exit status 1.

Flow control (sim): this process is the node ``<namespace>/lubrig_recorder`` (RECORDER_NODE) and
publishes lubrig_interfaces/FlowProgress on ``<namespace>/flow_progress``: samples 0 once its
state_block subscription and that of every --require-samples stream have matched a publisher
(a reader drops what arrives before it has matched the writer; a required stream is waited for
REQUIRED_MATCH_WAIT_S, then named in a warning), after every state_block it has written the
samples of that segment taken in order (with band_velocity_block required: only those whose band
samples are written too, bag/recording.py `reach`), and the latest value again every 0.2 s (heartbeat);
with --progress-heartbeat-only (`lubrig rig` in the wall-clock modes, where nothing paces on
it) only on matching and as the heartbeat.

Log times: receive time (system clock, ns); with --use-sim-time the rig time (bag/recording.py
says how each message is placed; in a sim rig every stamp is rig time). --use-sim-time also gives
this process's ROS nodes (flow progress, workers) use_sim_time true, as every node of a sim rig has.

Exit status: 0 after a clean stop (SIGINT/SIGTERM or --duration) with every stream complete,
2 on bad arguments or an unwritable output, 1 if writing failed while recording (the bag is then
finalized up to the last flushed chunk) or a stream has a gap, a duplicate or a sample out of
order (named on stderr).
"""

from __future__ import annotations

import argparse
import contextlib
import math
import signal
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

from lubrig_ros.app.interface.contract import (
    DEFAULT_NAMESPACE,
    RECORDER_PARTICIPANT,
    Topic,
    documented_topics,
    resolve,
)
from lubrig_ros.app.interface.contract import select_topics as _select_topics
from lubrig_ros.app.processes.startup_trace import mark
from lubrig_ros.bag.errors import BagError
from lubrig_ros.bag.layout import typestore
from lubrig_ros.bag.recording import REQUIRED_MATCH_WAIT_S, RecordingSession, required_streams
from lubrig_ros.bag.writer import BagWriter
from lubrig_ros.core.errors import InputError
from lubrig_ros.nodes.recorder_workers import PoolMessage, WorkerPool, sim_time_overrides, start_fork_server
from lubrig_ros.nodes.script import bounded_teardown, run_script

#: The recorder's flow-control participant: <namespace>/lubrig_recorder (app/interface/contract.py
#: RECORDER_PARTICIPANT; `lubrig rig` puts it in belt_drive's required_consumers).
RECORDER_NODE = RECORDER_PARTICIPANT
#: The participant name (relative to the namespace) `lubrig rig` checks before pacing on it.
FLOW_PARTICIPANT = RECORDER_NODE
#: After a stop request, wait up to this long for samples the plant announced but not yet taken.
CATCH_UP_S = 5.0


class ProgressNode:
    """The recorder process's own node <namespace>/lubrig_recorder: FlowProgress and /rosout (not spun)."""

    def __init__(self, namespace: str, use_sim_time: bool) -> None:
        import rclpy
        from rclpy.signals import SignalHandlerOptions

        from lubrig_ros.nodes.common import unspun_node
        from lubrig_ros.nodes.interfaces import message_class, qos_profile

        rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
        self.node: Any = unspun_node(RECORDER_NODE, namespace, overrides=sim_time_overrides(use_sim_time))
        spec = documented_topics(namespace)[resolve(namespace, "flow_progress")]
        self.cls = message_class(spec.msgtype)
        self.pub: Any = self.node.create_publisher(self.cls, spec.name, qos_profile(spec.qos))
        self.participant: str = self.node.get_fully_qualified_name()

    def publish(self, segment: int, samples: int, stamp_ns: int) -> None:
        """FlowProgress(segment, samples), stamped with the rig time of the newest sample."""
        msg = self.cls()
        msg.participant, msg.segment, msg.samples = self.participant, segment, samples
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(max(stamp_ns, 0), 1_000_000_000)
        self.pub.publish(msg)

    def destroy(self) -> None:
        """Destroy the node and rclpy's context of this process."""
        import rclpy

        with contextlib.suppress(Exception):
            self.node.destroy_node()
            rclpy.shutdown()


class Recorder:
    """The recorder process: a worker pool feeding a recording session, flow progress published."""

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
        self.session = RecordingSession(
            output, specs, run_config, use_sim_time, namespace, flush_period, flush_messages
        )
        self.session.participant = resolve(namespace, RECORDER_NODE)
        self.pool = WorkerPool([s.spec for s in self.session.streams], workers, use_sim_time, namespace)
        self.namespace = namespace
        self.use_sim_time = use_sim_time
        self.flush_interval = flush_interval
        self.progress_node: ProgressNode | None = None

    def start_progress(self, per_block: bool) -> None:
        """Create this process's node, if the state_block stream is recorded (sim flow control)."""
        self.session.progress_per_block = per_block
        if not self.session.records_state_block:
            return
        self.progress_node = ProgressNode(self.namespace, self.use_sim_time)
        self.session.participant = self.progress_node.participant
        self.session.on_progress = self.progress_node.publish

    def _message(self, message: PoolMessage) -> None:
        """A worker's "data" batch, "matched" or "graph" report (anything else is ignored)."""
        kind, wid, payload = message
        if kind == "data":
            self.session.handle(payload)
        elif kind == "matched":
            self.session.matched(payload)
        elif kind == "graph":
            self.session.graph(wid, *payload)

    def start_workers(self, timeout: float = 90.0, should_stop: Sequence[bool] = (False,)) -> bool:
        """Start the subscriber processes; see WorkerPool.start."""
        return self.pool.start(self._message, timeout, should_stop)

    def error(self, text: str) -> None:
        """An error line: on stderr (`recorder: error: ...`) and, once the node is up, on /rosout."""
        self._say("error", text)

    def warning(self, text: str) -> None:
        """A warning line: on stderr (`recorder: warning: ...`) and, once the node is up, on /rosout."""
        self._say("warning", text)

    def _say(self, level: str, text: str) -> None:
        print(f"recorder: {level}: {text}", file=sys.stderr, flush=True)
        if self.progress_node is not None:
            with contextlib.suppress(Exception):  # a context already shut down: stderr has it
                getattr(self.progress_node.node.get_logger(), level)(text)

    def stop_progress(self) -> None:
        """Destroy the progress node (and rclpy's context of this process)."""
        if self.progress_node is not None:
            self.session.on_progress = None
            self.progress_node.destroy()
            self.progress_node = None

    def run(self, should_stop: list[bool], duration: float | None) -> None:
        """Write batches until should_stop[0] or duration elapses, then drain the workers."""
        session = self.session
        session.start()
        end = time.monotonic() + duration if duration else math.inf
        catch_up = math.inf
        while time.monotonic() < min(end, catch_up):
            if should_stop[0] and catch_up == math.inf:
                catch_up = time.monotonic() + CATCH_UP_S  # take what the plant announced first
            if should_stop[0] and not session.behind():
                break
            message = self.pool.get(0.05)
            if message is not None:
                self._message(message)
            elif session.held:
                session.handle([])
            waiting = session.progress is None
            session.heartbeat()
            if waiting and session.ready_without:
                self.warning(
                    f"no publisher of required stream(s) {', '.join(session.ready_without)} "
                    f"{REQUIRED_MATCH_WAIT_S:g} s after state_block's: reporting ready without them "
                    "(their first samples may be lost)"
                )
            if waiting and session.ready_lagging:
                self.warning(
                    f"stream(s) {', '.join(session.ready_lagging)} not matched to every publisher on "
                    f"the graph {REQUIRED_MATCH_WAIT_S:g} s after state_block's (a publisher of another "
                    "type or QoS?): reporting ready without them (their first samples may be lost)"
                )
            session.flush_if_due(self.flush_interval)
            self.pool.check_alive()
        self.drain()

    def drain(self) -> None:
        """Stop the workers and write everything they received."""
        session = self.session

        def write(batch: list[tuple[int, int, bytes]]) -> None:
            if not session.writer.failed:
                session.handle(batch)

        self.pool.drain(write)
        if session.held and not session.writer.failed:
            session.handle([], force=True)

    def shutdown(self) -> None:
        """Stop the workers (if still running) and finalize the bag (repaired after a write failure)."""
        self.pool.stop()
        self.session.close()


# ----------------------------------------------------------------------------- command line


def build_parser() -> argparse.ArgumentParser:
    """Arguments of the recorder node."""
    p = argparse.ArgumentParser(prog="recorder", description=__doc__.splitlines()[0])
    p.add_argument("-o", "--output", type=Path, help="new bag directory (default: lubrig_<time>)")
    p.add_argument("--namespace", default=DEFAULT_NAMESPACE, help="rig namespace (default /lubrig)")
    p.add_argument(
        "--topics",
        nargs="+",
        metavar="TOPIC",
        help="topics to record (relative names go under the namespace; default: all documented)",
    )
    p.add_argument("--config", type=Path, help="YAML file of the run configuration to store")
    p.add_argument("--use-sim-time", action="store_true", help="log times from rig time (/clock)")
    p.add_argument("--workers", type=int, default=0, help="subscriber processes (0: auto)")
    p.add_argument(
        "--flush-interval",
        type=float,
        default=0.5,
        help="wall-clock seconds between flushes to the disk (fsync)",
    )
    p.add_argument(
        "--flush-period",
        type=float,
        default=BagWriter.FLUSH_PERIOD_NS / 1e9,
        help="close a chunk once its messages span this many seconds of log (rig) time: "
        "the most a SIGKILL or a full disk loses (default 0.2)",
    )
    p.add_argument(
        "--flush-messages",
        type=int,
        default=BagWriter.FLUSH_MESSAGES,
        help=f"... or once it holds this many messages (default {BagWriter.FLUSH_MESSAGES})",
    )
    p.add_argument("--duration", type=float, help="stop after this many seconds")
    p.add_argument(
        "--require-samples",
        nargs="+",
        default=[],
        metavar="TOPIC",
        help="recorded sample streams (e.g. state_block band_velocity_block) that must hold samples: "
        "one that got none makes the recording incomplete (exit status 1)",
    )
    p.add_argument(
        "--progress-heartbeat-only",
        dest="progress_per_block",
        action="store_false",
        help="FlowProgress once the subscriptions to state_block and the required streams have "
        "matched and then every 0.2 s, "
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
        raise InputError(
            f"--workers {args.workers} / --flush-interval {args.flush_interval}: "
            "expected workers >= 0 and flush interval > 0"
        )
    if not args.flush_period > 0 or args.flush_messages < 1:
        raise InputError(
            f"--flush-period {args.flush_period} / --flush-messages {args.flush_messages}: "
            "expected seconds > 0 and messages >= 1"
        )
    if args.duration is not None and args.duration <= 0:
        raise InputError(f"--duration {args.duration} is invalid: expected seconds > 0")
    run_config = None
    if args.config is not None:
        run_config = args.config.read_text(encoding="utf-8")
        try:
            yaml.safe_load(run_config)
        except yaml.YAMLError as exc:
            raise InputError(f"--config {str(args.config)!r} is not valid YAML: {exc}") from exc
    required = required_streams(specs, [resolve(args.namespace, n) for n in args.require_samples])
    output = args.output or Path(time.strftime("lubrig_%Y%m%d_%H%M%S"))
    should_stop = [False]

    def on_signal(_signum: int, _frame: object) -> None:
        should_stop[0] = True

    # before the bag exists: a Ctrl-C while it is being created must still leave it finalized
    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    # the fork server imports rclpy while this process sets up its own node and the bag, not
    # after (start-up of a recorded run is on the critical path)
    start_fork_server()
    recorder = Recorder(
        output,
        specs,
        args.workers or auto_workers(specs),
        run_config,
        args.use_sim_time,
        args.flush_interval,
        args.namespace,
        args.flush_period,
        args.flush_messages,
    )
    recorder.session.required = required
    try:
        recorder.start_progress(args.progress_per_block)
        started = recorder.start_workers(should_stop=should_stop)
    except BagError:  # nothing recorded yet: one error line, exit 2 (run_script)
        with contextlib.suppress(BagError):
            recorder.shutdown()
        with bounded_teardown("recorder", lambda: 2):
            recorder.stop_progress()
        raise
    status = _record(recorder, started, should_stop, args.duration, output)
    status = _verdict(recorder, output) or status
    # last, once the bag is final and the verdict printed: a hung teardown cannot cost either
    with bounded_teardown("recorder", lambda: status):
        recorder.stop_progress()
    return status


def _record(
    recorder: Recorder, started: bool, should_stop: list[bool], duration: float | None, output: Path
) -> int:
    """Record until the stop and finalize the bag: 0, or 1 if writing failed."""
    status = 0
    try:
        if started:
            mark("recorder", "recording")
            print(
                f"recorder: recording {len(recorder.session.streams)} topics with "
                f"{len(recorder.pool.procs)} workers to {output}",
                flush=True,
            )
        else:
            print("recorder: stop requested while the workers were starting", flush=True)
        recorder.run(should_stop, duration)
    except BagError as exc:
        recorder.error(f"{exc}; recording stopped")
        status = 1
    finally:
        try:
            recorder.shutdown()
        except BagError as exc:
            recorder.error(str(exc))
            status = 1
    return status


def _verdict(recorder: Recorder, output: Path) -> int:
    """Print what was recorded, write accounting.json; 1 if a stream has a problem, else 0."""
    session = recorder.session
    counts = ", ".join(f"{k}={v}" for k, v in session.writer.counts.items() if v)
    print(f"recorder: stopped; bag {output}: {counts}", flush=True)
    for name, account in session.accounts.items():
        print(
            f"recorder: samples {name}: {account.samples} in {account.messages} messages, "
            f"{account.missing} missing, {account.duplicates} duplicates, "
            f"{account.out_of_order} out of order",
            flush=True,
        )
        if account.skipped:
            gaps = account.declared_gaps
            print(
                f"recorder: {name}: {account.skipped} samples skipped by the plant in "
                f"{len(gaps)} declared gap(s) (it fell behind real time); first: {gaps[0].count} "
                f"from index {gaps[0].first_index} of segment {gaps[0].segment}",
                flush=True,
            )
    with contextlib.suppress(OSError):
        session.write_accounting()
    problems = session.problems()
    for line in problems:
        recorder.error(f"incomplete recording: {line}")
    return 1 if problems else 0


def prepare() -> None:
    """While `lubrig rig`'s start gate holds the process (nodes/entry.py): the fork server, the types.

    The fork server imports rclpy and the workers' modules (about 0.5 s of CPU) and joins no
    graph; `run` finds it running. It ends with this process, also when the gate stays shut. The
    bag's type store (rosbags' types and lubrig_interfaces', 0.13 s) is built once per process
    and the writer needs it first: built here, not between the gate and the workers' start.
    """
    start_fork_server()
    typestore()


def main(argv: Sequence[str] | None = None) -> int:
    """Console script `recorder` (ROS arguments after --ros-args are ignored)."""
    return run_script("recorder", build_parser, run, argv, (ValueError, OSError, BagError))


if __name__ == "__main__":
    sys.exit(main())
