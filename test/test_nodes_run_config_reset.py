"""A parameter change and a reset republish the run configuration, and the bag keeps every version.

Issue 11: after `ros2 param set /lubrig/plant rig.damping_ratio 0.05` and a reset the plant
integrates 0.05; the latched <ns>/run_config must say so too, and the recorder must store both
versions with their times (the analysis node and a bag reader follow the newest).
"""

from __future__ import annotations

import yaml
from std_msgs.msg import String
from std_srvs.srv import Trigger

from lubrig_interfaces.msg import FlowProgress
from lubrig_ros.app.interface import contract
from lubrig_ros.bag.reader import read_messages
from lubrig_ros.bag.writer import typestore
from lubrig_ros.nodes import common
from lubrig_ros.nodes.interfaces import qos_profile

NS = "/lubrig"


def _damping(text: str) -> float:
    return float(yaml.safe_load(text)["rig"]["damping_ratio"])


def test_reset_with_new_parameters_republishes_run_config_and_the_bag_keeps_both(procs, probe, tmp_path):
    probe.subscribe(f"{NS}/run_config", String, common.LATCHED_QOS)
    probe.subscribe(f"{NS}/flow_progress", FlowProgress, qos_profile(contract.BLOCK_QOS))
    bag = tmp_path / "bag"
    rec = procs.module("lubrig_ros.nodes.recorder", "-o", str(bag), "--topics", "run_config", "state_block")
    rec.wait_for_output("recording", timeout=90)
    # the plant announces itself only once the recorder has subscribed, and the recorder reports
    # once it has matched the plant: after both, the recorder holds the first run_config (latched)
    procs.node("plant", case=1, duration=30.0, wait_for_subscriber="lubrig_recorder")
    participants = lambda: {m.participant for m in probe.messages[f"{NS}/flow_progress"]}  # noqa: E731
    assert probe.wait_for(lambda: {f"{NS}/plant", f"{NS}/lubrig_recorder"} <= participants(), 120), (
        participants(),
        procs.logs(),
    )
    assert probe.wait_for(lambda: probe.messages[f"{NS}/run_config"], 60), procs.logs()
    first = _damping(probe.messages[f"{NS}/run_config"][-1].data)
    assert first != 0.05
    assert probe.set_parameter("lubrig/plant", "rig.damping_ratio", 0.05).successful
    # accepted, applied at the next reset: the configuration on the topic is still the old one
    assert _damping(probe.messages[f"{NS}/run_config"][-1].data) == first
    assert probe.call(Trigger, f"{NS}/plant/reset", Trigger.Request()).success
    assert probe.wait_for(lambda: _damping(probe.messages[f"{NS}/run_config"][-1].data) == 0.05, 30)
    # the recorder has both versions (transient local: its subscription also got the first)
    store = typestore()

    def recorded() -> list[float]:
        return [
            _damping(store.deserialize_cdr(data, msgtype).data)
            for _topic, msgtype, _t, data in read_messages(bag, [f"{NS}/run_config"])
        ]

    assert rec.stop() == 0, rec.log()
    versions = recorded()
    assert versions[0] == first and versions[-1] == 0.05, versions
    codes = procs.stop_all()
    assert all(code == 0 for code in codes.values()), (codes, procs.logs())
