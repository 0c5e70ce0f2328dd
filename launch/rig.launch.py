"""One rig run with launch_ros: belt_drive, plant and analysis in the rig's namespace.

ros2 launch lubrig_ros rig.launch.py [case:=N | config_file:=FILE] [mode:=sim|realtime] [duration:=S]
[namespace:=NS] [network:=false|true] [publish_clock:=true|false] [view:=false|true].

For ROS 2 installations with launch_ros (not installable from pip here: `lubrig rig` is the
launcher that works everywhere). Like `lubrig rig`, it resolves the run once (case | config file |
default, plus duration and convention), writes it to RUN_DIR/run_config.yaml (`run_dir:=DIR`,
default ~/.ros/lubrig/<time>) and hands that file to belt_drive, plant and analysis as their
`config_file` parameter, with config/nodes.yaml for the node settings. The nodes run in
`namespace` (default /lubrig, launch_ros's `namespace=`: the nodes' relative topic and service
names resolve under it; a relative value such as `rig2` goes under an enclosing
PushRosNamespace). Like `lubrig rig`, discovery and transports stay on this host unless
`network:=true` (docs/security.md). When any node exits, the whole rig is shut down.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

from lubrig_ros.app.contract import DEFAULT_NAMESPACE

try:
    from ament_index_python.packages import get_package_share_directory
    from launch.actions import DeclareLaunchArgument, EmitEvent, OpaqueFunction, RegisterEventHandler
    from launch.event_handlers import OnProcessExit
    from launch.events import Shutdown
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node

    from launch import LaunchDescription

    IMPORT_ERROR: ImportError | None = None
except ImportError as exc:  # pragma: no cover - launch is not available from pip
    LaunchDescription = None
    IMPORT_ERROR = exc

ARGUMENTS = {
    "case": "0",
    "config_file": "",
    "mode": "sim",
    "duration": "10.0",
    "convention": "",
    "run_dir": "",
    "namespace": DEFAULT_NAMESPACE,
    "network": "false",
    "publish_clock": "true",
    "view": "false",  # true: also the live view for Foxglove (lubrig view) on ws://127.0.0.1:8765
}
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


def _nodes(context, *_args, **_kwargs):
    """Resolve the run, write its YAML, and describe the three nodes that read it."""
    from lubrig_ros.app.discovery import discovery_environment
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
    run_config = str(write_run_config(config, run_dir))
    params_file = os.path.join(get_package_share_directory("lubrig_ros"), "config", "nodes.yaml")
    mode = value["mode"]
    per_node = {
        "plant": {
            "config_file": run_config,
            "mode": mode,
            # sim: /clock has one owner per domain; publish_clock:=false for a second rig
            "publish_clock": mode == "sim" and bool(value["publish_clock"]),
        },
        "belt_drive": {"config_file": run_config, "mode": mode},
        "analysis": {"config_file": run_config},
    }
    nodes = [
        Node(
            package="lubrig_ros",
            executable=name,
            name=name,
            namespace=value["namespace"],
            parameters=[params_file, params],
            output="screen",
            additional_env=changed,
        )
        for name, params in per_node.items()
    ]
    # one node gone (crash, bad parameter, end of run) ends the rig: no node runs on alone
    stop = [
        RegisterEventHandler(
            OnProcessExit(
                target_action=node,
                on_exit=[EmitEvent(event=Shutdown(reason=f"{node.node_executable} exited"))],
            )
        )
        for node in nodes
    ]
    if value["view"]:
        nodes.append(Node(package="lubrig_ros", executable="view", name="view", namespace=value["namespace"],
                          output="screen", additional_env=changed))  # namespace: launch's __ns
    return [*nodes, *stop]


def generate_launch_description():
    """Launch description of one rig run."""
    if LaunchDescription is None:
        raise RuntimeError(
            f"rig.launch.py needs launch and launch_ros: {IMPORT_ERROR} (without a ROS 2 "
            "installation, `lubrig rig` is the launcher)"
        )
    declared = [DeclareLaunchArgument(name, default_value=value) for name, value in ARGUMENTS.items()]
    return LaunchDescription([*declared, OpaqueFunction(function=_nodes)])
