"""ROS-free numerics core: friction law, band profiles, integrator, stability, wavelets."""
