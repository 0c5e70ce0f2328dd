"""What docs/security.md says about DDS security holds for the pinned wheels.

The Fast DDS in ros-fastdds / ros-rmw-fastrtps-cpp is built without the security plugins: a node
asked to run with an enclave (ROS_SECURITY_ENABLE=true, Enforce) is refused by the rmw with
"This Fast DDS version doesn't have the security libraries". If a wheel update brings them, this
test fails: then SROS2-style security can be offered and docs/security.md must change.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

pytestmark = pytest.mark.ros

ENCLAVE_FILES = (
    "identity_ca.cert.pem",
    "cert.pem",
    "key.pem",
    "permissions_ca.cert.pem",
    "governance.p7s",
    "permissions.p7s",
)
NODE = textwrap.dedent(
    """
    import rclpy
    rclpy.init(args=["--ros-args", "--enclave", "/lubrig_check"])
    try:
        rclpy.create_node("security_check")
        print("NODE CREATED")
    except Exception as exc:
        print("REFUSED", exc)
    """
)


def test_pinned_fast_dds_has_no_security_plugins(tmp_path, ros_env):
    enclave = tmp_path / "keystore" / "enclaves" / "lubrig_check"
    enclave.mkdir(parents=True)
    for name in ENCLAVE_FILES:  # rcl only checks that they exist; the rmw decides what follows
        (enclave / name).write_text("placeholder\n")
    env = dict(
        ros_env,
        ROS_SECURITY_ENABLE="true",
        ROS_SECURITY_STRATEGY="Enforce",
        ROS_SECURITY_KEYSTORE=str(tmp_path / "keystore"),
    )
    out = subprocess.run(
        [sys.executable, "-c", NODE], env=env, capture_output=True, text=True, timeout=60
    ).stdout
    assert "REFUSED" in out, out
    assert "doesn't have the security libraries" in out, out
