"""ROS 2 nodes: thin adapters around the core (one node per module)."""
