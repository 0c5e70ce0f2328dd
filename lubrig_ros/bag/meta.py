"""rosbag2 metadata (metadata.yaml, the in-file "rosbag2" record) and channel QoS text.

Shared by the writer and repair (which never import each other); the layout follows what the
rosbags rosbag2 writer produced before issue 15, so existing bags and new ones look alike.
"""

from __future__ import annotations

from io import StringIO

import yaml
from rosbags.interfaces import Qos
from rosbags.rosbag2.metadata import dump_qos_v9
from ruamel.yaml import YAML

from lubrig_ros.bag.layout import typestore

MESSAGE_ENCODING = "cdr"
SCHEMA_ENCODING = "ros2msg"
PROFILE = "ros2"


def _ruamel_dump(data: object) -> str:
    out = StringIO()
    dumper = YAML(typ="safe")
    dumper.default_flow_style = False
    dumper.dump(data, out)
    return out.getvalue()


def qos_text(qos: list[Qos]) -> str:
    """The channel metadata value `offered_qos_profiles` (rosbag2 version 9 YAML)."""
    return _ruamel_dump(dump_qos_v9(qos)).strip()


def message_definition(msgtype: str) -> tuple[str, str]:
    """(schema encoding, schema text) of msgtype from the type store (ros2msg or ros2idl)."""
    text, _ = typestore().generate_msgdef(msgtype, ros_version=2)
    encoding = "ros2idl" if text.startswith("=" * 80 + "\nIDL: ") else SCHEMA_ENCODING
    return encoding, text


def type_hash(msgtype: str) -> str:
    """RIHS01 hash of msgtype ("" if the type store cannot compute it)."""
    try:
        return str(typestore().hash_rihs01(msgtype))
    except Exception:
        return ""


def metadata_dict(
    mcap_name: str,
    topics: list[tuple[str, str, str, int]],
    start: int,
    end: int,
    custom_data: dict[str, str],
) -> dict[str, object]:
    """rosbag2 (version 9) metadata; topics are (name, type, offered_qos_yaml, count)."""
    count = sum(t[3] for t in topics)
    duration = max(0, end - start) if count else 0
    start = start if count else 0
    entries = []
    for name, msgtype, qos_yaml, n in topics:
        try:
            qos = yaml.safe_load(qos_yaml) if qos_yaml else []
        except yaml.YAMLError:
            qos = []
        entries.append(
            {
                "topic_metadata": {
                    "name": name,
                    "type": msgtype,
                    "serialization_format": MESSAGE_ENCODING,
                    "offered_qos_profiles": qos or [],
                    "type_description_hash": type_hash(msgtype),
                },
                "message_count": n,
            }
        )
    return {
        "rosbag2_bagfile_information": {
            "version": 9,
            "storage_identifier": "mcap",
            "relative_file_paths": [mcap_name],
            "duration": {"nanoseconds": duration},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": count,
            "topics_with_message_count": entries,
            "compression_format": "",
            "compression_mode": "",
            "files": [
                {
                    "path": mcap_name,
                    "starting_time": {"nanoseconds_since_epoch": start},
                    "duration": {"nanoseconds": duration},
                    "message_count": count,
                }
            ],
            "custom_data": custom_data or None,
            "ros_distro": "rosbags",
        }
    }


def metadata_texts(meta: dict[str, object]) -> tuple[str, str]:
    """(metadata.yaml text, the in-file "rosbag2" serialized_metadata text) of a metadata_dict."""
    return _ruamel_dump(meta), _ruamel_dump(meta["rosbag2_bagfile_information"]).strip()
