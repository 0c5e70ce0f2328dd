"""A bag in the legacy layout (before issue 12): JointState on <ns>/state, Float64 μ and band.

What `lubrig report` must still read; written from a core run with lubrig_ros's own BagWriter.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from lubrig_ros.bag.writer import BagWriter, serialize_string, typestore
from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import simulate


def write_legacy_bag(path: Path, duration: float = 3.0, namespace: str = "/lubrig") -> tuple[Any, Any]:
    """Write case 1 of `duration` s as a legacy-layout bag at `path`; returns (config, trajectory)."""
    config = load_case(1).with_overrides(duration=duration)
    traj = simulate(config)
    ts = typestore()
    js, hdr, stamp = (
        ts.types[n]
        for n in ("sensor_msgs/msg/JointState", "std_msgs/msg/Header", "builtin_interfaces/msg/Time")
    )
    f64 = ts.types["std_msgs/msg/Float64"]
    writer = BagWriter(path, run_config=config.to_yaml())
    writer.write(f"{namespace}/run_config", "std_msgs/msg/String", 0, serialize_string(config.to_yaml()))
    normal = config.rig.friction.normal_force
    for k, t in enumerate(traj.time):
        ns = round(float(t) * 1e9)
        sec, nsec = divmod(ns, 10**9)
        state = js(
            hdr(stamp(sec, nsec), ""),
            ["mass"],
            np.array([traj.displacement[k]]),
            np.array([traj.velocity[k]]),
            np.array([traj.friction_coefficient[k] * normal]),
        )
        writer.write(
            f"{namespace}/state",
            "sensor_msgs/msg/JointState",
            ns,
            ts.serialize_cdr(state, "sensor_msgs/msg/JointState"),
        )
        writer.write(
            f"{namespace}/friction_coefficient",
            "std_msgs/msg/Float64",
            ns,
            ts.serialize_cdr(f64(float(traj.friction_coefficient[k])), "std_msgs/msg/Float64"),
        )
        if k:
            writer.write(
                f"{namespace}/band_velocity",
                "std_msgs/msg/Float64",
                ns,
                ts.serialize_cdr(f64(float(traj.band_velocity[k])), "std_msgs/msg/Float64"),
            )
    writer.close()
    return config, traj
