"""The opt-in ways back from a Foxglove client to the rig (`view --allow-*`; app/view/access.py).

- `ServiceBridge`: the rig's services as Foxglove services (request and response in ROS 2 CDR
  with their ros2msg definitions); a call is forwarded to the ROS service and the ROS reply is
  returned; no server or no reply within `CALL_TIMEOUT_S` fails the call with a message.
- `BandInput`: a client channel on ``<ns>/band_velocity`` (std_msgs/Float64, CDR or JSON) is
  republished into ROS while the plant runs rig_in_loop (its ``mode`` parameter, asked when the
  channel is advertised); other channels are refused with a status naming what is allowed.
- `Listener`: the server's callbacks (parameters: view_parameters.py; client channels: BandInput).

The server calls the handlers on its own threads; they wait for the ROS reply while the node's
executor (the main thread) takes it, and every client action is logged with the client's id.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

from foxglove.websocket import ServerListener

from lubrig_ros.app.view import access as view_access
from lubrig_ros.app.view.access import Access
from lubrig_ros.core.errors import InputError

from .interfaces import create_publisher, message_class
from .view_topics import MessageSchemas

#: s a forwarded service call or parameter request may wait for the rig node's reply
CALL_TIMEOUT_S = 10.0


#: s after which an idempotent request (parameters) is sent again while none is answered: Fast DDS
#: drops a reply when the server has not yet matched a new client's reply reader
RESEND_S = 2.0


def wait_for(call: Callable[[], Any], what: str, idempotent: bool = False) -> Any:
    """The reply to `call()` (an rclpy future completed by the executor on another thread).

    An idempotent request is sent again every RESEND_S while none is answered (the first reply
    is taken); TimeoutError after CALL_TIMEOUT_S.
    """
    done = threading.Event()
    futures: list[Any] = []
    end = time.monotonic() + CALL_TIMEOUT_S
    while not done.is_set():
        left = end - time.monotonic()
        if left <= 0:
            for future in futures:
                future.cancel()
            raise TimeoutError(f"{what}: no reply within {CALL_TIMEOUT_S:g} s")
        if not futures or idempotent:
            future = call()
            future.add_done_callback(lambda _f: done.set())
            futures.append(future)
        done.wait(min(left, RESEND_S) if idempotent else left)
    return next(f for f in futures if f.done()).result()


class ServiceBridge:
    """The rig's services (contract) callable from Foxglove."""

    def __init__(self, node: Any, namespace: str, schemas: MessageSchemas) -> None:
        self.node = node
        self.schemas = schemas
        self.specs = view_access.rig_services(namespace)
        self.classes: dict[str, Any] = {s.name: message_class(s.srvtype) for s in self.specs}
        self.clients = {s.name: node.create_client(self.classes[s.name], s.name) for s in self.specs}
        self.calls = 0
        self.failed = 0

    def services(self) -> list[Any]:
        """The foxglove Service objects to advertise."""
        import foxglove

        services = []
        for spec in self.specs:
            request, response = self.schemas.service_texts(spec.srvtype)

            def part(name: str, text: str) -> Any:
                schema = foxglove.Schema(name=name, encoding="ros2msg", data=text.encode())
                return foxglove.MessageSchema(encoding="cdr", schema=schema)

            schema = foxglove.ServiceSchema(
                spec.srvtype,
                request=part(spec.srvtype + "_Request", request),
                response=part(spec.srvtype + "_Response", response),
            )
            services.append(foxglove.Service(spec.name, schema=schema, handler=self.handle))
        return services

    def summary(self) -> str:
        """Calls forwarded for clients."""
        return f"  services: {self.calls} calls forwarded, {self.failed} failed"

    def handle(self, request: Any) -> bytes:
        """One call from a client (see `call`); a failure is counted and fails the client's call."""
        try:
            return self.call(request)
        except Exception:
            self.failed += 1
            raise

    def call(self, request: Any) -> bytes:
        """One call from a client: the ROS reply, serialized; an exception fails the call."""
        from rclpy.serialization import deserialize_message, serialize_message

        name = request.service_name
        cls, client = self.classes[name], self.clients[name]
        if request.encoding != "cdr":
            raise InputError(f"{name}: request encoding {request.encoding!r} is not valid; expected cdr")
        if cls.Request.get_fields_and_field_types():
            try:
                ros_request = deserialize_message(bytes(request.payload), cls.Request)
            except Exception as exc:  # rclpy raises a bare RuntimeError
                raise InputError(f"{name}: malformed request ({exc})") from None
        else:  # no fields: whatever the client's CDR writer made of an empty struct
            ros_request = cls.Request()
        if not client.wait_for_service(timeout_sec=CALL_TIMEOUT_S):
            raise RuntimeError(f"{name} is not offered on the ROS graph (is the rig running?)")
        self.node.get_logger().info(f"view: Foxglove client {request.client_id} calls {name}")
        reply = wait_for(lambda: client.call_async(ros_request), name)
        self.calls += 1
        return bytes(serialize_message(reply))


class BandInput:
    """Band velocity published by clients, republished on ``<ns>/band_velocity``."""

    def __init__(self, node: Any, namespace: str) -> None:
        self.node = node
        self.namespace = namespace
        self.publisher = create_publisher(node, view_access.BAND_INPUT)
        self.topic = str(self.publisher.topic_name)  # also for the summary, after the node is gone
        from rclpy.parameter_client import AsyncParameterClient

        self.plant = AsyncParameterClient(node, view_access.resolve_node(namespace, view_access.PLANT))
        self.accepted: dict[tuple[int, int], str] = {}  # (client, channel) -> encoding
        self.published = 0
        self.refused = 0

    def summary(self) -> str:
        """Band input republished for clients."""
        return f"  {self.topic}: {self.published} client messages republished, {self.refused} refused"

    def plant_mode(self) -> object:
        """The plant's `mode` parameter, None if no plant answers (asked on the caller's thread)."""
        from rclpy.parameter import parameter_value_to_python

        if not self.plant.wait_for_services(timeout_sec=CALL_TIMEOUT_S):
            return None
        try:
            reply = wait_for(lambda: self.plant.get_parameters(["mode"]), "plant mode", idempotent=True)
        except TimeoutError:
            return None
        return parameter_value_to_python(reply.values[0]) if reply.values else None

    def advertise(self, client_id: int, channel: Any) -> str | None:
        """Accept a client channel, or the reason it is refused."""
        problem = view_access.band_channel_problem(
            self.namespace, channel.topic, channel.encoding, channel.schema_name
        ) or view_access.band_mode_problem(self.namespace, self.plant_mode())
        if problem is None:
            self.accepted[(client_id, channel.id)] = channel.encoding
            self.node.get_logger().info(f"view: Foxglove client {client_id} publishes on {channel.topic}")
        return problem

    def unadvertise(self, client_id: int, channel_id: int) -> None:
        """The client's channel is gone."""
        self.accepted.pop((client_id, channel_id), None)

    def message(self, client_id: int, channel_id: int, data: bytes) -> str | None:
        """Republish one message of an accepted channel; the reason when it is not republished."""
        from std_msgs.msg import Float64

        encoding = self.accepted.get((client_id, channel_id))
        if encoding is None:
            self.refused += 1
            return f"client channel {channel_id} was refused or not advertised: its messages are dropped"
        try:
            value = view_access.band_value(encoding, data)
        except InputError as exc:
            self.refused += 1
            return str(exc)
        self.publisher.publish(Float64(data=value))
        self.published += 1
        return None


class Listener(ServerListener):
    """The server's callbacks for what `access` opened (the foxglove ServerListener protocol)."""

    def __init__(self, node: Any, access: Access, parameters: Any, band: BandInput | None) -> None:
        self.node = node
        self.access = access
        self.parameters = parameters
        self.band = band
        self._server: Any = None

    @property
    def server(self) -> Any:
        """The running server (None before): statuses go to every client."""
        return self._server

    @server.setter
    def server(self, server: Any) -> None:
        self._server = server
        if self.parameters is not None:
            self.parameters.server = server

    def status(self, message: str, error: bool = True) -> None:
        """Tell the clients (and the log)."""
        import foxglove

        log = self.node.get_logger()
        (log.warning if error else log.info)(f"view: {message}")
        if self.server is not None:
            level = foxglove.StatusLevel.Error if error else foxglove.StatusLevel.Info
            self.server.publish_status(message, level)

    def on_client_advertise(self, client: Any, channel: Any) -> None:
        """A client channel: band input, or refused."""
        problem = (
            "publishing is not enabled" if self.band is None else self.band.advertise(client.id, channel)
        )
        if problem is not None:
            self.status(f"client channel {channel.topic!r} refused: {problem}")

    def on_client_unadvertise(self, client: Any, client_channel_id: int) -> None:
        """A client channel ends."""
        if self.band is not None:
            self.band.unadvertise(client.id, client_channel_id)

    def on_message_data(self, client: Any, client_channel_id: int, data: bytes) -> None:
        """A client's message: republished, or refused with a status (never fatal)."""
        if self.band is None:
            return
        problem = self.band.message(client.id, client_channel_id, bytes(data))
        if problem is not None and self.band.refused <= 10:  # a stream of bad input: the first ten
            self.status(problem)

    def on_get_parameters(
        self, client: Any, param_names: list[str], request_id: str | None = None
    ) -> list[Any]:
        """The named parameters of the rig nodes (all of them for no name)."""
        if self.parameters is None:
            return []
        return list(self.parameters.get(param_names, self.status))

    def on_parameters_subscribe(self, param_names: list[str]) -> None:
        """Clients want changes of these parameters pushed."""
        if self.parameters is not None:
            self.parameters.subscribe(param_names, True)

    def on_parameters_unsubscribe(self, param_names: list[str]) -> None:
        """No client wants changes of these parameters any more."""
        if self.parameters is not None:
            self.parameters.subscribe(param_names, False)

    def on_set_parameters(
        self, client: Any, parameters: list[Any], request_id: str | None = None
    ) -> list[Any]:
        """Set through the nodes; returns the values they hold afterwards (a refused one unchanged)."""
        if self.parameters is None:
            return []
        self.node.get_logger().info(f"view: Foxglove client {client.id} sets {[p.name for p in parameters]}")
        return list(self.parameters.set(parameters, self.status))
