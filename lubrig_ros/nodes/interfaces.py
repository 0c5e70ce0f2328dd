"""The contract's plain data (app/contract.py) as rclpy objects.

QoS profiles, message classes, and publishers, subscriptions and services made by contract name.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from ..app import contract
from ..app.contract import QoS


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
        raise ValueError(f"message type {msgtype!r} is invalid: expected pkg/msg/Name")
    try:
        return getattr(importlib.import_module(f"{parts[0]}.{parts[1]}"), parts[2])
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"message type {msgtype!r} is not installed") from exc


def create_publisher(node: Any, namespace: str, name: str) -> Any:
    """A publisher of the contract topic `name` in `namespace` (type and QoS from the contract)."""
    spec = contract.topic(name).resolved(namespace)
    return node.create_publisher(message_class(spec.msgtype), spec.name, qos_profile(spec.qos))


def create_subscription(
    node: Any, namespace: str, name: str, callback: Callable[[Any], None], raw: bool = False
) -> Any:
    """A subscription to the contract topic `name` in `namespace`."""
    spec = contract.topic(name).resolved(namespace)
    return node.create_subscription(
        message_class(spec.msgtype), spec.name, callback, qos_profile(spec.qos), raw=raw
    )


def create_service(node: Any, namespace: str, name: str, callback: Callable[[Any, Any], Any]) -> Any:
    """A service server of the contract service `name` in `namespace`."""
    spec = contract.service(name).resolved(namespace)
    return node.create_service(message_class(spec.srvtype), spec.name, callback)
