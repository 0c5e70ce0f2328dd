"""A rig kept on this host cannot be reached from another network (app/processes/discovery.py).

An "other host" is a network namespace joined to this one by a veth pair: a participant there,
told this host's address (ROS_STATIC_PEERS), publishes band input. A subscriber with the rig's
default environment receives none of it; with the network environment (the control: proves the
setup could deliver) it receives the samples. Needs CAP_NET_ADMIN and `ip`; skipped otherwise.
"""

from __future__ import annotations

import os
import random
import shutil
import subprocess
import sys
import textwrap
import uuid
from collections.abc import Iterator

import pytest

from lubrig_ros.app.processes.discovery import discovery_environment

pytestmark = pytest.mark.ros

SECONDS = 10.0  # the subscriber's listening time; the intruder publishes from before until after it

ATTACKER = textwrap.dedent(
    """
    import sys, time, rclpy
    from std_msgs.msg import Float64
    rclpy.init()
    node = rclpy.create_node("intruder")
    pub = node.create_publisher(Float64, "/lubrig/band_velocity", 10)
    end = time.monotonic() + float(sys.argv[1])
    while time.monotonic() < end:
        pub.publish(Float64(data=1e-7))
        rclpy.spin_once(node, timeout_sec=0.02)
    """
)
VICTIM = textwrap.dedent(
    """
    import sys, time, rclpy
    from std_msgs.msg import Float64
    rclpy.init()
    node = rclpy.create_node("rig_side")
    got = []
    node.create_subscription(Float64, "/lubrig/band_velocity", lambda m: got.append(m.data), 10)
    end = time.monotonic() + float(sys.argv[1])
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    print(len(got), flush=True)
    """
)


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True, timeout=10)


def _free_subnet() -> int:
    """A 10.213.X.0/24 no interface of this host uses (a killed run may leave its veth behind)."""
    used = subprocess.run(["ip", "-o", "addr"], capture_output=True, text=True, check=False).stdout
    free = [x for x in range(1, 255) if f"10.213.{x}." not in used]
    return random.choice(free)


@pytest.fixture
def other_host() -> Iterator[tuple[str, str]]:
    """A network namespace on a veth link to this one; yields (its name, this host's address)."""
    if shutil.which("ip") is None:
        pytest.skip("no `ip` command: cannot build a second network")
    name = f"lubrig{uuid.uuid4().hex[:6]}"
    subnet = _free_subnet()
    host, peer = f"10.213.{subnet}.1", f"10.213.{subnet}.2"
    host_if, peer_if = f"{name}h", f"{name}p"
    try:
        _ip("netns", "add", name)
    except (subprocess.CalledProcessError, OSError) as exc:
        pytest.skip(f"cannot create a network namespace here (needs CAP_NET_ADMIN): {exc}")
    try:
        _ip("link", "add", host_if, "type", "veth", "peer", "name", peer_if)
        _ip("link", "set", peer_if, "netns", name)
        _ip("addr", "add", f"{host}/24", "dev", host_if)
        _ip("link", "set", host_if, "up")
        _ip("netns", "exec", name, "ip", "addr", "add", f"{peer}/24", "dev", peer_if)
        _ip("netns", "exec", name, "ip", "link", "set", peer_if, "up")
        _ip("netns", "exec", name, "ip", "link", "set", "lo", "up")
        yield name, host
    finally:
        subprocess.run(["ip", "link", "del", host_if], capture_output=True, timeout=10)
        subprocess.run(["ip", "netns", "del", name], capture_output=True, timeout=10)


def _received(other: tuple[str, str], domain: int, network: bool) -> int:
    netns, host = other
    rig_env = discovery_environment(os.environ, network=network).env
    rig_env["ROS_DOMAIN_ID"] = str(domain)
    intruder_env = {k: v for k, v in os.environ.items() if not k.startswith(("ROS_", "FASTDDS_"))}
    intruder_env.update(
        ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="SUBNET", ROS_STATIC_PEERS=host
    )
    victim = subprocess.Popen(
        [sys.executable, "-c", VICTIM, str(SECONDS)], env=rig_env, stdout=subprocess.PIPE, text=True
    )
    intruder = subprocess.Popen(  # outlives the subscriber: start-up under load costs seconds
        ["ip", "netns", "exec", netns, sys.executable, "-c", ATTACKER, str(SECONDS + 60)],
        env=intruder_env,
    )
    try:
        out, _ = victim.communicate(timeout=SECONDS + 90)
    finally:
        for p in (victim, intruder):
            if p.poll() is None:
                p.kill()
    return int(out.strip())


def test_a_peer_on_another_network_cannot_inject_band_input(other_host, ros_domain):
    assert _received(other_host, ros_domain, network=False) == 0
    # control: the same peer reaches a rig opened to the network
    assert _received(other_host, ros_domain, network=True) > 0
