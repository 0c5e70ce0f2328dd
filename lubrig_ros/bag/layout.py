"""The bag's layout shared by writer, reader and repair (keys, sidecar, type store, files).

custom_data keys, the run-config sidecar, the ROS 2 distribution (pinned and installed), the
rosbags type store, metadata.yaml and the one .mcap file of a bag directory.

Nothing here writes a bag; writer, reader and repair import this module and never each other.
"""

from __future__ import annotations

import os
import re
import sys
from functools import cache
from importlib import metadata
from pathlib import Path
from typing import Any

import yaml
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from lubrig_ros.bag.errors import BagError

RUN_CONFIG_KEY = "lubrig_ros.run_config"
VERSION_KEY = "lubrig_ros.version"
CONFIG_SIDECAR = "run_config.yaml"  # copy of the run configuration, kept for repair after a crash
ACCOUNTING_SIDECAR = (
    "accounting.json"  # the recorder's per-stream sample accounting (app/recording/accounting.py)
)

#: The rig's own interface package (lubrig_interfaces, ament_cmake + rosidl).
INTERFACE_PACKAGE = "lubrig_interfaces"

#: The ROS 2 distribution requirements.txt pins: its unprefixed ros-* wheels are the Kilted line
#: (rclpy 9.1). The one place the project names it: the type store below and the fallback of
#: ros_distro().
PINNED_ROS_DISTRO = "kilted"

#: rclpy's major version per ROS 2 distribution line (a release keeps its rclpy major).
RCLPY_MAJOR_DISTRO = {3: "humble", 4: "iron", 7: "jazzy", 9: "kilted"}

_PREFIXED_RCLPY = re.compile(r"ros-([a-z]+)-rclpy")

_TYPESTORE: Typestore | None = None


@cache
def installed_ros_distro() -> str | None:
    """The ROS 2 distribution of the installed rclpy, from its package metadata (None: unknown).

    A prefixed wheel set (``ros-jazzy-rclpy``, ``ros-kilted-rclpy``) names it; the unprefixed
    ``ros-rclpy`` wheel (and the ``rclpy`` of a ROS install or colcon build) by its version's
    major (RCLPY_MAJOR_DISTRO). Read once per process.
    """

    def line(dist: str) -> str | None:
        try:
            major = int(metadata.version(dist).split(".")[0])
        except (metadata.PackageNotFoundError, ValueError):
            return None
        return RCLPY_MAJOR_DISTRO.get(major)

    distro = line("ros-rclpy")
    if distro:
        return distro
    for dist in metadata.distributions():
        try:
            name = re.sub(r"[-_.]+", "-", str(dist.metadata["Name"] or "")).lower()
        except KeyError:  # no Name field
            continue
        match = _PREFIXED_RCLPY.fullmatch(name)
        if match:
            return match.group(1)
    return line("rclpy")


def ros_distro() -> str:
    """The ROS 2 distribution this process runs (metadata.yaml's ``ros_distro``).

    ``ROS_DISTRO`` if set (what rosbag2 records; a sourced ROS environment sets it), else the
    installed rclpy's distribution (installed_ros_distro), else the pinned one (PINNED_ROS_DISTRO).
    """
    return os.environ.get("ROS_DISTRO", "").strip() or installed_ros_distro() or PINNED_ROS_DISTRO


def install_prefixes() -> list[Path]:
    """Where installed ROS packages are: this interpreter's prefix, then every AMENT_PREFIX_PATH entry."""
    prefixes = [Path(sys.prefix)]
    prefixes += [Path(p) for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    return prefixes


def interface_msg_dirs() -> list[Path]:
    """Where lubrig_interfaces' .msg files may be, in the order they are looked for.

    The installed package first (what the nodes publish with: ``$PREFIX/share/lubrig_interfaces/msg``
    of this interpreter's prefix, then of every AMENT_PREFIX_PATH entry, as a colcon workspace
    sets it), then the repository's source directory next to the lubrig_ros package.
    """
    dirs = [prefix / "share" / INTERFACE_PACKAGE / "msg" for prefix in install_prefixes()]
    dirs.append(Path(__file__).resolve().parents[2] / INTERFACE_PACKAGE / "msg")
    return dirs


def interface_definitions() -> dict[str, str]:
    """``{"lubrig_interfaces/msg/Name": msg text}`` of the first directory holding .msg files.

    BagError naming the directories looked in when none has them (the recorder cannot write the
    rig's messages without their definitions).
    """
    dirs = interface_msg_dirs()
    for directory in dirs:
        files = sorted(directory.glob("*.msg")) if directory.is_dir() else []
        if files:
            return {f"{INTERFACE_PACKAGE}/msg/{f.stem}": f.read_text(encoding="utf-8") for f in files}
    raise BagError(
        f"no {INTERFACE_PACKAGE} message definitions (*.msg) found in "
        f"{', '.join(str(d) for d in dirs)}: build the interface package (`make setup`)"
    )


def typestore() -> Typestore:
    """The rosbags type store: the pinned distribution's types (Kilted) plus lubrig_interfaces'.

    lubrig_interfaces' .msg files are registered from their text (interface_definitions), so the
    writer stores their schemas (ros2msg) in the MCAP, meta.type_hash gives the RIHS01 hash rosidl
    computes for them and rosbags can (de)serialize them.
    """
    global _TYPESTORE
    if _TYPESTORE is None:
        store = get_typestore(Stores(f"ros2_{PINNED_ROS_DISTRO}"))
        types: dict[str, Any] = {}
        for name, text in interface_definitions().items():
            types.update(get_types_from_msg(text, name))
        store.register(types)
        _TYPESTORE = store
    return _TYPESTORE


class MetadataUnreadableError(BagError):
    """metadata.yaml cannot be read; ``what`` says so without naming the bag (one line)."""

    def __init__(self, bag_dir: Path, reason: str) -> None:
        self.what = f"metadata.yaml is unreadable ({reason})"
        super().__init__(f"bag {str(bag_dir)!r}: {self.what}")


def _reason(exc: Exception) -> str:
    """One line for why metadata.yaml did not load (a YAML error names its line and column)."""
    if isinstance(exc, yaml.MarkedYAMLError) and exc.problem_mark is not None:
        mark = exc.problem_mark
        return f"{exc.problem} at line {mark.line + 1}, column {mark.column + 1}"
    if isinstance(exc, KeyError):
        return f"no {exc} mapping"
    return " ".join(f"{type(exc).__name__}: {exc}".split())


def bag_information(bag_dir: Path) -> dict[str, object]:
    """The rosbag2_bagfile_information mapping of bag_dir/metadata.yaml; MetadataUnreadableError if not."""
    try:
        return dict(yaml.safe_load((bag_dir / "metadata.yaml").read_text())["rosbag2_bagfile_information"])
    except (OSError, yaml.YAMLError, KeyError, TypeError, ValueError) as exc:
        raise MetadataUnreadableError(bag_dir, _reason(exc)) from exc


def find_mcap(bag: str | Path) -> Path:
    """The .mcap file of a bag: the file itself, or the one *.mcap of a bag directory.

    metadata.yaml is not trusted for this (it may be wrong: that is what `lubrig bag check`
    names and repair rebuilds); it only chooses among several .mcap files, when it names one of
    them. BagError if there is none, or several and metadata.yaml names none of them.
    """
    bag = Path(bag)
    if bag.is_file():
        return bag
    if not bag.is_dir():
        raise BagError(f"bag {str(bag)!r} does not exist: give a bag directory or an .mcap file")
    found = sorted(bag.glob("*.mcap"))
    if len(found) == 1:
        return found[0]
    if found:
        try:
            named = bag_information(bag).get("relative_file_paths")
        except BagError:
            named = None
        if isinstance(named, list) and len(named) == 1 and bag / str(named[0]) in found:
            return bag / str(named[0])
    raise BagError(f"bag {str(bag)!r}: expected one .mcap file, found {len(found)}")


def cdr_string(data: bytes) -> str | None:
    """Text of a serialized std_msgs/msg/String, or None if it does not decode."""
    try:
        msg: Any = typestore().deserialize_cdr(data, "std_msgs/msg/String")
    except Exception:
        return None
    return str(msg.data)
