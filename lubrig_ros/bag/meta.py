"""rosbag2 metadata (metadata.yaml, the in-file "rosbag2" record), channel metadata, type hashes.

Shared by the writer and repair (which never import each other); the layout is what rosbag2
itself writes: the rosbags rosbag2 writer's layout plus every channel's ``topic_type_hash``
(rosbag2_storage_mcap's channel metadata, equal to the topic's ``type_description_hash`` in
metadata.yaml) and the real ``ros_distro``.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from io import StringIO
from typing import Any

import yaml
from rosbags.interfaces import Nodetype, Qos
from rosbags.rosbag2.metadata import dump_qos_v9
from rosbags.typesys.store import Typestore
from ruamel.yaml import YAML

from lubrig_ros.bag.layout import install_prefixes, ros_distro, typestore

MESSAGE_ENCODING = "cdr"
SCHEMA_ENCODING = "ros2msg"
PROFILE = "ros2"
#: Channel metadata keys rosbag2's MCAP storage plugin writes (rosbag2_storage_mcap create_topic).
QOS_KEY = "offered_qos_profiles"
TYPE_HASH_KEY = "topic_type_hash"


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


def channel_metadata(qos: str, rihs01: str) -> dict[str, str]:
    """An MCAP channel's metadata as rosbag2 writes it: offered QoS (YAML) and the RIHS01 type hash."""
    return {QOS_KEY: qos, TYPE_HASH_KEY: rihs01}


def type_hash(msgtype: str) -> str:
    """RIHS01 hash of msgtype as rosidl computes it ("" if it is not known).

    The installed type description first (installed_type_hash: the hash the rig's publishers
    advertise), else computed from the type store's definition (computed_type_hash).
    """
    return installed_type_hash(msgtype) or computed_type_hash(msgtype)


def installed_type_hash(msgtype: str) -> str:
    """The hash rosidl generated for msgtype ("pkg/msg/Name"), "" if no installed package has it.

    From ``share/<pkg>/msg/<Name>.json`` (rosidl_generator_type_description's output) of the
    install prefixes (this interpreter's, then AMENT_PREFIX_PATH's).
    """
    parts = msgtype.split("/")
    if len(parts) != 3 or not all(parts):
        return ""
    package, kind, name = parts
    for prefix in install_prefixes():
        path = prefix / "share" / package / kind / f"{name}.json"
        try:
            entries = json.loads(path.read_text(encoding="utf-8"))["type_hashes"]
            found = [str(e["hash_string"]) for e in entries if e["type_name"] == msgtype]
        except (OSError, ValueError, KeyError, TypeError):
            continue
        if found:
            return found[0]
    return ""


def _msg_char_as_uint8(desc: Any) -> Any:
    """A field description with .msg ``char`` as rosidl reads it: uint8 (rosidl_adapter's mapping)."""
    kind, rest = desc
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        return (kind, (_msg_char_as_uint8(rest[0]), rest[1]))
    if kind == Nodetype.BASE and rest[0] == "char":
        return (kind, ("uint8", rest[1]))
    return desc


def computed_type_hash(msgtype: str) -> str:
    """RIHS01 hash of msgtype computed from the type store's definition ("" if it cannot be).

    rosbags' ``hash_rihs01`` alone is wrong for every type holding a ``char`` (std_msgs/Char,
    rmw_dds_common/Gid, service_msgs/ServiceEventInfo, ...): it hashes it as a char (type id 13),
    but rosidl turns a .msg ``char`` into uint8 (type id 3) before hashing. The types are hashed
    with that mapping applied (every type of the store comes from a .msg file).
    """
    source = typestore()
    if msgtype not in source.fielddefs:
        return ""
    store = Typestore()
    store.fielddefs = {
        name: (consts, [(field, _msg_char_as_uint8(desc)) for field, desc in fields])
        for name, (consts, fields) in source.fielddefs.items()
    }
    try:
        return str(store.hash_rihs01(msgtype))
    except Exception:
        return ""


def metadata_dict(
    mcap_name: str,
    topics: list[tuple[str, str, str, int]],
    start: int,
    end: int,
    custom_data: dict[str, str],
    type_hashes: Mapping[str, str] | None = None,
    distro: str | None = None,
) -> dict[str, object]:
    """rosbag2 (version 9) metadata; topics are (name, type, offered_qos_yaml, count).

    type_hashes: topic -> the ``topic_type_hash`` its channel carries (type_hash(type) for a topic
    not in it); distro: ``ros_distro`` (None: this process's, layout.ros_distro).
    """
    hashes = type_hashes or {}
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
                    "type_description_hash": hashes[name] if name in hashes else type_hash(msgtype),
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
            "ros_distro": distro or ros_distro(),
        }
    }


def metadata_texts(meta: dict[str, object]) -> tuple[str, str]:
    """(metadata.yaml text, the in-file "rosbag2" serialized_metadata text) of a metadata_dict."""
    return _ruamel_dump(meta), _ruamel_dump(meta["rosbag2_bagfile_information"]).strip()
