"""The recorder's subscriber processes: raw subscriptions in worker processes, batches to the writer.

Subscriptions are spread over worker processes (multiprocessing, forkserver: the server imports
rclpy and this module once, each worker is forked from it, so three workers cost one import,
about 0.8 s of CPU each at start-up otherwise; nothing of ROS is initialized in the server, so
forking it is safe). Each worker runs a real rclpy node ``<namespace>/lubrig_recorder_w<i>`` with
raw subscriptions (serialized CDR bytes, no deserialization) spun by rclpy's EventsExecutor in a
spin_once loop, and ships (stream index, receive time, bytes) batches to the recorder process, the
only writer of the bag: block messages at once, others every BATCH_PERIOD_S.

Messages on the pool's queue: ("ready", wid, None) once a worker has subscribed, ("matched", wid,
[stream index]) once a subscription has a publisher, ("graph", wid, ({topic: publishers on its
graph}, {stream index: publishers its reader has matched})) whenever either changes (every
recorded topic: each worker discovers each publisher on its own, and a reader is held to what any
worker sees; bag/recording.py `unmatched_publishers`), ("data", wid, [(stream, recv_ns, bytes)]),
and ("done", wid, None) after its last batch.
"""

from __future__ import annotations

import multiprocessing as mp
import multiprocessing.forkserver as mp_forkserver
import os
import queue
import signal
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

from lubrig_ros.app.interface.contract import DEFAULT_NAMESPACE, RECORDER_PARTICIPANT, QoS, Topic
from lubrig_ros.app.processes.lifetime import die_with_parent
from lubrig_ros.bag.errors import BagError

#: A worker ships its batch of non-block messages this often (s).
BATCH_PERIOD_S = 0.02
#: Samples kept by each reader while its worker is busy (reader_qos).
READER_DEPTH = 10_000
#: Longest a worker waits for a message before it checks shipping and stop (s); a message wakes it.
WORKER_WAIT_S = 0.02
#: Block types: a worker ships a batch holding one at once (sim flow control waits for it).
BLOCK_TYPES = ("lubrig_interfaces/msg/RigStateBlock", "lubrig_interfaces/msg/BandVelocityBlock")

#: One queue message: (kind, worker id, payload); see the module docstring.
PoolMessage = tuple[str, int, Any]


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
        [
            "lubrig_ros.nodes.recorder_forkserver",
            "rclpy",
            "rclpy.experimental",
            "lubrig_ros.nodes.interfaces",
            __name__,
        ]
    )
    return ctx


def start_fork_server() -> None:
    """Start the fork server now: it imports rclpy while the recorder sets up its node and bag."""
    _context()
    mp_forkserver.ensure_running()


def sim_time_overrides(use_sim_time: bool) -> list[Any]:
    """parameter_overrides of the recorder's ROS nodes: use_sim_time as the recorder was asked."""
    from rclpy.parameter import Parameter

    return [Parameter("use_sim_time", Parameter.Type.BOOL, True)] if use_sim_time else []


def _worker(
    wid: int,
    specs: list[Topic],
    streams: list[int],
    out: Any,
    stop: Any,
    use_sim_time: bool = False,
    namespace: str = DEFAULT_NAMESPACE,
    recorded: Sequence[str] = (),
) -> None:
    """Subscribe to specs (raw) and ship batches of (stream index, recv_ns, bytes) to out.

    `recorded`: every topic the recorder records (all workers'): the worker reports the publishers
    it sees of each (the "graph" message), so that the readers of another worker can be held to
    what this one has discovered.

    Spun by rclpy's EventsExecutor with spin_once (its spin() fires no timer in this wheel and
    keeps a core busy: ../shared/ros2-interfaces-on-pip.md), so shipping and the stop check are
    done in the loop.
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
        f"{RECORDER_PARTICIPANT}_w{wid}",
        namespace=namespace,
        parameter_overrides=sim_time_overrides(use_sim_time),
    )
    batch: list[tuple[int, int, bytes]] = []
    urgent = [False]
    now = time.time_ns

    def make_cb(index: int, block: bool) -> Callable[[bytes], None]:
        def cb(data: bytes) -> None:
            batch.append((index, now(), data))
            if block:
                urgent[0] = True

        return cb

    subs = [  # QoS from the contract (app/interface/contract.py), deeper history
        node.create_subscription(
            message_class(spec.msgtype),
            spec.name,
            make_cb(index, spec.msgtype in BLOCK_TYPES),
            qos_profile(reader_qos(spec.qos)),
            raw=True,
        )
        for spec, index in zip(specs, streams, strict=True)
    ]
    executor = EventsExecutor()
    executor.add_node(node)
    out.put(("ready", wid, None))
    unmatched = set(range(len(subs)))
    view: tuple[tuple[int, ...], tuple[int, ...]] | None = None  # the last "graph" report
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
                    out.put(("matched", wid, [streams[i] for i in matched]))
                seen = tuple(node.count_publishers(name) for name in recorded)
                counts = tuple(sub.get_publisher_count() for sub in subs)
                if (seen, counts) != view:
                    view = (seen, counts)
                    report = (dict(zip(recorded, seen, strict=True)), dict(zip(streams, counts, strict=True)))
                    out.put(("graph", wid, report))
        # what arrived before the stop was seen: take it, then ship the rest
        for _ in range(1000):
            before = len(batch)
            executor.spin_once(timeout_sec=0.01)
            if len(batch) == before:
                break
    finally:
        out.put(("data", wid, batch))
        out.put(("done", wid, None))
        executor.shutdown(timeout_sec=1.0)  # before destroy_node, as nodes.common.spin_node
        node.destroy_node()
        rclpy.shutdown()


class WorkerPool:
    """The worker processes of one recorder: stream i of `specs` is recorded by worker i % workers."""

    def __init__(self, specs: Sequence[Topic], workers: int, use_sim_time: bool, namespace: str) -> None:
        self.specs = list(specs)
        self.n_workers = max(1, min(workers, len(self.specs)))
        self.use_sim_time = use_sim_time
        self.namespace = namespace
        ctx = _context()
        self.queue: Any = ctx.Queue()
        self.stop_event: Any = ctx.Event()
        self.procs: list[Any] = []  # forkserver-context processes
        self.groups = [list(range(i, len(self.specs), self.n_workers)) for i in range(self.n_workers)]

    def start(
        self,
        on_message: Callable[[PoolMessage], None],
        timeout: float = 90.0,
        should_stop: Sequence[bool] = (False,),
    ) -> bool:
        """Start the workers; True once all have subscribed (other messages go to on_message).

        False at once if should_stop[0] becomes true meanwhile (a Ctrl-C while a loaded machine is
        still starting the workers: the stop must not wait for them). BagError, naming the
        worker's topics, if one dies or is not ready within timeout s.
        """
        ctx = _context()
        for wid, group in enumerate(self.groups):
            proc = ctx.Process(
                target=_worker,
                args=(
                    wid,
                    [self.specs[i] for i in group],
                    group,
                    self.queue,
                    self.stop_event,
                    self.use_sim_time,
                    self.namespace,
                    [spec.name for spec in self.specs],
                ),
                daemon=True,
            )
            proc.start()
            self.procs.append(proc)
        ready: set[int] = set()
        deadline = time.monotonic() + timeout
        while len(ready) < len(self.procs):
            if should_stop[0]:
                return False
            message = self.get(0.2)
            if message is not None and message[0] == "ready":
                ready.add(message[1])
            elif message is not None:
                on_message(message)
            self._check_starting(ready, deadline, timeout)
        return True

    def _check_starting(self, ready: set[int], deadline: float, timeout: float) -> None:
        for wid, (proc, group) in enumerate(zip(self.procs, self.groups, strict=True)):
            if wid in ready:
                continue
            names = ", ".join(self.specs[i].name for i in group)
            if not proc.is_alive():
                raise BagError(
                    f"recorder worker {wid} ({names}) exited with status {proc.exitcode} before subscribing"
                )
            if time.monotonic() > deadline:
                raise BagError(f"recorder worker {wid} ({names}) not ready after {timeout:g} s")

    def get(self, timeout: float) -> PoolMessage | None:
        """The next message of a worker, or None after timeout s."""
        try:
            message: PoolMessage = self.queue.get(timeout=timeout)
        except queue.Empty:
            return None
        return message

    def check_alive(self) -> None:
        """BagError if a worker process died while recording."""
        if any(not p.is_alive() for p in self.procs):
            raise BagError("a recorder worker process died; recording stopped")

    def drain(self, on_batch: Callable[[list[tuple[int, int, bytes]]], None], timeout: float = 10.0) -> None:
        """Stop the workers and pass on everything they received (at most timeout s)."""
        self.stop_event.set()
        done = 0
        deadline = time.monotonic() + timeout
        while done < len(self.procs) and time.monotonic() < deadline:
            message = self.get(0.2)
            if message is None:
                if not any(p.is_alive() for p in self.procs):
                    break
                continue
            if message[0] == "data":
                on_batch(message[2])
            elif message[0] == "done":
                done += 1

    def stop(self) -> None:
        """Stop the workers (if still running): 3 s each to end, then SIGKILL."""
        self.stop_event.set()
        for p in self.procs:
            p.join(timeout=3)
            if p.is_alive():
                p.kill()
