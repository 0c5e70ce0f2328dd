"""Rig node parameters for Foxglove clients (`view --allow-parameters`; app/view/access.py).

Read and set through each node's own ROS parameter services (rclpy's AsyncParameterClient), so
the node's validation decides: a value it refuses is not applied, and its reason goes back to the
client as an error status while the value returned is the one the node still holds. Clients see
``<node FQN>.<parameter>``; the nodes are the contract's rig nodes found in the namespace. A
change of a parameter a client subscribed to, made by anyone (``ros2 param set``, another
client), is pushed to the clients from the node's ``/parameter_events``.
"""

from __future__ import annotations

import array
import functools
from collections.abc import Callable, Iterable
from typing import Any

from lubrig_ros.app.view import access as view_access
from lubrig_ros.core.errors import InputError

from .view_control import wait_for

Status = Callable[[str], None]


def _native(value: Any, current: Any) -> Any:
    """A client's value in the type of the node's current value where the wire lost it (2 -> 2.0)."""
    if isinstance(current, float) and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if isinstance(current, list) and isinstance(value, list) and current and isinstance(current[0], float):
        return [float(v) if isinstance(v, int) and not isinstance(v, bool) else v for v in value]
    return value


def _wire(value: Any) -> Any:
    """A ROS parameter value as foxglove takes it (arrays as lists)."""
    if isinstance(value, tuple | array.array):
        return list(value)
    return value


class ParameterBridge:
    """Parameters of the rig nodes of `namespace`, by the names clients see."""

    def __init__(self, node: Any, namespace: str) -> None:
        self.node = node
        self.nodes = view_access.rig_nodes(namespace)
        self.clients: dict[str, Any] = {}  # node FQN -> AsyncParameterClient, made on the main thread
        self.namespace = namespace
        self.subscribed: set[str] = set()  # client names whose changes clients want pushed
        self.server: Any = None  # set once the server runs
        self.taken = 0
        self.refused = 0
        from rcl_interfaces.msg import ParameterEvent
        from rclpy.qos import qos_profile_parameter_events

        node.create_subscription(
            ParameterEvent, "/parameter_events", self._on_event, qos_profile_parameter_events
        )

    def summary(self) -> str:
        """Parameter updates sent for clients."""
        return f"  parameters: {self.taken} set, {self.refused} refused by their node"

    def subscribe(self, names: list[str], on: bool) -> None:
        """Clients want changes of `names` pushed (on) or no longer (off)."""
        if on:
            self.subscribed.update(names)
        else:
            self.subscribed.difference_update(names)

    def _on_event(self, event: Any) -> None:
        """A rig node's parameters changed (whoever set them): push the subscribed ones."""
        import foxglove
        from rclpy.parameter import parameter_value_to_python

        if event.node not in self.nodes or self.server is None:
            return
        pushed = []
        for p in [*event.new_parameters, *event.changed_parameters]:
            full = view_access.parameter_name(event.node, p.name)
            value = parameter_value_to_python(p.value)
            if full in self.subscribed and value is not None:
                pushed.append(foxglove.Parameter(full, value=_wire(value)))
        if pushed:
            self.server.publish_parameter_values(pushed)

    def discover(self) -> None:
        """Parameter clients for the rig nodes now on the graph (called on the node's thread)."""
        from rclpy.parameter_client import AsyncParameterClient

        for name, ns in self.node.get_node_names_and_namespaces():
            fqn = view_access.resolve_node(ns, name)
            if fqn in self.nodes and fqn not in self.clients:
                self.clients[fqn] = AsyncParameterClient(self.node, fqn)

    def _values(self, fqn: str, names: list[str] | None) -> dict[str, Any]:
        """Name -> value (Python) of `names` of node `fqn` (all of them for None)."""
        from rclpy.parameter import parameter_value_to_python

        client = self.clients[fqn]
        if names is None:
            listed = wait_for(client.list_parameters, f"{fqn}: list parameters", idempotent=True)
            names = list(listed.result.names)
        reply = wait_for(lambda: client.get_parameters(names), f"{fqn}: get parameters", idempotent=True)
        return {n: parameter_value_to_python(v) for n, v in zip(names, reply.values, strict=False)}

    def _grouped(self, names: Iterable[str], status: Status) -> dict[str, list[str]]:
        """Client names grouped by node FQN (unknown nodes named in a status)."""
        grouped: dict[str, list[str]] = {}
        for full in names:
            try:
                fqn, name = view_access.split_parameter_name(full, self.nodes)
            except InputError as exc:
                status(str(exc))
                continue
            if fqn not in self.clients:
                status(f"parameter {full!r}: node {fqn} is not on the ROS graph")
                continue
            grouped.setdefault(fqn, []).append(name)
        return grouped

    def get(self, names: list[str], status: Status) -> Iterable[Any]:
        """Foxglove Parameters for `names` (every rig node parameter for none)."""
        import foxglove

        requests = {fqn: None for fqn in list(self.clients)} if not names else self._grouped(names, status)
        for fqn, wanted in requests.items():
            try:
                values = self._values(fqn, wanted)
            except TimeoutError as exc:
                status(str(exc))
                continue
            for name, value in values.items():
                if value is not None:  # not set: nothing to show
                    yield foxglove.Parameter(view_access.parameter_name(fqn, name), value=_wire(value))

    def set(self, parameters: list[Any], status: Status) -> Iterable[Any]:
        """Set each through its node; the values the nodes hold afterwards (refusals in statuses)."""
        from rclpy.parameter import Parameter

        wanted = {p.name: p.get_value() for p in parameters}
        grouped = self._grouped(wanted, status)
        for fqn, names in grouped.items():
            try:
                current = self._values(fqn, names)
                values = {n: _native(wanted[view_access.parameter_name(fqn, n)], current[n]) for n in names}
                request = [Parameter(n, value=v) for n, v in values.items()]
                send = functools.partial(self.clients[fqn].set_parameters, request)
                reply = wait_for(send, f"{fqn}: set parameters", idempotent=True)
            except (TimeoutError, TypeError, ValueError, KeyError) as exc:
                status(f"parameters {names} of {fqn} not set: {exc}")
                continue
            for (name, value), result in zip(values.items(), reply.results, strict=False):
                if not result.successful:
                    self.refused += 1
                    status(f"{fqn} refused {name} = {value!r}: {result.reason}")
                else:
                    self.taken += 1
                    self.node.get_logger().info(f"view: {fqn} took {name} = {value!r}")
        return self.get(list(wanted), lambda _m: None)  # unknown names were reported above
