"""The plant's state_subscribers (the launchers name the analysis): a sim run waits for them.

A sim plant whose state_subscribers name a node stays silent (no flow_progress, so belt_drive
would not start and no sample is published) past its own start-up check until that node has
subscribed to state_block; then it announces itself. Real processes over DDS.
"""

from __future__ import annotations

import time

import pytest
from lubrig_testkit.harness import wait_until

from lubrig_interfaces.msg import FlowProgress, RigStateBlock
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
