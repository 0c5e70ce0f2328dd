"""The contract's plain data (app/interface/contract.py) as rclpy objects.

QoS profiles, message classes, and publishers, subscriptions and services made by contract name.
Names are handed to rclpy as the contract holds them, RELATIVE (``band_velocity``,
``plant/reset``; only ``/clock`` and ``/diagnostics`` are absolute): rcl resolves them against
the node's namespace and applies remap rules, so ``--ros-args -r __ns:=/rig2``, relative remaps
(``-r band_velocity:=/my/band``) and launch namespaces/remappings work as in every ROS 2 package.
The resolved name is the entity's ``topic_name`` / ``srv_name``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from lubrig_ros.core.errors import InputError

from ..app.interface import contract
from ..app.interface.contract import QoS


def qos_profile(qos: QoS) -> QoSProfile:
    """The rclpy QoSProfile of a contract QoS."""
    return QoSProfile(
        history=HistoryPolicy[qos.history.upper()],
        depth=qos.depth,
        reliability=ReliabilityPolicy[qos.reliability.upper()],
        durability=DurabilityPolicy[qos.durability.upper()],
    )


def message_class(msgtype: str) -> type:
    """The rclpy message (or service) class of "pkg/msg/Name" ("pkg/srv/Name")."""
    parts = msgtype.split("/")
    if len(parts) != 3:
        raise InputError(f"message type {msgtype!r} is invalid: expected pkg/msg/Name")
    try:
        return getattr(importlib.import_module(f"{parts[0]}.{parts[1]}"), parts[2])
    except (ImportError, AttributeError) as exc:
        raise InputError(f"message type {msgtype!r} is not installed") from exc


def message_type(cls: type) -> str:
    """The "pkg/msg/Name" of an rclpy message class (message_class's inverse)."""
    return f"{cls.__module__.split('.')[0]}/msg/{cls.__name__}"


def create_publisher(node: Any, name: str) -> Any:
    """A publisher of the contract topic `name` (type and QoS from the contract), name resolved by rcl."""
    spec = contract.topic(name)
    return node.create_publisher(message_class(spec.msgtype), spec.name, qos_profile(spec.qos))


def create_subscription(node: Any, name: str, callback: Callable[[Any], None], raw: bool = False) -> Any:
    """A subscription to the contract topic `name`, name resolved by rcl (namespace, remaps)."""
    spec = contract.topic(name)
    return node.create_subscription(
        message_class(spec.msgtype), spec.name, callback, qos_profile(spec.qos), raw=raw
    )


def create_service(node: Any, name: str, callback: Callable[[Any, Any], Any]) -> Any:
    """A service server of the contract service `name`, name resolved by rcl (namespace, remaps)."""
    spec = contract.service(name)
    return node.create_service(message_class(spec.srvtype), spec.name, callback)
