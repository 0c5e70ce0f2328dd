"""What a sim plant waits for before it announces itself (and so before belt_drive starts).

A sim plant whose state_subscribers name a node (the launchers name the analysis) stays silent
(no flow_progress, so belt_drive would not start and no sample is published) past its own
start-up check until that node has subscribed to state_block; then it announces itself. One with
a declared band_source (the launchers declare belt_drive) stays silent, and a wall-clock one does
not start its loop, until a band reader has matched that source (a block sent before would be
dropped by the reader); another band publisher does not count. Real processes over DDS.
"""

from __future__ import annotations

import time

import pytest
from lubrig_testkit.harness import wait_until

from lubrig_interfaces.msg import BandVelocityBlock, FlowProgress, RigStateBlock
from lubrig_ros.app.interface import contract
from lubrig_ros.nodes.interfaces import qos_profile

pytestmark = pytest.mark.ros

NS = "/lubrig"


def test_a_sim_plant_announces_itself_only_once_its_state_subscribers_are_there(procs, probe):
    progress = f"{NS}/flow_progress"
    probe.subscribe(progress, FlowProgress, qos_profile(contract.topic("flow_progress").qos))
    plant = procs.node("plant", case=1, duration=1.0, state_subscribers="['probe']")
    wait_until(
        lambda: "plant: mode=sim" in plant.errors() + plant.output(), 120, "the plant built", alive=(plant,)
    )
    time.sleep(3.0)  # twice its namespace check (1.5 s): it would have announced itself by now
    assert not probe.messages[progress], plant.log()
    probe.subscribe(f"{NS}/state_block", RigStateBlock, qos_profile(contract.topic("state_block").qos))
    assert probe.wait_for(
        lambda: any(m.participant == f"{NS}/plant" for m in list(probe.messages[progress])), 60
    ), plant.log()
    assert plant.running(), plant.log()


def _announced(probe, progress: str) -> bool:
    return any(m.participant == f"{NS}/plant" for m in list(probe.messages[progress]))


@pytest.mark.parametrize("mode", ["sim", "realtime"])
def test_a_plant_starts_only_once_its_declared_band_source_reaches_its_band_reader(procs, probe, mode):
    """Sim: no announcement; realtime: no loop (no flow_progress) until the source's band reaches it."""
    progress = f"{NS}/flow_progress"
    probe.subscribe(progress, FlowProgress, qos_profile(contract.topic("flow_progress").qos))
    # no start-up check (as `lubrig rig` starts it): nothing else holds the plant back
    plant = procs.node(
        "plant", case=1, mode=mode, duration=1.0, band_source="belt_drive", namespace_settle=0.0
    )
    wait_until(
        lambda: f"plant: mode={mode}" in plant.errors() + plant.output(),
        120,
        "the plant built",
        alive=(plant,),
    )
    # another publisher of band input is not the declared source: it does not release the plant
    spec = contract.topic("band_velocity_block")
    probe.publisher(spec.resolved(NS).name, BandVelocityBlock, qos_profile(spec.qos))
    time.sleep(3.0)  # sixty of its announcement polls or loop-start checks (50 ms)
    assert not _announced(probe, progress), plant.log()
    belt = procs.node("belt_drive", case=1, mode=mode, duration=1.0)
    assert probe.wait_for(lambda: _announced(probe, progress), 60), plant.log() + belt.log()
    assert plant.running() or plant.wait(timeout=1) == 0, plant.log()
