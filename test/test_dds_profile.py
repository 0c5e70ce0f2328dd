"""Fast DDS reads the shipped profile (config/fastdds_localhost.xml) whole.

A profile Fast DDS cannot parse is dropped with an "XMLPARSER Error" on stderr and the node runs on
the built-in transports: the rig would be reachable from the network again, and its writers would
repair a lost sample only every 3 s, longer than the plant's stall limit. A node process on the
rig's environment (the test's domain, the profile set by discovery_environment) creates a
publisher and a subscription; Fast DDS must print no parser error, and the profile must carry the
values docs/security.md and docs/nodes.md describe.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
import xml.etree.ElementTree as ET

import pytest

from lubrig_ros.app.plant.diagnostics import STALL_S
from lubrig_ros.app.processes.discovery import PROFILE_VARIABLE, localhost_profile

pytestmark = pytest.mark.ros

NODE = textwrap.dedent(
    """
    import rclpy
    from std_msgs.msg import Float64
    rclpy.init()
    node = rclpy.create_node("profile_check")
    node.create_publisher(Float64, "profile_check", 10)
    node.create_subscription(Float64, "profile_check", lambda msg: None, 10)
    print("NODE CREATED")
    """
)


def test_fast_dds_parses_the_shipped_profile_without_an_error(ros_env):
    assert ros_env[PROFILE_VARIABLE] == str(localhost_profile())
    res = subprocess.run(
        [sys.executable, "-c", NODE], capture_output=True, text=True, timeout=60, env=ros_env
    )
    assert res.returncode == 0 and "NODE CREATED" in res.stdout, res.stderr
    assert "XMLPARSER" not in res.stderr, res.stderr


def test_every_writer_repairs_a_lost_sample_well_before_the_plant_reports_a_stall():
    ns = {"d": "http://www.eprosima.com"}
    writer = ET.parse(localhost_profile()).getroot().find(".//d:data_writer", ns)
    assert writer is not None and writer.get("is_default_profile") == "true"
    period = writer.find("d:times/d:heartbeat_period", ns)
    assert period is not None
    seconds = int(period.findtext("d:sec", "0", ns)) + int(period.findtext("d:nanosec", "0", ns)) * 1e-9
    # a lost band block comes again one heartbeat and a NACK later: well inside the plant's stall
    # limit (Fast DDS's default, 3 s, is longer than it)
    assert 0 < seconds <= STALL_S / 4
