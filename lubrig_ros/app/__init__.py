"""ROS-free application layer: the facts (contract, run selection, run directory) and sessions."""
