"""ros2 launch lubrig_ros rig.launch.py [case:=N | config_file:=FILE] [mode:=sim|realtime] [duration:=S].

For ROS 2 installations with launch_ros (not installable from pip here: `lubrig rig` is the
launcher that works everywhere). Starts belt_drive, plant and analysis with config/nodes.yaml.
"""

from __future__ import annotations

import os

try:
    from ament_index_python.packages import get_package_share_directory
    from launch.actions import DeclareLaunchArgument
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node

    from launch import LaunchDescription
except ImportError:  # pragma: no cover - launch is not available from pip
    LaunchDescription = None


def generate_launch_description():
    """Launch description of one rig run."""
    if LaunchDescription is None:
        raise RuntimeError("launch and launch_ros are not installed; use `lubrig rig` instead")
    params_file = os.path.join(get_package_share_directory("lubrig_ros"), "config", "nodes.yaml")
    arguments = {
        "case": "0",
        "config_file": "",
        "mode": "sim",
        "duration": "10.0",
        "convention": "",
    }
    declared = [DeclareLaunchArgument(name, default_value=value) for name, value in arguments.items()]
    selection = {
        "case": LaunchConfiguration("case"),
        "config_file": LaunchConfiguration("config_file"),
    }
    run = {"mode": LaunchConfiguration("mode"), "duration": LaunchConfiguration("duration")}
    nodes = [
        Node(
            package="lubrig_ros",
            executable="plant",
            name="plant",
            parameters=[params_file, selection, run, {"convention": LaunchConfiguration("convention")}],
            output="screen",
        ),
        Node(
            package="lubrig_ros",
            executable="belt_drive",
            name="belt_drive",
            parameters=[params_file, selection, run],
            output="screen",
        ),
        Node(
            package="lubrig_ros",
            executable="analysis",
            name="analysis",
            parameters=[params_file, selection, {"convention": LaunchConfiguration("convention")}],
            output="screen",
        ),
    ]
    return LaunchDescription([*declared, *nodes])
