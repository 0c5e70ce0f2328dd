"""Every service a running rig offers answers: `ros2 param list` and the like never wait forever.

A real `lubrig rig --mode realtime` on the test's domain; a separate participant (the probe) lists
every node of the rig's namespace and calls each node's list_parameters service, as `ros2 param
list` does once it has found it. A node that nothing spins must offer no service at all: it would
be found and never answer (the recorder's progress node once stalled `ros2 param list` this way).
The launcher's own node and the recorder's progress node are on the graph for the whole run.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from lubrig_testkit.harness import wait_until
from rcl_interfaces.srv import ListParameters

from lubrig_interfaces.msg import BandVelocityBlock
from lubrig_ros.app.interface import contract
from lubrig_ros.app.processes.rig_plan import LAUNCHER_NODE, NODES, RECORDER_NODE_PREFIX
from lubrig_ros.nodes.interfaces import qos_profile

pytestmark = pytest.mark.ros

NS = contract.DEFAULT_NAMESPACE
DURATION = 60.0  # wall s: the run outlasts the probe's calls; it is stopped when they are done


def _rig_nodes(probe) -> list[str]:
    return sorted(n for n, ns in probe.node.get_node_names_and_namespaces() if ns == NS)


def test_every_service_of_a_running_rig_answers(procs, probe, tmp_path: Path) -> None:
    run = tmp_path / "run"
    argv = ["rig", "--mode", "realtime", "--duration", str(DURATION), "--run-dir", str(run), "--no-report"]
    rig = procs.script("lubrig", *argv)
    # the run going: band blocks flow (a rig stopped before its first one is recorded ends with
    # an incomplete recording, exit 1, which is not what this test is about)
    spec = contract.topic("band_velocity_block")
    probe.subscribe(spec.resolved(NS).name, BandVelocityBlock, qos_profile(spec.qos))
    wait_until(lambda: probe.messages[spec.resolved(NS).name], 120, "band blocks flowing", alive=(rig,))
    expected = {*NODES, LAUNCHER_NODE, RECORDER_NODE_PREFIX}
    wait_until(lambda: expected <= set(_rig_nodes(probe)), 60, "the rig's nodes on the graph", alive=(rig,))
    answered, silent = [], []
    for name in _rig_nodes(probe):
        services = dict(probe.node.get_service_names_and_types_by_node(name, NS))
        if name in (LAUNCHER_NODE, RECORDER_NODE_PREFIX):  # nothing spins them: no service
            assert services == {}, (name, services)
            continue
        service = f"{NS}/{name}/list_parameters"
        assert service in services, (name, sorted(services))
        client = probe.node.create_client(ListParameters, service)
        assert client.wait_for_service(timeout_sec=30), service
        future = client.call_async(ListParameters.Request())
        (answered if probe.wait_for(future.done, 30) else silent).append(name)
        probe.node.destroy_client(client)
    assert not silent, f"no answer within 30 s from {silent}"
    assert set(NODES) <= set(answered), answered
    assert rig.running(), rig.log()  # the calls were made while it ran
    assert rig.stop(timeout=60) == 130, rig.log()  # a Ctrl-C: interrupted, what ran is recorded
    assert "error" not in rig.errors(), rig.errors()
