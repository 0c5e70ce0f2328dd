"""ros2 launch lubrig_ros rig.launch.py [case:=N | config_file:=FILE] [mode:=sim|realtime] [duration:=S]
[namespace:=NS].

For ROS 2 installations with launch_ros (not installable from pip here: `lubrig rig` is the
launcher that works everywhere). Like `lubrig rig`, it resolves the run once (case | config file |
default, plus duration and convention), writes it to RUN_DIR/run_config.yaml (`run_dir:=DIR`,
default ~/.ros/lubrig/<time>) and hands that file to belt_drive, plant and analysis as their
`config_file` parameter, with config/nodes.yaml for the node settings. The nodes run in
`namespace` (default /lubrig, launch_ros's `namespace=`: the nodes' relative topic and service
names resolve under it; a relative value such as `rig2` goes under an enclosing
PushRosNamespace).
"""

from __future__ import annotations

import os
import time
from pathlib import Path

from lubrig_ros.app.contract import DEFAULT_NAMESPACE

try:
    from ament_index_python.packages import get_package_share_directory
    from launch.actions import DeclareLaunchArgument, OpaqueFunction
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node

    from launch import LaunchDescription
except ImportError:  # pragma: no cover - launch is not available from pip
    LaunchDescription = None

ARGUMENTS = {
    "case": "0",
    "config_file": "",
    "mode": "sim",
    "duration": "10.0",
    "convention": "",
    "run_dir": "",
    "namespace": DEFAULT_NAMESPACE,
}


def _nodes(context, *_args, **_kwargs):
    """Resolve the run, write its YAML, and describe the three nodes that read it."""
    from lubrig_ros.cli.rig import resolve_run, write_run_config

    value = {name: LaunchConfiguration(name).perform(context) for name in ARGUMENTS}
    config = resolve_run(
        int(value["case"] or 0),
        value["config_file"] or None,
        float(value["duration"]) if value["duration"] else None,
        value["convention"] or None,
    )
    run_dir = Path(value["run_dir"] or Path.home() / ".ros" / "lubrig" / time.strftime("%Y%m%d_%H%M%S"))
    run_dir.mkdir(parents=True, exist_ok=True)
    run_config = str(write_run_config(config, run_dir))
    params_file = os.path.join(get_package_share_directory("lubrig_ros"), "config", "nodes.yaml")
    mode = value["mode"]
    per_node = {
        "plant": {"config_file": run_config, "mode": mode},
        "belt_drive": {"config_file": run_config, "mode": mode},
        "analysis": {"config_file": run_config},
    }
    return [
        Node(
            package="lubrig_ros",
            executable=name,
            name=name,
            namespace=value["namespace"],
            parameters=[params_file, params],
            output="screen",
        )
        for name, params in per_node.items()
    ]


def generate_launch_description():
    """Launch description of one rig run."""
    if LaunchDescription is None:
        raise RuntimeError("launch and launch_ros are not installed; use `lubrig rig` instead")
    declared = [DeclareLaunchArgument(name, default_value=value) for name, value in ARGUMENTS.items()]
    return LaunchDescription([*declared, OpaqueFunction(function=_nodes)])
