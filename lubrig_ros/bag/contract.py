"""The documented topic contract (docs/topics.md) as data: names, types and QoS."""

from __future__ import annotations

from dataclasses import dataclass

DEFAULT_NAMESPACE = "/lubrig"


@dataclass(frozen=True)
class TopicSpec:
    """One topic: absolute name, ROS type ("pkg/msg/Name"), QoS depth and latching."""

    name: str
    msgtype: str
    depth: int = 1000
    latched: bool = False


# (relative name or absolute name, type, depth, latched); relative names live under the namespace.
_CONTRACT: tuple[tuple[str, str, int, bool], ...] = (
    ("band_velocity", "std_msgs/msg/Float64", 1000, False),
    ("displacement", "std_msgs/msg/Float64", 1000, False),
    ("velocity", "std_msgs/msg/Float64", 1000, False),
    ("friction_coefficient", "std_msgs/msg/Float64", 1000, False),
    ("state", "sensor_msgs/msg/JointState", 1000, False),
    ("/clock", "rosgraph_msgs/msg/Clock", 1000, False),
    ("run_config", "std_msgs/msg/String", 1, True),
    ("run_complete", "std_msgs/msg/Bool", 1, True),
    ("dominant_frequency", "std_msgs/msg/Float64", 10, False),
    ("wavelet_power", "std_msgs/msg/Float64MultiArray", 10, False),
    ("wavelet_image", "sensor_msgs/msg/Image", 10, False),
    ("linear_zone", "std_msgs/msg/UInt8", 10, False),
    ("critical_damping_ratio", "std_msgs/msg/Float64", 10, False),
    ("oscillation_growing", "std_msgs/msg/Bool", 10, False),
    ("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray", 10, False),
)

#: The plant's high-rate outputs (one message each per sample), used by tests and the benchmark.
PLANT_TOPICS: tuple[str, ...] = (
    "displacement",
    "velocity",
    "friction_coefficient",
    "state",
    "band_velocity",
    "/clock",
)


def validate_namespace(namespace: str) -> str:
    """Return the namespace without a trailing slash; ValueError if it is not absolute."""
    if not namespace.startswith("/") or "//" in namespace or " " in namespace:
        raise ValueError(f"namespace {namespace!r} is invalid: expected an absolute name like /lubrig")
    return namespace.rstrip("/") or ""


def resolve(name: str, namespace: str = DEFAULT_NAMESPACE) -> str:
    """Absolute topic name of a contract name (relative names go under the namespace)."""
    if name.startswith("/"):
        return name
    return f"{validate_namespace(namespace)}/{name}"


def documented_topics(namespace: str = DEFAULT_NAMESPACE) -> dict[str, TopicSpec]:
    """All documented topics, keyed by absolute name."""
    specs = [TopicSpec(resolve(n, namespace), t, d, latched) for n, t, d, latched in _CONTRACT]
    return {s.name: s for s in specs}


def plant_topics(namespace: str = DEFAULT_NAMESPACE) -> dict[str, TopicSpec]:
    """The high-rate plant topics (see PLANT_TOPICS), keyed by absolute name."""
    docs = documented_topics(namespace)
    return {resolve(n, namespace): docs[resolve(n, namespace)] for n in PLANT_TOPICS}
