"""lubrig_ros: a virtual lubricated test rig (numerics core, ROS 2 nodes, recording, analysis)."""

__version__ = "0.1.0"
