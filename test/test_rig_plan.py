"""The launch plan (app/processes/rig_plan.py): one wiring for `lubrig rig` and launch/rig.launch.py."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import yaml

from lubrig_ros.app.interface.contract import NODE_PARAMETERS, RECORDER_PARTICIPANT
from lubrig_ros.app.processes.rig_plan import NODES, rig_plan, ros_value
from lubrig_ros.core.presets import config_dir

ROOT = Path(__file__).resolve().parents[1]


def _launch_file():
    spec = importlib.util.spec_from_file_location("rig_launch", ROOT / "launch" / "rig.launch.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # launch / launch_ros absent here: the module still loads
    return module


def test_recorded_sim_plan_holds_the_run_for_the_recorder():
    plan = rig_plan(Path("/r/run_config.yaml"), Path("/p/nodes.yaml"), "sim", "/rig2", recorded=True)
    assert [n.name for n in plan.nodes] and {n.name for n in plan.nodes} == set(NODES)
    plant, belt = plan.node("plant").parameters, plan.node("belt_drive").parameters
    assert plant["wait_for_subscriber"] == belt["wait_for_subscriber"] == RECORDER_PARTICIPANT
    assert belt["required_consumers"] == [RECORDER_PARTICIPANT]
    assert plant["publish_clock"] is True and plant["band_source"] == "belt_drive"
    assert all(n.parameters["use_sim_time"] is True for n in plan.nodes)
    assert plan.node("plant").after == ()  # the recorder holds the run: all start at once
    for node in plan.nodes:  # every parameter is one the node declares (app/interface/contract.py)
        declared = {p.name for p in NODE_PARAMETERS[node.name]} | {"use_sim_time"}
        assert set(node.parameters) <= declared, node.name


def test_unrecorded_and_wall_clock_plans_start_the_plant_last_without_clock():
    for mode, recorded in (("sim", False), ("realtime", True), ("realtime", False)):
        plan = rig_plan(Path("/r/c.yaml"), Path("/p/n.yaml"), mode, recorded=recorded)
        assert plan.node("plant").after == ("belt_drive", "analysis"), (mode, recorded)
        # recorded: plant and belt_drive hold their first samples for the recorder in every mode
        awaited = {plan.node(n).parameters.get("wait_for_subscriber") for n in ("plant", "belt_drive")}
        assert awaited == ({RECORDER_PARTICIPANT} if recorded else {None}), (mode, recorded)
        assert "required_consumers" not in plan.node("belt_drive").parameters  # sim flow control only
    plan = rig_plan(Path("/r/c.yaml"), Path("/p/n.yaml"), "realtime", publish_clock=True)
    assert "publish_clock" not in plan.node("plant").parameters and not plan.publish_clock
    assert all(n.parameters["use_sim_time"] is False for n in plan.nodes)


def test_ros_args_are_what_rcl_parses_back():
    plan = rig_plan(Path("/r/c.yaml"), Path("/p/n.yaml"), "sim", "/rig2", recorded=True)
    args = plan.ros_args("belt_drive")
    assert args[:6] == ["--ros-args", "-r", "__ns:=/rig2", "--params-file", "/p/n.yaml", "-p"]
    given = dict(a.split(":=", 1) for a in args[6::2])
    assert {k: yaml.safe_load(v) for k, v in given.items()} == plan.node("belt_drive").parameters
    assert ros_value(True) == "true" and ros_value(["a", "b"]) == "['a', 'b']"


def test_the_launch_file_runs_the_same_plan():
    launch = _launch_file()
    plan = rig_plan(Path("/r/c.yaml"), config_dir() / "nodes.yaml", "realtime", "/rig3")
    actions = launch.node_actions(plan)
    assert list(actions) == [n.name for n in plan.nodes]
    for node in plan.nodes:
        kwargs = actions[node.name]
        assert kwargs["executable"] == kwargs["name"] == node.name and kwargs["namespace"] == "/rig3"
        assert kwargs["parameters"] == [str(plan.params_file), node.parameters]
        assert kwargs["remappings"] == list(node.remappings)
