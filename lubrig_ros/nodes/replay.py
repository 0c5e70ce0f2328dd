"""`replay` node: republish a bag with its original timing (scaled by --rate), a player you can drive.

The whole bag is verified first (every chunk decompressed and CRC-checked, metadata.yaml
consistent); a truncated or corrupted bag is refused with one error line before anything is
published. Messages are published as recorded (serialized bytes, no re-encoding): blocks
(RigStateBlock, BandVelocityBlock) as blocks, RigState per sample. With --clock, /clock is
published from the bag's log times (and a recorded /clock topic is not replayed).

The player (app/recording/replay.py; its ROS side nodes/replay_player.py) plays from --start to
--until, pauses, steps one message, seeks and changes its rate through the services and
parameters of the node /lubrig_replay (docs/recording.md). With --lossless NODE ..., it
publishes the state blocks no faster than those nodes report on flow_progress that they took
them (the sim flow control, app/recording/replay_flow.py): no sample is lost to a slow subscriber.

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

from lubrig_ros.app.flow import qualified_name
from lubrig_ros.app.interface.cdr import sample_span
from lubrig_ros.app.interface.contract import DEFAULT_NAMESPACE, STREAM_QOS, documented_topics, resolve
from lubrig_ros.app.interface.node_parameters import DEFAULT_REPLAY_FLOW_WINDOW
from lubrig_ros.app.recording.replay import MAX_RATE, Entry, ReplaySession, check_rate
from lubrig_ros.app.recording.replay_flow import LosslessFlow
from lubrig_ros.bag.errors import BagError
from lubrig_ros.bag.reader import Bag
from lubrig_ros.core.errors import InputError
from lubrig_ros.nodes.graph import matched_every_subscription, subscribed_by
from lubrig_ros.nodes.script import run_script

LEGACY_STATE = "sensor_msgs/msg/JointState"
STATE_BLOCK = "lubrig_interfaces/msg/RigStateBlock"
#: The replay's node name (its services and parameters are under /lubrig_replay/).
NODE_NAME = "lubrig_replay"
#: Longest wait, after the last message, for the subscribers' acknowledgements (s).
DELIVERY_WAIT_S = 5.0
#: Longest --wait-for-subscribers, s.
MAX_WAIT_S = 3600.0
#: How the player is driven while it plays (the epilog of --help).
CONTROLS = (
    f"While it plays: `ros2 service call /{NODE_NAME}/pause std_srvs/srv/Trigger` (also resume, "
    f"toggle_paused, is_paused, play_next: one message of a paused replay), `ros2 param set "
    f"/{NODE_NAME} rate 4` (time scale) and `ros2 param set /{NODE_NAME} seek 12.5` (the next message "
    "is the first at or after 12.5 s of the bag). It ends after its last message (--until, the "
    "bag's end), unless --loop."
)


def build_parser(prog: str = "replay") -> argparse.ArgumentParser:
    """Arguments of the replay node (also used by `lubrig replay`)."""
    p = argparse.ArgumentParser(prog=prog, description=__doc__.splitlines()[0], epilog=CONTROLS)
    add_arguments(p)
    return p


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the replay arguments to p."""
    p.add_argument("bag", type=Path, help="bag directory")
    p.add_argument(
        "--rate", type=float, default=1.0, help=f"time scale (2 = twice as fast), in (0, {MAX_RATE:g}]"
    )
    p.add_argument("--loop", action="store_true", help="start over at --start after the end until stopped")
    p.add_argument("--topics", nargs="+", metavar="TOPIC", help="replay only these topics")
    p.add_argument(
        "--start", type=float, default=0.0, help="skip the first S seconds of the bag (less than its span)"
    )
    p.add_argument(
        "--until",
        type=float,
        default=None,
        metavar="T",
        help="stop after the last message at or before T seconds of the bag (after --start, within its span)",
    )
    p.add_argument(
        "--paused",
        action="store_true",
        help=f"start paused (services /{NODE_NAME}/resume, play_next, ...; docs/recording.md)",
    )
    p.add_argument(
        "--lossless",
        nargs="+",
        metavar="NODE",
        help="publish state blocks no faster than these nodes report taking them on flow_progress "
        "(fully qualified, or relative to --namespace): none is lost to a slow subscriber",
    )
    p.add_argument(
        "--flow-window",
        type=int,
        default=DEFAULT_REPLAY_FLOW_WINDOW,
        metavar="N",
        help="with --lossless: samples sent beyond the slowest subscriber's",
    )
    p.add_argument("--clock", action="store_true", help="publish /clock from the log times")
    p.add_argument(
        "--namespace", default=DEFAULT_NAMESPACE, help="for relative --topics and --lossless names"
    )
    p.add_argument(
        "--wait-for-subscribers",
        type=float,
        default=0.0,
        metavar="S",
        help=(
            "wait up to S seconds until every replayed topic has a subscriber (each one discovered "
            "matched; with --lossless a reliable one)"
        ),
    )


def _check_options(args: argparse.Namespace) -> None:
    """InputError naming a bad --rate, --start, --until, --flow-window or --wait-for-subscribers."""
    check_rate(args.rate)
    if not (math.isfinite(args.start) and args.start >= 0):
        raise InputError(f"--start {args.start} is invalid: expected seconds >= 0")
    if args.until is not None and not (math.isfinite(args.until) and args.until > args.start):
        raise InputError(f"--until {args.until} is invalid: expected seconds after --start {args.start:g}")
    if args.flow_window < 1:
        raise InputError(f"--flow-window {args.flow_window} is invalid: expected samples >= 1")
    if not (math.isfinite(args.wait_for_subscribers) and 0 <= args.wait_for_subscribers <= MAX_WAIT_S):
        raise InputError(
            f"--wait-for-subscribers {args.wait_for_subscribers} is invalid: expected seconds in "
            f"[0, {MAX_WAIT_S:g}]"
        )


def _check_range(args: argparse.Namespace, span_s: float) -> None:
    """InputError for a --start or --until outside the bag's span."""
    if args.start > 0 and args.start >= span_s:
        raise InputError(
            f"--start {args.start:g} is invalid: the bag spans {span_s:g} s; expected "
            f"seconds in [0, {span_s:g})"
        )
    if args.until is not None and args.until > span_s:
        raise InputError(
            f"--until {args.until:g} is invalid: the bag spans {span_s:g} s; expected seconds in "
            f"({args.start:g}, {span_s:g}]"
        )


def replayed_types(args: argparse.Namespace, summary: Any) -> dict[str, str]:
    """Topic -> type of what is replayed (bag checked; InputError for what cannot be replayed)."""
    _check_range(args, summary.duration_s)
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
    if args.lossless:  # the live subscribers' reports pace the replay, not the recorded ones
        types.pop(resolve(args.namespace, "flow_progress"), None)
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


def lossless_flow(args: argparse.Namespace, types: dict[str, str]) -> tuple[LosslessFlow | None, str]:
    """The flow control of --lossless (None without it) and the topic it paces."""
    paced = resolve(args.namespace, "state_block")
    if not args.lossless:
        return None, paced
    names = tuple(qualified_name(args.namespace, n) for n in args.lossless)
    if f"/{NODE_NAME}" in names:
        raise InputError(
            f"--lossless /{NODE_NAME} is the replay itself; expected its subscribers' node names"
        )
    if types.get(paced) != STATE_BLOCK:
        raise InputError(
            f"--lossless paces the state blocks ({paced}, {STATE_BLOCK}), which are not replayed; "
            f"replayed: {', '.join(types) or 'nothing'}"
        )
    return LosslessFlow(f"/{NODE_NAME}", names, args.flow_window), paced


def entries(bag: Bag, types: dict[str, str], flow: LosslessFlow | None, paced: str) -> list[Entry]:
    """The messages to replay in log-time order; with flow control, the paced blocks' samples."""
    out = []
    longest = 0
    for stream, t, data in bag.messages(list(types)):
        span = None
        if flow is not None and stream.topic == paced:
            span = sample_span(STATE_BLOCK, data)
            longest = max(longest, span.count)
        out.append(Entry(stream.topic, t, data, span))
    if flow is not None:
        flow.check_blocks(longest)
    return out


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
    flow, paced = lossless_flow(args, types)
    messages = entries(bag, types, flow, paced)

    import rclpy
    from rclpy.signals import SignalHandlerOptions
    from rosgraph_msgs.msg import Clock

    from lubrig_ros.nodes.interfaces import message_class, qos_profile
    from lubrig_ros.nodes.replay_player import Player, Spinner

    stop = [False]

    def on_signal(_s: int, _f: object) -> None:
        stop[0] = True

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(NODE_NAME)
    docs = documented_topics(args.namespace)
    pubs: dict[str, Any] = {}
    for name, msgtype in types.items():
        spec = docs.get(name)  # QoS from the contract; topics outside it as sample streams
        qos = qos_profile(spec.qos if spec else STREAM_QOS)
        pubs[name] = node.create_publisher(message_class(msgtype), name, qos)
    clock_qos = qos_profile(docs["/clock"].qos)
    clock_pub = node.create_publisher(Clock, "/clock", clock_qos) if args.clock else None
    session = ReplaySession(
        messages,
        origin_ns=summary.start_ns,
        now=time.monotonic(),
        rate=args.rate,
        start_s=args.start,
        until_s=args.until,
        loop=args.loop,
        paused=args.paused,
        flow=flow,
    )
    player = Player(node, session, pubs, clock_pub, stop)
    if flow is not None:
        progress = docs[resolve(args.namespace, "flow_progress")]
        node.create_subscription(
            message_class(progress.msgtype), progress.name, player.on_progress, qos_profile(progress.qos)
        )
    spinner = Spinner(node)
    deadline = time.monotonic() + args.wait_for_subscribers
    published = [*pubs.values(), *([clock_pub] if clock_pub is not None else [])]
    while time.monotonic() < deadline and not stop[0]:
        if subscribed(node, published, lossless=flow is not None):
            break
        time.sleep(0.05)
    with player.cond:
        if not session.paused and session.position == session.first:
            session.anchor = (time.monotonic(), session.start_ns)  # the schedule starts now
    print(
        f"replay: {summary.path.parent}: {len(pubs)} topics, rate {args.rate}"
        + (", paused" if args.paused else "")
        + (f", lossless to {', '.join(flow.subscribers)}" if flow is not None else ""),
        flush=True,
    )
    try:
        player.play()
        if not stop[0]:
            _await_delivery(published)
    finally:
        spinner.stop()
        node.destroy_node()
        rclpy.shutdown()
    print(f"replay: published {session.published} messages", flush=True)
    return 0


def subscribed(node: Any, publishers: Sequence[Any], lossless: bool) -> bool:
    """A subscriber on every topic, and each discovered one matched (nodes/graph.py says why).

    Lossless: on every topic a subscriber that takes every sample (a reliable one on a reliable
    topic): a node's use_sim_time /clock reader is best effort and does not record /clock.
    """
    if lossless and not subscribed_by(node, publishers, ""):
        return False
    return all(p.get_subscription_count() > 0 and matched_every_subscription(node, p) for p in publishers)


def _await_delivery(publishers: Sequence[Any]) -> None:
    """Wait until every reliable subscriber has acknowledged what was published (DELIVERY_WAIT_S at most).

    A publisher destroyed with samples unacknowledged drops them: a subscriber that had not yet
    taken the last messages would never get them. One line names the topics still unacknowledged.
    """
    from rclpy.duration import Duration

    deadline = time.monotonic() + DELIVERY_WAIT_S
    late = [
        p.topic_name
        for p in publishers
        if not p.wait_for_all_acked(Duration(seconds=max(0.0, deadline - time.monotonic())))
    ]
    if late:
        print(
            f"replay: not acknowledged by every subscriber within {DELIVERY_WAIT_S:g} s: {', '.join(late)}",
            flush=True,
        )


def main(argv: Sequence[str] | None = None) -> int:
    """Console script `replay` (ROS arguments after --ros-args are ignored)."""
    return run_script("replay", build_parser, run, argv, (ValueError, OSError, BagError))


if __name__ == "__main__":
    sys.exit(main())
