"""Synthetic rig traffic for tests and benchmarks (real rclpy nodes, documented types).

``python -m lubrig_testkit.synthetic publish --rate 1000 --samples 3000`` publishes the plant's
topics (displacement, velocity, friction_coefficient, state, band_velocity, /clock): sample k
carries value k (Float64 data, JointState position, /clock = start + k/rate). It waits until
every topic has a subscriber, then prints one JSON line ``{"published": {topic: count}, ...}``.
Paced at --rate on the wall clock (a realtime source: a slow subscriber can lose samples), or,
with ``--flow-control N``, unpaced but waiting after every N samples until every subscriber has
acknowledged them (reliable delivery; the tests' way to need no assumption about speed).

``python -m lubrig_testkit.synthetic listen --topics T... --count N --output F.json`` records the
Float64/Clock/JointState values it receives with receive times and writes them as JSON.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence

from lubrig_ros.app.contract import DEFAULT_NAMESPACE, documented_topics, plant_topics, resolve

START_NS = 1_000_000_000  # rig time of sample 0


def publish(args: argparse.Namespace) -> int:
    """Publish args.samples plant samples at args.rate Hz."""
    import rclpy
    from rclpy.duration import Duration
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64

    from lubrig_ros.nodes.interfaces import qos_profile

    rclpy.init(args=[])
    node = rclpy.create_node("lubrig_synthetic_plant")
    specs = plant_topics(args.namespace)
    pubs = {}
    for name, spec in specs.items():
        cls = {"std_msgs/msg/Float64": Float64, "sensor_msgs/msg/JointState": JointState,
               "rosgraph_msgs/msg/Clock": Clock}[spec.msgtype]
        pubs[name] = node.create_publisher(cls, name, qos_profile(spec.qos))
    deadline = time.monotonic() + args.wait_subscribers
    while time.monotonic() < deadline:
        if all(p.get_subscription_count() >= args.subscribers for p in pubs.values()):
            break
        time.sleep(0.05)
    else:
        print(json.dumps({"error": "subscribers not matched"}), flush=True)
        return 3
    time.sleep(args.settle)
    ns = args.namespace
    floats = [(pubs[resolve(ns, n)], Float64()) for n in
              ("displacement", "velocity", "friction_coefficient", "band_velocity")]
    state_pub, clock_pub = pubs[resolve(ns, "state")], pubs["/clock"]
    state = JointState(name=["mass"])
    clock = Clock()
    period = 1.0 / args.rate
    t0 = time.perf_counter()
    for k in range(args.samples):
        stamp = START_NS + round(k * 1e9 / args.rate)
        clock.clock.sec, clock.clock.nanosec = divmod(stamp, 1_000_000_000)
        clock_pub.publish(clock)
        for pub, msg in floats:
            msg.data = float(k)
            pub.publish(msg)
        state.header.stamp = clock.clock
        state.position, state.velocity, state.effort = [float(k)], [0.5 * k], [-float(k)]
        state_pub.publish(state)
        if args.flow_control:
            if (k + 1) % args.flow_control == 0 or k + 1 == args.samples:
                for pub in pubs.values():
                    while not pub.wait_for_all_acked(Duration(seconds=1)):
                        pass
            continue
        ahead = t0 + (k + 1) * period - time.perf_counter()
        if ahead > 0:
            time.sleep(ahead)
    elapsed = time.perf_counter() - t0
    print(json.dumps({"published": {n: args.samples for n in pubs}, "elapsed": elapsed}), flush=True)
    time.sleep(args.linger)  # keep the writer alive while reliable delivery completes
    node.destroy_node()
    rclpy.shutdown()
    return 0


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
            elif hasattr(msg, "position"):
                value = float(msg.position[0])
            else:
                value = float(msg.data)
            got.append((topic, time.time_ns(), value))

        return cb

    subs = []
    for name in args.topics:
        spec = docs[resolve(args.namespace, name)]
        subs.append(node.create_subscription(
            message_class(spec.msgtype), spec.name, make_cb(spec.name), qos_profile(spec.qos)
        ))
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
    pp.add_argument("--flow-control", type=int, default=0, metavar="N",
                    help="unpaced; after every N samples wait until all subscribers acknowledged them")
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
