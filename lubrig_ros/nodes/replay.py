"""`replay` node: republish a bag with its original timing (scaled by --rate).

The whole bag is verified first (every chunk decompressed and CRC-checked, metadata.yaml
consistent); a truncated or corrupted bag is refused with one error line before anything is
published. Messages are published as recorded (serialized bytes, no re-encoding): blocks
(RigStateBlock, BandVelocityBlock) as blocks, RigState per sample. With --clock, /clock is
published from the bag's log times (and a recorded /clock topic is not replayed).

A bag of the legacy layout (sensor_msgs/JointState on <ns>/state, recorded before
lubrig_interfaces) is refused with one line when its state topic is selected: the current nodes
subscribe to lubrig_interfaces/RigState there, so nothing would consume it (`lubrig report`
still reads such bags; its other topics can be replayed with --topics).
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from lubrig_ros.app.contract import DEFAULT_NAMESPACE, STREAM_QOS, documented_topics, resolve
from lubrig_ros.bag.errors import BagError
from lubrig_ros.bag.reader import Bag
from lubrig_ros.core.errors import InputError
from lubrig_ros.nodes.script import run_script

LEGACY_STATE = "sensor_msgs/msg/JointState"
#: Fastest --rate (time scale): beyond it a 1 kHz bag is 1 MHz of messages, no replay.
MAX_RATE = 1000.0
#: Longest --wait-for-subscribers, s.
MAX_WAIT_S = 3600.0


def build_parser(prog: str = "replay") -> argparse.ArgumentParser:
    """Arguments of the replay node (also used by `lubrig replay`)."""
    p = argparse.ArgumentParser(prog=prog, description=__doc__.splitlines()[0])
    add_arguments(p)
    return p


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the replay arguments to p."""
    p.add_argument("bag", type=Path, help="bag directory")
    p.add_argument(
        "--rate", type=float, default=1.0, help=f"time scale (2 = twice as fast), in (0, {MAX_RATE:g}]"
    )
    p.add_argument("--loop", action="store_true", help="start over at the end until stopped")
    p.add_argument("--topics", nargs="+", metavar="TOPIC", help="replay only these topics")
    p.add_argument(
        "--start", type=float, default=0.0, help="skip the first S seconds of the bag (less than its span)"
    )
    p.add_argument("--clock", action="store_true", help="publish /clock from the log times")
    p.add_argument("--namespace", default=DEFAULT_NAMESPACE, help="for relative --topics names")
    p.add_argument(
        "--wait-for-subscribers",
        type=float,
        default=0.0,
        metavar="S",
        help="wait up to S seconds until every replayed topic has a subscriber",
    )


def _check_options(args: argparse.Namespace) -> None:
    """InputError naming a bad --rate, --start or --wait-for-subscribers."""
    if not (math.isfinite(args.rate) and 0 < args.rate <= MAX_RATE):
        raise InputError(f"--rate {args.rate} is invalid: expected a time scale in (0, {MAX_RATE:g}]")
    if not (math.isfinite(args.start) and args.start >= 0):
        raise InputError(f"--start {args.start} is invalid: expected seconds >= 0")
    if not (math.isfinite(args.wait_for_subscribers) and 0 <= args.wait_for_subscribers <= MAX_WAIT_S):
        raise InputError(
            f"--wait-for-subscribers {args.wait_for_subscribers} is invalid: expected seconds in "
            f"[0, {MAX_WAIT_S:g}]"
        )


def replayed_types(args: argparse.Namespace, summary: Any) -> dict[str, str]:
    """Topic -> type of what is replayed (bag checked; InputError for what cannot be replayed)."""
    if args.start > 0 and args.start >= summary.duration_s:
        raise InputError(
            f"--start {args.start:g} is invalid: the bag spans {summary.duration_s:g} s; expected "
            f"seconds in [0, {summary.duration_s:g})"
        )
    types = {t.name: t.msgtype for t in summary.topics if t.count}
    if args.topics:
        wanted = [resolve(args.namespace, n) for n in args.topics]
        unknown = [n for n in wanted if n not in types]
        if unknown:
            raise InputError(
                f"--topics {', '.join(unknown)} not in bag; topics with messages: {', '.join(types)}"
            )
        types = {n: types[n] for n in wanted}
    if args.clock:
        types.pop("/clock", None)
    legacy = [name for name, msgtype in types.items() if msgtype == LEGACY_STATE and name.endswith("/state")]
    if legacy:
        others = [n for n in types if n not in legacy]
        raise InputError(
            f"bag {str(args.bag)!r} has the legacy layout ({LEGACY_STATE} on {', '.join(legacy)}, "
            "recorded before lubrig_interfaces): the current nodes read lubrig_interfaces/msg/RigState "
            f"there, so it is not replayed; `lubrig report {args.bag}` still reads the bag"
            + (f"; replay its other topics with --topics {' '.join(others)}" if others else "")
        )
    return types


def run(args: argparse.Namespace, bag: Bag | None = None) -> int:
    """Check the bag, then publish it; returns the exit status.

    bag: the bag args.bag already read (`lubrig replay` checks it first); else it is read here.
    The file is read once, however often --loop publishes it.
    """
    _check_options(args)
    if bag is None:
        bag = Bag(args.bag)
    summary = bag.summary()
    types = replayed_types(args, summary)

    import rclpy
    from rclpy.signals import SignalHandlerOptions
    from rosgraph_msgs.msg import Clock

    from lubrig_ros.nodes.interfaces import message_class, qos_profile

    stop = [False]

    def on_signal(_s: int, _f: object) -> None:
        stop[0] = True

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("lubrig_replay")
    docs = documented_topics(args.namespace)
    pubs: dict[str, Any] = {}
    for name, msgtype in types.items():
        spec = docs.get(name)  # QoS from the contract; topics outside it as sample streams
        qos = qos_profile(spec.qos if spec else STREAM_QOS)
        pubs[name] = node.create_publisher(message_class(msgtype), name, qos)
    clock_qos = qos_profile(docs["/clock"].qos)
    clock_pub = node.create_publisher(Clock, "/clock", clock_qos) if args.clock else None
    deadline = time.monotonic() + args.wait_for_subscribers
    while time.monotonic() < deadline and not stop[0]:
        if all(p.get_subscription_count() > 0 for p in pubs.values()):
            break
        time.sleep(0.05)
    print(f"replay: {summary.path.parent}: {len(pubs)} topics, rate {args.rate}", flush=True)
    first = summary.start_ns + round(args.start * 1e9)
    published = 0
    clock = Clock()
    try:
        while not stop[0]:
            t0 = time.monotonic()
            for stream, t, data in bag.messages(list(pubs)):
                topic = stream.topic
                if stop[0]:
                    break
                if t < first:
                    continue
                if not sleep_until(t0 + (t - first) / 1e9 / args.rate, stop):
                    break
                if clock_pub is not None:
                    clock.clock.sec, clock.clock.nanosec = divmod(t, 1_000_000_000)
                    clock_pub.publish(clock)
                pubs[topic].publish(data)
                published += 1
            if not args.loop:
                break
        time.sleep(0.5)  # let reliable delivery of the last messages complete
    finally:
        node.destroy_node()
        rclpy.shutdown()
    print(f"replay: published {published} messages", flush=True)
    return 0


def sleep_until(deadline: float, stop: list[bool], step: float = 0.1) -> bool:
    """Sleep until time.monotonic() reaches deadline, in slices of at most step s.

    Returns False as soon as stop[0] is set (a signal handler returning resumes a plain
    time.sleep, so a long gap at a low --rate could not be interrupted).
    """
    while not stop[0]:
        left = deadline - time.monotonic()
        if left <= 0:
            return True
        time.sleep(min(step, left))
    return False


def main(argv: Sequence[str] | None = None) -> int:
    """Console script `replay` (ROS arguments after --ros-args are ignored)."""
    return run_script("replay", build_parser, run, argv, (ValueError, OSError, BagError))


if __name__ == "__main__":
    sys.exit(main())
