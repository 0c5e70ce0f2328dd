"""Test and benchmark helpers of lubrig_ros (installed by `make setup`, never shipped).

- ``harness``: isolated ROS domains, node processes, a probe node, waits on conditions.
- ``synthetic``: a synthetic plant publisher and a listener (``python -m lubrig_testkit.synthetic``).
- ``crosscheck``: a bag read back by two independent readers (rosbags; mcap + mcap_ros2).
- ``reference_rig``: the rig written independently from the model document, solved by scipy LSODA.
"""
