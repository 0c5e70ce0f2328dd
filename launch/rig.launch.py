"""One rig run with launch_ros: belt_drive, plant and analysis in the rig's namespace.

ros2 launch lubrig_ros rig.launch.py [case:=N | config_file:=FILE] [mode:=sim|realtime] [duration:=S]
[namespace:=NS] [network:=false|true] [publish_clock:=true|false] [view:=false|true]
(`--show-args` describes each).

For ROS 2 installations with launch_ros (not installable from pip here: `lubrig rig` is the
launcher that works everywhere; `make setup` registers the package in the venv's ament index, so
AMENT_PREFIX_PATH=.venv finds it). Like `lubrig rig`, it resolves the run once (case | config file |
default, plus duration and convention), writes it to RUN_DIR/run_config.yaml (`run_dir:=DIR`,
default ~/.ros/lubrig/<time>) and hands that file to belt_drive, plant and analysis as their
`config_file` parameter, with config/nodes.yaml for the node settings. Which nodes run with which
parameters, remappings and start order is the launch plan (lubrig_ros/app/processes/rig_plan.py), the one
`lubrig rig` runs too; this file turns it into launch_ros actions (`node_actions`). The nodes run in
`namespace` (default /lubrig, launch_ros's `namespace=`: the nodes' relative topic and service
names resolve under it; a relative value such as `rig2` goes under an enclosing
PushRosNamespace). Like `lubrig rig`, discovery and transports stay on this host unless
`network:=true` (docs/security.md).

The launch ends by itself when the run is over: the plant runs with `exit_when_complete:=true`
and ends (exit status 0) once its sim run is complete or, in realtime, once the sample at
`duration` (counted from its first sample) is published; when any node exits, the whole rig is
shut down (OnProcessExit → Shutdown: the other nodes get SIGINT and end with status 0). A node
that ended otherwise than cleanly (the plant's 3: the rig did not hold real time; 2: a bad
parameter; a crash) makes the launch fail: ros2 launch exits 1 (LaunchService.run returns 0 or 1)
with an error naming the node and its status. The plant starts last, once belt_drive and the
analysis have printed their start lines (the plan's `after`: nothing records here, so nothing
else holds the run).
"""

from __future__ import annotations

import os
import time
from pathlib import Path

from lubrig_ros.app.interface.contract import DEFAULT_NAMESPACE

try:
    from ament_index_python.packages import get_package_share_directory
    from launch.actions import DeclareLaunchArgument, EmitEvent, OpaqueFunction, RegisterEventHandler
    from launch.event_handlers import OnProcessExit, OnProcessIO
    from launch.events import Shutdown
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node

    from launch import LaunchDescription

    IMPORT_ERROR: ImportError | None = None
except ImportError as exc:  # pragma: no cover - launch is not available from pip
    LaunchDescription = None
    IMPORT_ERROR = exc

#: Launch arguments: default and description (`ros2 launch lubrig_ros rig.launch.py --show-args`).
ARGUMENTS = {
    "case": ("0", "study case 1..10 (config/cases/caseNN.yaml); 0: config_file, else the default rig"),
    "config_file": ("", "run configuration YAML, used when case is 0; empty: config/rig.yaml"),
    "mode": (
        "sim",
        "sim: rig time, as fast as the nodes go, ends when the plant has integrated "
        "`duration`; realtime: 1 kHz on the wall clock, ends `duration` s after the plant's "
        "first sample",
    ),
    "duration": (
        "10.0",
        "run length in s (rig time in sim, wall time in realtime); empty: the run "
        "configuration's; the launch ends by itself when it is over",
    ),
    "convention": ("", "velocity coupling: physical | paper | hertz; empty: the run configuration's"),
    "run_dir": (
        "",
        "folder for run_config.yaml (the resolved run every node reads); empty: ~/.ros/lubrig/<time>",
    ),
    "namespace": (
        DEFAULT_NAMESPACE,
        "ROS namespace of the nodes, their topics and services "
        "(relative: under an enclosing PushRosNamespace)",
    ),
    "network": (
        "false",
        "true: hosts on the network may discover the rig (default: this host "
        "only; an unsecured domain lets them drive it, docs/security.md)",
    ),
    "publish_clock": (
        "true",
        "sim: the plant publishes rig time on /clock (one owner per ROS domain: false for a second rig)",
    ),
    "view": ("false", "true: also the live view for Foxglove (lubrig view) on ws://127.0.0.1:8765"),
}
CHOICES = {"mode": ["sim", "realtime"]}
TYPES = {"case": int, "duration": float}  # the others are strings, but for the booleans
BOOLEANS = ("network", "publish_clock", "view")


def _typed(name: str, text: str) -> object:
    """A launch argument's value as its type, or a ValueError naming the argument and the value."""
    if name in BOOLEANS:
        if text.lower() not in ("true", "false"):
            raise ValueError(f"{name}:={text!r} is not valid; expected true or false")
        return text.lower() == "true"
    kind = TYPES.get(name)
    if kind is None or text == "":
        return text
    try:
        number = float(text)
        if kind is int and not number.is_integer():
            raise ValueError(text)
        return int(number) if kind is int else number
    except ValueError:
        expected = "an integer" if kind is int else "a number"
        raise ValueError(f"{name}:={text!r} is not valid; expected {expected}") from None


def _on_exit(name: str, clean: tuple[int, ...]):
    """OnProcessExit action of node `name`: shut the rig down; a status not in `clean` fails the launch."""

    def ended(event, _context):
        if event.returncode in clean:
            return [EmitEvent(event=Shutdown(reason=f"{name} exited with status {event.returncode}"))]
        # an exception in a handler is how a launch file makes LaunchService.run return 1; launch
        # logs it and shuts every process down
        raise RuntimeError(f"the rig failed: {name} exited with status {event.returncode}")

    return ended


def _when_ready(names: dict[str, str], start: list):
    """OnProcessIO callback: `start` once every node of `names` (node → start line) has printed its line."""
    ready: set[str] = set()

    def seen(name: str):
        def on_output(event):
            if name in ready or names[name] not in event.text.decode(errors="replace"):
                return None
            ready.add(name)
            return start if ready == set(names) else None

        return on_output

    return seen


def node_actions(plan) -> dict[str, dict]:
    """The launch_ros `Node` arguments of every node of the plan (app/processes/rig_plan.py), by name.

    The same plan `lubrig rig` turns into command lines: parameters, remappings, namespace.
    """
    return {
        node.name: {
            "package": "lubrig_ros",
            "executable": node.name,
            "name": node.name,
            "namespace": plan.namespace,
            "parameters": [str(plan.params_file), dict(node.parameters)],
            "remappings": list(node.remappings),
        }
        for node in plan.nodes
    }


def _nodes(context, *_args, **_kwargs):
    """Resolve the run, write its YAML, and turn the launch plan of its nodes into actions."""
    from lubrig_ros.app.processes.discovery import discovery_environment
    from lubrig_ros.app.processes.rig_plan import CLEAN_EXITS, READY_LINES, rig_plan
    from lubrig_ros.cli.rig import resolve_run, write_run_config

    value = {name: _typed(name, LaunchConfiguration(name).perform(context)) for name in ARGUMENTS}
    config = resolve_run(
        int(value["case"] or 0),
        value["config_file"] or None,
        float(value["duration"]) if value["duration"] != "" else None,
        value["convention"] or None,
    )
    discovery = discovery_environment(os.environ, network=bool(value["network"])).env
    changed = {k: v for k, v in discovery.items() if os.environ.get(k) != v}
    run_dir = Path(value["run_dir"] or Path.home() / ".ros" / "lubrig" / time.strftime("%Y%m%d_%H%M%S"))
    run_dir.mkdir(parents=True, exist_ok=True)
    params_file = Path(get_package_share_directory("lubrig_ros")) / "config" / "nodes.yaml"
    plan = rig_plan(
        write_run_config(config, run_dir),
        params_file,
        value["mode"],
        value["namespace"],
        publish_clock=bool(value["publish_clock"]),  # sim: one /clock owner per domain
        plant_extra={"exit_when_complete": True},  # the plant ends at the end of its run, and so the launch
    )
    nodes = {
        name: Node(**kwargs, output="screen", additional_env=changed)
        for name, kwargs in node_actions(plan).items()
    }
    # one node gone (end of run, crash, bad parameter) ends the rig: no node runs on alone
    handlers = [
        RegisterEventHandler(OnProcessExit(target_action=node, on_exit=_on_exit(name, CLEAN_EXITS)))
        for name, node in nodes.items()
    ]
    # a node with `after` starts once those have printed their start lines (the plan says why)
    started: list = []
    for launch in plan.nodes:
        if not launch.after:
            started.append(nodes[launch.name])
            continue
        others = {name: READY_LINES[name] for name in launch.after}
        seen = _when_ready(others, [nodes[launch.name]])
        handlers += [
            RegisterEventHandler(OnProcessIO(target_action=nodes[n], on_stdout=seen(n), on_stderr=seen(n)))
            for n in others
        ]
    if value["view"]:
        started.append(
            Node(
                package="lubrig_ros",
                executable="view",
                name="view",
                namespace=value["namespace"],  # namespace: launch's __ns
                output="screen",
                additional_env=changed,
            )
        )
    return [*handlers, *started]


def generate_launch_description():
    """Launch description of one rig run."""
    if LaunchDescription is None:
        raise RuntimeError(
            f"rig.launch.py needs launch and launch_ros: {IMPORT_ERROR} (without a ROS 2 "
            "installation, `lubrig rig` is the launcher)"
        )
    declared = [
        DeclareLaunchArgument(name, default_value=default, description=text, **_choices(name))
        for name, (default, text) in ARGUMENTS.items()
    ]
    return LaunchDescription([*declared, OpaqueFunction(function=_nodes)])


def _choices(name: str) -> dict[str, list[str]]:
    return {"choices": CHOICES[name]} if name in CHOICES else {}
