"""Synthetic rig traffic for tests and benchmarks (real rclpy nodes, documented types).

``python -m lubrig_testkit.synthetic publish --rate 1000 --samples 3000`` publishes what the plant
publishes per sample in realtime mode: ``state`` (lubrig_interfaces/RigState, sample_index k,
segment 0), ``band_velocity`` and (``--scalars``) displacement, velocity, friction_coefficient
(Float64), and ``/clock`` (``--clock``; start + k/rate). Sample k carries value k (displacement,
Float64 data, RigState.band_velocity; velocity 0.5 k, friction force -k). It waits until every
topic has a subscriber, then prints one JSON line ``{"published": {topic: samples}, ...}``.
Paced at --rate on the wall clock (a realtime source: a slow subscriber can lose samples), or,
with ``--flow-control N``, unpaced but waiting after every N samples until every subscriber has
acknowledged them (reliable delivery; the tests' way to need no assumption about speed).

``--blocks N``: the sim layout instead: ``state_block`` (RigStateBlock) and
``band_velocity_block`` (BandVelocityBlock) of N samples, one ``/clock`` per block, and the node is
``<namespace>/plant`` reporting its own FlowProgress after every block. With ``--consumer FQN``
(e.g. ``/lubrig/lubrig_recorder``) it is paced like belt_drive: it waits for the consumer's first
FlowProgress and never runs more than ``--flow-window`` samples ahead of the consumer's reported
progress; at the end it waits until the consumer has reported every sample. Paced, it also writes
``published N`` to stderr after every block: what it published, even when it is killed stalled.

``--skip K ...``: sample indices never published (the gap tests): per sample, state has no
message for K; with blocks, the block holding K is not published.

``python -m lubrig_testkit.synthetic listen --topics T... --count N --output F.json`` records the
Float64/Clock/RigState values it receives with receive times and writes them as JSON.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence

from lubrig_ros.app.interface.contract import DEFAULT_NAMESPACE, documented_topics, resolve
from lubrig_ros.app.plant.output import BLOCK_FIELDS

START_NS = 1_000_000_000  # rig time of sample 0
PER_SAMPLE_TOPICS = ("state", "band_velocity")
SCALAR_TOPICS = ("displacement", "velocity", "friction_coefficient")
BLOCK_TOPICS = ("state_block", "band_velocity_block")


def topics_of(args: argparse.Namespace) -> list[str]:
    """Absolute names of the topics published with these options."""
    names = list(BLOCK_TOPICS if args.blocks else PER_SAMPLE_TOPICS)
    if args.scalars and not args.blocks:
        names += SCALAR_TOPICS
    if args.blocks:
        names.append("flow_progress")
    out = [resolve(args.namespace, n) for n in names]
    if args.clock or args.blocks:
        out.append("/clock")
    return out


def publish(args: argparse.Namespace) -> int:
    """Publish args.samples plant samples (per sample at args.rate Hz, or in blocks)."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    from lubrig_ros.nodes.graph import matched_every_subscription, takes_every_sample
    from lubrig_ros.nodes.interfaces import message_class, qos_profile

    rclpy.init(args=[])
    if args.blocks:
        node = rclpy.create_node("plant", namespace=args.namespace)
    else:
        node = rclpy.create_node("lubrig_synthetic_plant")
    docs = documented_topics(args.namespace)
    names = topics_of(args)
    pubs = {
        n: node.create_publisher(message_class(docs[n].msgtype), n, qos_profile(docs[n].qos)) for n in names
    }
    progress_name = resolve(args.namespace, "flow_progress")
    consumer: dict[str, int] = {}
    executor = None
    if args.blocks and args.consumer:

        def on_progress(msg: object) -> None:
            if msg.participant == args.consumer:  # type: ignore[attr-defined]
                consumer["samples"] = max(consumer.get("samples", 0), int(msg.samples))  # type: ignore[attr-defined]

        spec = docs[progress_name]
        node.create_subscription(
            message_class(spec.msgtype), progress_name, on_progress, qos_profile(spec.qos)
        )
        executor = SingleThreadedExecutor()
        executor.add_node(node)
    waited = [p for n, p in pubs.items() if n != progress_name or not args.consumer]
    deadline = time.monotonic() + args.wait_subscribers
    while time.monotonic() < deadline:
        if executor is not None:
            executor.spin_once(timeout_sec=0.05)
        # subscribers that take every sample (a use_sim_time node's best-effort /clock reader
        # does not), each one discovered matched (nodes/graph.py)
        subscribed = all(
            sum(takes_every_sample(i, p) for i in node.get_subscriptions_info_by_topic(p.topic_name))
            >= args.subscribers
            and matched_every_subscription(node, p)
            for p in waited
        )
        if subscribed and (executor is None or "samples" in consumer):
            break
        if executor is None:
            time.sleep(0.05)
    else:
        print(json.dumps({"error": "subscribers not matched", "consumer": consumer}), flush=True)
        return 3
    time.sleep(args.settle)
    skip = set(args.skip or ())
    t0 = time.perf_counter()
    if args.blocks:
        published = _publish_blocks(args, node, pubs, executor, consumer, skip)
    else:
        published = _publish_samples(args, pubs, skip)
    elapsed = time.perf_counter() - t0
    print(json.dumps({"published": published, "elapsed": elapsed, "skipped": sorted(skip)}), flush=True)
    time.sleep(args.linger)  # keep the writer alive while reliable delivery completes
    node.destroy_node()
    rclpy.shutdown()
    return 0


def _stamp(msg: object, ns: int) -> None:
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 1_000_000_000)  # type: ignore[attr-defined]


def _publish_samples(args: argparse.Namespace, pubs: dict, skip: set[int]) -> dict[str, int]:
    from rclpy.duration import Duration
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import Float64

    from lubrig_interfaces.msg import RigState

    ns = args.namespace
    names = ("band_velocity", *(SCALAR_TOPICS if args.scalars else ()))
    floats = [(pubs[resolve(ns, n)], Float64()) for n in names]
    state_pub = pubs[resolve(ns, "state")]
    clock_pub = pubs.get("/clock")
    state, clock = RigState(), Clock()
    period = 1.0 / args.rate
    t0 = time.perf_counter()
    counts = dict.fromkeys(pubs, 0)
    for k in range(args.samples):
        stamp = START_NS + round(k * 1e9 / args.rate)
        clock.clock.sec, clock.clock.nanosec = divmod(stamp, 1_000_000_000)
        if clock_pub is not None:
            clock_pub.publish(clock)
            counts["/clock"] += 1
        for pub, msg in floats:
            msg.data = float(k)
            pub.publish(msg)
            counts[pub.topic_name] += 1
        if k not in skip:
            state.header.stamp = clock.clock
            state.sample_index, state.segment = k, 0
            state.displacement, state.velocity, state.friction_force = float(k), 0.5 * k, -float(k)
            state.band_velocity, state.belt_travel = float(k), float(k)
            state_pub.publish(state)
            counts[state_pub.topic_name] += 1
        if args.flow_control:
            if (k + 1) % args.flow_control == 0 or k + 1 == args.samples:
                for pub in pubs.values():
                    while not pub.wait_for_all_acked(Duration(seconds=1)):
                        pass
            continue
        ahead = t0 + (k + 1) * period - time.perf_counter()
        if ahead > 0:
            time.sleep(ahead)
    return counts


def _publish_blocks(
    args: argparse.Namespace,
    node: object,
    pubs: dict,
    executor: object,
    consumer: dict[str, int],
    skip: set[int],
) -> dict[str, int]:
    from rclpy.duration import Duration
    from rosgraph_msgs.msg import Clock

    from lubrig_interfaces.msg import BandVelocityBlock, FlowProgress, RigStateBlock

    ns = args.namespace
    state_pub, band_pub = pubs[resolve(ns, "state_block")], pubs[resolve(ns, "band_velocity_block")]
    progress_pub, clock_pub = pubs[resolve(ns, "flow_progress")], pubs["/clock"]
    counts = dict.fromkeys(pubs, 0)
    n = args.blocks
    dt = 1.0 / args.rate
    participant = node.get_fully_qualified_name()  # type: ignore[attr-defined]
    for first in range(0, args.samples, n):
        size = min(n, args.samples - first)
        if executor is not None:  # paced on the consumer: at most flow_window samples ahead
            while first + size - consumer.get("samples", 0) > args.flow_window:
                executor.spin_once(timeout_sec=0.05)  # type: ignore[attr-defined]
        stamp = START_NS + round(first * 1e9 / args.rate)
        values = [float(k) for k in range(first, first + size)]
        clock = Clock()
        clock.clock.sec, clock.clock.nanosec = divmod(stamp, 1_000_000_000)
        clock_pub.publish(clock)
        counts["/clock"] += 1
        if not skip & set(range(first, first + size)):
            block = RigStateBlock(sample_period=dt, first_sample_index=first, segment=0)
            _stamp(block, stamp)
            for name in BLOCK_FIELDS:  # every sample field, then chosen values for some
                setattr(block, name, values)
            block.displacement = values
            block.velocity = [0.5 * v for v in values]
            block.friction_coefficient = [0.0] * size
            block.friction_force = [-v for v in values]
            block.band_velocity = values
            block.relative_velocity = values
            block.belt_travel = values
            state_pub.publish(block)
            counts[state_pub.topic_name] += size
        band = BandVelocityBlock(sample_period=dt, first_sample_index=first, segment=0, band_velocity=values)
        _stamp(band, stamp)
        band_pub.publish(band)
        counts[band_pub.topic_name] += size
        progress = FlowProgress(participant=participant, segment=0, samples=first + size)
        _stamp(progress, stamp)
        progress_pub.publish(progress)
        counts[progress_pub.topic_name] += 1
        if executor is not None:  # what was published, for a test that kills this paced plant
            print(f"published {first + size}", file=sys.stderr, flush=True)
        if args.flow_control:
            for pub in pubs.values():
                while not pub.wait_for_all_acked(Duration(seconds=1)):
                    pass
    if executor is not None:  # every sample taken by the consumer (or it stopped reporting)
        end = time.monotonic() + args.wait_subscribers
        while consumer.get("samples", 0) < args.samples and time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)  # type: ignore[attr-defined]
        counts["consumer_samples"] = consumer.get("samples", 0)
    return counts


def listen(args: argparse.Namespace) -> int:
    """Collect messages until args.count arrived or args.timeout elapsed; write JSON."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    from lubrig_ros.nodes.interfaces import message_class, qos_profile

    rclpy.init(args=[])
    node = rclpy.create_node("lubrig_synthetic_listener")
    docs = documented_topics(args.namespace)
    got: list[tuple[str, int, float]] = []

    def make_cb(topic: str):
        def cb(msg: object) -> None:
            if hasattr(msg, "clock"):
                value = msg.clock.sec + msg.clock.nanosec * 1e-9
            elif hasattr(msg, "sample_index"):
                value = float(msg.displacement)
            else:
                value = float(msg.data)
            got.append((topic, time.time_ns(), value))

        return cb

    subs = []
    for name in args.topics:
        spec = docs[resolve(args.namespace, name)]
        subs.append(
            node.create_subscription(
                message_class(spec.msgtype), spec.name, make_cb(spec.name), qos_profile(spec.qos)
            )
        )
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    print("listening", flush=True)
    end = time.monotonic() + args.timeout
    while len(got) < args.count and time.monotonic() < end:
        executor.spin_once(timeout_sec=0.1)
    with open(args.output, "w", encoding="utf-8") as f:
        json.dump(got, f)
    node.destroy_node()
    rclpy.shutdown()
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: publish | listen."""
    p = argparse.ArgumentParser(prog="python -m lubrig_testkit.synthetic")
    sub = p.add_subparsers(dest="mode", required=True)
    pp = sub.add_parser("publish")
    pp.add_argument("--namespace", default=DEFAULT_NAMESPACE)
    pp.add_argument("--rate", type=float, default=1000.0)
    pp.add_argument("--samples", type=int, default=3000)
    pp.add_argument(
        "--flow-control",
        type=int,
        default=0,
        metavar="N",
        help="unpaced; after every N samples wait until all subscribers acknowledged them",
    )
    pp.add_argument("--scalars", action="store_true", help="also the Float64 scalar topics")
    pp.add_argument("--clock", action="store_true", help="also /clock (always with --blocks)")
    pp.add_argument("--blocks", type=int, default=0, metavar="N", help="sim layout, blocks of N samples")
    pp.add_argument("--consumer", default="", help="with --blocks: pace on this FlowProgress participant")
    pp.add_argument("--flow-window", type=int, default=1000, help="with --consumer: samples ahead at most")
    pp.add_argument("--skip", type=int, nargs="+", metavar="K", help="sample indices not published")
    pp.add_argument("--subscribers", type=int, default=1)
    pp.add_argument("--wait-subscribers", type=float, default=20.0)
    pp.add_argument("--settle", type=float, default=0.5)
    pp.add_argument("--linger", type=float, default=1.0)
    pp.set_defaults(func=publish)
    pl = sub.add_parser("listen")
    pl.add_argument("--namespace", default=DEFAULT_NAMESPACE)
    pl.add_argument("--topics", nargs="+", required=True)
    pl.add_argument("--count", type=int, required=True)
    pl.add_argument("--timeout", type=float, default=20.0)
    pl.add_argument("--output", required=True)
    pl.set_defaults(func=listen)
    args = p.parse_args(argv)
    return int(args.func(args))


if __name__ == "__main__":
    sys.exit(main())
