"""The bag's layout shared by writer, reader and repair (keys, sidecar, type store, files).

custom_data keys, the run-config sidecar, the rosbags type store, metadata.yaml and the one
.mcap file of a bag directory.

Nothing here writes a bag; writer, reader and repair import this module and never each other.
"""

from __future__ import annotations

from pathlib import Path

import yaml
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from lubrig_ros.bag.errors import BagError

RUN_CONFIG_KEY = "lubrig_ros.run_config"
VERSION_KEY = "lubrig_ros.version"
CONFIG_SIDECAR = "run_config.yaml"  # copy of the run configuration, kept for repair after a crash

_TYPESTORE: Typestore | None = None


def typestore() -> Typestore:
    """The rosbags type store used for message definitions (ROS 2 Kilted)."""
    global _TYPESTORE
    if _TYPESTORE is None:
        _TYPESTORE = get_typestore(Stores.ROS2_KILTED)
    return _TYPESTORE


def bag_information(bag_dir: Path) -> dict[str, object]:
    """The rosbag2_bagfile_information mapping of bag_dir/metadata.yaml; BagError if unreadable."""
    try:
        return dict(yaml.safe_load((bag_dir / "metadata.yaml").read_text())["rosbag2_bagfile_information"])
    except (OSError, yaml.YAMLError, KeyError, TypeError, ValueError) as exc:
        raise BagError(f"bag {str(bag_dir)!r}: metadata.yaml is unreadable ({exc})") from exc


def find_mcap(bag: str | Path) -> Path:
    """The .mcap file of a bag directory (from metadata.yaml, else the only *.mcap), or a file."""
    bag = Path(bag)
    if bag.is_file():
        return bag
    if not bag.is_dir():
        raise BagError(f"bag {str(bag)!r} does not exist: give a bag directory or an .mcap file")
    if (bag / "metadata.yaml").is_file():
        files = bag_information(bag).get("relative_file_paths")
        if not isinstance(files, list):
            raise BagError(f"bag {str(bag)!r}: metadata.yaml lists no relative_file_paths")
        if len(files) != 1 or not str(files[0]).endswith(".mcap"):
            raise BagError(f"bag {str(bag)!r}: expected one .mcap file, metadata lists {files}")
        return bag / files[0]
    found = sorted(bag.glob("*.mcap"))
    if len(found) != 1:
        raise BagError(f"bag {str(bag)!r}: expected one .mcap file, found {len(found)}")
    return found[0]


def cdr_string(data: bytes) -> str | None:
    """Text of a serialized std_msgs/msg/String, or None if it does not decode."""
    try:
        msg = typestore().deserialize_cdr(data, "std_msgs/msg/String")
    except Exception:
        return None
    return str(msg.data)
