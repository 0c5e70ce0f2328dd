"""A synthetic "real rig" for shadow mode: its band sent ahead in blocks, its measured displacement after.

``python -m lubrig_testkit.shadow_rig --config RUN.yaml --samples N --out record.npz
[--truth JSON] [--noise 0.01] [--seed 1] [--lead 500] [--namespace /lubrig]
[--wait-for-subscriber lubrig_recorder]``

Physics: the independent reference rig (reference_rig.py: scipy LSODA, nothing of lubrig_ros's
integrator) with the `--truth` parameters (ReferenceRig fields; the others the study's), at rest
at its own equilibrium for the first band value, driven by the run configuration's band at
1 kHz: band value k = config.band(k / 1000), k = 0 … N − 1, linear between samples; γ = 1 in the
physical convention, 1/ω0 of the true f0 otherwise. Its measured displacement of band value k is
x(k / 1000), plus Gaussian noise of `--noise` × the range of x (seeded).

Sending, by the numbers the plant pairs on (app/plant/session.py, "Shadow"): band value k is
value k of a BandVelocityBlock (first_sample_index = the number of its first value, segment 0),
sent ahead, never more than `--lead` values beyond what the plant has taken (its flow_progress,
counted from its progress when the first block went out: the rig_in_loop plant queues at most
one second of values, which it takes one per tick, in order, and drops what overflows). The
plant takes the first value when the first block arrives, some time after that progress (under
load, over 0.1 s was seen), so the queue holds `--lead` values plus that delay: the default
lead, half the queue, leaves half a second for it. Measured value k is one
std_msgs/Float64 on measured_displacement, sent once the plant's progress says it has taken band
value k (after its sample, as a real rig's would come). The numbers, not the timing, decide the
pairs: however late a message is, value k pairs with the sample integrated with band value k.
At the end every measured value has been sent; the record (time, band, x, measured) goes to
--out (npz) and one JSON line is printed: {"band": N, "measured": N, "plant_start": progress}.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .reference_rig import ReferenceRig, reference_state

BLOCK = 50  # band values per BandVelocityBlock
RATE = 1000.0  # Hz


def rig_record(
    config: Any, truth: dict[str, float], samples: int, noise: float, seed: int
) -> dict[str, np.ndarray]:
    """(time, band, x, measured) of the reference rig with `truth` over the first `samples` band values."""
    rig = ReferenceRig(**truth)
    time_s = np.arange(samples) / RATE
    band = np.asarray(config.band(time_s), float)
    gamma = 1.0 if config.rig.convention == "physical" else 1.0 / rig.omega0
    x0 = rig.mu(float(band[0])) * rig.normal_force / rig.stiffness
    x, _ = reference_state(time_s, band, x0, gamma, rig)
    rng = np.random.default_rng(seed)
    measured = x + rng.normal(0.0, noise * float(np.ptp(x)), x.size) if noise > 0 else x.copy()
    return {"time": time_s, "band": band, "x": x, "measured": measured}


def run(args: argparse.Namespace) -> int:
    import rclpy
    from std_msgs.msg import Float64

    from lubrig_interfaces.msg import BandVelocityBlock, FlowProgress
    from lubrig_ros.app.interface.contract import topic
    from lubrig_ros.core.presets import load_config
    from lubrig_ros.nodes.graph import delivers_to
    from lubrig_ros.nodes.interfaces import qos_profile

    config = load_config(Path(args.config))
    record = rig_record(config, json.loads(args.truth), args.samples, args.noise, args.seed)
    np.savez(args.out, **record)
    band, measured = record["band"], record["measured"]
    n = band.size

    rclpy.init(args=[])
    node = rclpy.create_node("real_rig", namespace=args.namespace)
    band_pub = node.create_publisher(
        BandVelocityBlock, "band_velocity_block", qos_profile(topic("band_velocity_block").qos)
    )
    measured_pub = node.create_publisher(
        Float64, "measured_displacement", qos_profile(topic("measured_displacement").qos)
    )
    plant = f"{args.namespace.rstrip('/')}/plant"
    progress: list[int] = []

    def on_progress(msg: FlowProgress) -> None:
        if msg.participant == plant:
            progress.append(int(msg.samples))

    node.create_subscription(
        FlowProgress, "flow_progress", on_progress, qos_profile(topic("flow_progress").qos)
    )
    deadline = time.monotonic() + args.timeout
    try:
        # the plant subscribed to both, and every discovered subscription matched (a value sent
        # before a match never reaches that subscriber): nodes/graph.py
        subscribed = (band_pub, measured_pub)

        def ready() -> bool:
            plant = delivers_to(node, list(subscribed), "plant")  # its subscriptions, matched
            return plant and delivers_to(node, [band_pub], args.wait_for_subscriber)

        while not progress or not ready():
            rclpy.spin_once(node, timeout_sec=0.05)
            if time.monotonic() > deadline:
                print("shadow_rig: no plant (flow_progress and subscriptions) in time", file=sys.stderr)
                return 1
        start = progress[-1]
        sent = answered = 0
        block = BandVelocityBlock()
        block.sample_period = 1.0 / RATE
        value = Float64()
        while answered < n:
            taken = max(0, progress[-1] - start)
            while sent < min(n, taken + args.lead):
                count = min(BLOCK, n - sent, taken + args.lead - sent)
                block.header.stamp = node.get_clock().now().to_msg()
                block.first_sample_index = sent
                block.band_velocity = band[sent : sent + count].tolist()
                band_pub.publish(block)
                sent += count
            # after its sample; all of them once every band value was sent and taken (or at the end)
            due = n if sent == n and taken >= n else min(taken, sent)
            while answered < due:
                value.data = float(measured[answered])
                measured_pub.publish(value)
                answered += 1
            if time.monotonic() > deadline:
                due = n  # out of time: send the rest anyway, the pairing does not need the order
                while answered < due:
                    value.data = float(measured[answered])
                    measured_pub.publish(value)
                    answered += 1
                break
            rclpy.spin_once(node, timeout_sec=0.01)
        end = time.monotonic() + 1.0
        while time.monotonic() < end:  # let the reliable writers deliver
            rclpy.spin_once(node, timeout_sec=0.05)
        print(json.dumps({"band": sent, "measured": answered, "plant_start": start}), flush=True)
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="lubrig_testkit.shadow_rig", description=__doc__.splitlines()[0])
    parser.add_argument("--config", required=True, help="run configuration YAML (band, convention)")
    parser.add_argument("--samples", type=int, required=True, help="band values to send (1 kHz)")
    parser.add_argument("--out", required=True, help="npz of time, band, x, measured")
    parser.add_argument("--truth", default="{}", help="JSON of ReferenceRig fields (the rig's parameters)")
    parser.add_argument("--noise", type=float, default=0.0, help="measurement noise, share of the range of x")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--lead", type=int, default=500, help="band values sent beyond the plant's progress")
    parser.add_argument("--namespace", default="/lubrig")
    parser.add_argument(
        "--wait-for-subscriber",
        default="",
        metavar="PREFIX",
        help="also wait until a node named PREFIX* (the recorder) has subscribed to the band blocks, matched",
    )
    parser.add_argument("--timeout", type=float, default=120.0, help="s, the whole exchange at most")
    return run(parser.parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
