"""Where a rig's DDS traffic may go: this host only (the default) or the network (when asked for).

A ROS 2 domain without DDS security lets every participant that can reach it publish band input
and call reset/pause (docs/security.md). So `lubrig rig`, the launch file and the test suite keep a
rig on this host unless the user asks for the network (`lubrig rig --network`, or the environment
variable LUBRIG_DISCOVERY=network). On this host means both halves:

- ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST: the participants do not look for peers elsewhere;
- the Fast DDS profile config/fastdds_localhost.xml (FASTDDS_DEFAULT_PROFILES_FILE): the UDP
  transport bound to the loopback interface, so a peer elsewhere that knows the host's address
  cannot reach the rig either (the range alone does not stop that; measured, docs/security.md).

A user's own FASTDDS_DEFAULT_PROFILES_FILE is kept (their transport choice wins, and
`isolation` says so).

Who else is on the graph (the rules, without ROS): which nodes hold a rig's namespace
(`rig_occupants`, `extra_publishers`), whether band input has a publisher too many
(`band_source_problem`) and which node called a service (`client_name`, `CallerQueue`);
nodes/graph.py and cli/rig_ros.py ask rclpy for the graph.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

from ...core.params import ParameterError
from ...core.presets import config_dir

DISCOVERY_VARIABLE = "LUBRIG_DISCOVERY"
DISCOVERY_CHOICES = ("localhost", "network")
RANGE_VARIABLE = "ROS_AUTOMATIC_DISCOVERY_RANGE"
PROFILE_VARIABLE = "FASTDDS_DEFAULT_PROFILES_FILE"
LOCALHOST_PROFILE = "fastdds_localhost.xml"


def localhost_profile() -> Path:
    """The shipped Fast DDS profile that binds UDP to the loopback interface."""
    return config_dir() / LOCALHOST_PROFILE


@dataclass(frozen=True)
class Discovery:
    """The environment for a rig's processes and one line saying what it allows."""

    env: dict[str, str]
    choice: str
    isolation: str


def discovery_environment(env: Mapping[str, str], network: bool = False) -> Discovery:
    """A copy of `env` for rig processes: on this host only, unless `network` or LUBRIG_DISCOVERY=network.

    ParameterError (a ValueError) names a LUBRIG_DISCOVERY value other than localhost or network.
    """
    out = dict(env)
    choice = "network" if network else out.get(DISCOVERY_VARIABLE, "localhost").strip().lower()
    if choice not in DISCOVERY_CHOICES:
        raise ParameterError(
            f"{DISCOVERY_VARIABLE}={out[DISCOVERY_VARIABLE]!r} is not valid; expected one of "
            f"{list(DISCOVERY_CHOICES)}"
        )
    ours = str(localhost_profile())
    if choice == "network":
        out[RANGE_VARIABLE] = "SUBNET"
        if out.get(PROFILE_VARIABLE) == ours:
            del out[PROFILE_VARIABLE]  # inherited from a localhost launcher: not for the network
        return Discovery(out, choice, "discovery on the network: any host on it can reach the rig")
    out[RANGE_VARIABLE] = "LOCALHOST"
    own = out.get(PROFILE_VARIABLE)
    if own and own != ours:
        text = f"discovery on this host; transports from your {PROFILE_VARIABLE}={own}"
    else:
        out[PROFILE_VARIABLE] = ours
        text = "discovery and transports on this host only (--network or LUBRIG_DISCOVERY=network to open)"
    return Discovery(out, choice, text)


# ------------------------------------------------------------------- who else is on the graph
#
# Two rigs in one namespace on one domain (two `lubrig rig` without --namespace) would both run,
# each bag holding both rigs' samples; two publishers of band input fight over the band. The
# rules below read what a node sees of the ROS graph (node names, publishers per topic, as
# plain (namespace, name) pairs) and say who is in the way; nodes/common.py asks rclpy.

#: What rmw reports for an endpoint whose node is not discovered yet (skipped: known soon).
UNKNOWN_NODE = "_NODE_NAME_UNKNOWN_"
#: s of discovery before "nobody else is there" is believed: a participant announces itself every
#: 0.5 s (config/fastdds_localhost.xml; peers were seen 0.09-0.53 s after they were ready), so
#: three announcement periods.
GRAPH_SETTLE_S = 1.5
#: s a service request's client may stay unnamed in the graph before it is reported as unknown.
#: rmw learns an endpoint's node from its participant's announcement of its entities, which can
#: come after the endpoint itself: beside CPU hogs a request from a client made just before it
#: arrived while the client's node was still _NODE_NAME_UNKNOWN_.
CALLER_SETTLE_S = GRAPH_SETTLE_S

Endpoint = tuple[str, str]  # (node namespace, node name)
ClientEndpoint = tuple[bytes, str, str]  # (endpoint GID, node namespace, node name)


def fully_qualified(namespace: str, name: str) -> str:
    """The node's fully qualified name, /ns/name (/name in the root namespace)."""
    return f"{namespace.rstrip('/')}/{name}"


def _known(endpoints: Iterable[Endpoint]) -> list[str]:
    return [fully_qualified(ns, n) for ns, n in endpoints if n != UNKNOWN_NODE]


def _rig_node(name: str, rig_names: Iterable[str]) -> bool:
    return any(name == r or name.startswith(r + "_") for r in rig_names)


def rig_occupants(
    namespace: str,
    nodes: Iterable[Endpoint],
    publishers: Mapping[str, Iterable[Endpoint]],
    rig_names: Iterable[str],
) -> list[str]:
    """Who holds `namespace`: its rig nodes and the publishers of its topics (sorted, once each).

    Rig nodes: those in `namespace` named as one of `rig_names`, or that name + "_…";
    `publishers`: topic → endpoints, every one of which holds the namespace.
    """
    names = tuple(rig_names)
    held = {fully_qualified(ns, n) for ns, n in nodes if ns == namespace and _rig_node(n, names)}
    for endpoints in publishers.values():
        held.update(_known(endpoints))
    return sorted(held)


def extra_publishers(publishers: Mapping[str, Iterable[Endpoint]], own: str) -> list[str]:
    """Publishers of the topics (each with one publisher of node `own`) besides `own`'s.

    A second node with `own`'s name counts: it is named as `own` (a second rig's node).
    """
    extra: set[str] = set()
    for endpoints in publishers.values():
        names = _known(endpoints)
        if own in names:
            names.remove(own)
        extra.update(names)
    return sorted(extra)


def band_source_problem(
    publishers: Mapping[str, Iterable[Endpoint]], source: str, namespace: str
) -> str | None:
    """Why band input has a publisher too many (None if it has not).

    `publishers`: band input topic → endpoints. `source`: the declared band source, a node name
    (in `namespace`) or a fully qualified name; empty: any one publisher. A publisher other than
    the declared source, a second node of its name, or (no source declared) a second publisher
    is too many.
    """
    by_topic = {topic: _known(endpoints) for topic, endpoints in publishers.items()}
    if source:
        expected = source if source.startswith("/") else fully_qualified(namespace, source)
        others = sorted({n for names in by_topic.values() for n in names if n != expected})
        twice = any(names.count(expected) > 1 for names in by_topic.values())
        if others:
            return (
                f"band input from {', '.join(others)} besides the declared source {expected} "
                "(band_source): more than one publisher drives the band"
            )
        if twice:
            return (
                f"two nodes named {expected} publish band input (another rig in namespace "
                f"{namespace}?): more than one publisher drives the band"
            )
        return None
    every = sorted({n for names in by_topic.values() for n in names})
    twice = any(len(names) != len(set(names)) for names in by_topic.values())
    if len(every) > 1 or twice:
        return (
            f"band input from {len(every) if len(every) > 1 else 2} publishers ({', '.join(every)}): "
            "more than one drives the band (band_source names the one expected)"
        )
    return None


def client_name(endpoints: Iterable[ClientEndpoint], gid: bytes, final: bool = False) -> str | None:
    """Who owns the service client endpoint `gid`; None while the graph cannot tell yet.

    `endpoints`: the service's client endpoints (request writers, reply readers). The endpoint
    itself names its node, once the node is discovered (not UNKNOWN_NODE). Only when waiting is
    over (`final`) does another endpoint of its participant (the GID's first 12 bytes: the process)
    name the process instead: before that, it may be the client's own other endpoint, discovered
    before the one asked for.
    """
    listed = list(endpoints)
    for own, namespace, name in listed:
        if own[: len(gid)] == gid and name != UNKNOWN_NODE:
            return fully_qualified(namespace, name)
    if final:
        for own, namespace, name in listed:
            if own[:12] == gid[:12] and name != UNKNOWN_NODE:
                return f"a client in the process of {fully_qualified(namespace, name)}"
    return None


@dataclass
class _Request:
    gid: bytes
    sequence: int
    deadline: float
    client: str | None = None


class CallerQueue:
    """Service requests whose client is to be named, reported in the order they came.

    Every pending request's client is looked up at each `ready` until found (a short-lived caller
    leaves the graph soon after its reply). A request whose client the graph cannot name yet is
    held, at most `settle` s from its arrival, and then reported as unknown; the reports of the
    requests after it are held behind it, so they keep the order of the requests.
    """

    def __init__(self, settle: float = CALLER_SETTLE_S) -> None:
        self.settle = settle
        self._pending: deque[_Request] = deque()

    def __len__(self) -> int:
        return len(self._pending)

    def add(self, gid: bytes, sequence: int, now: float) -> None:
        """Request `sequence` from client endpoint `gid` arrived at `now` (s, a monotonic clock)."""
        self._pending.append(_Request(gid, sequence, now + self.settle))

    def ready(self, endpoints: Iterable[ClientEndpoint], now: float) -> list[str]:
        """The reports due at `now`, oldest first: "<client> (request N)".

        `endpoints`: the service's client endpoints in the graph now (as for `client_name`).
        """
        listed = list(endpoints)
        for request in self._pending:
            if request.client is None:
                request.client = client_name(listed, request.gid, now >= request.deadline)
        reports = []
        while self._pending and (self._pending[0].client is not None or now >= self._pending[0].deadline):
            request = self._pending.popleft()
            unknown = f"an unknown client (GID {request.gid.hex()}, of no node the ROS graph knows)"
            reports.append(f"{request.client or unknown} (request {request.sequence})")
        return reports

    def flush(self, endpoints: Iterable[ClientEndpoint] | None) -> list[str]:
        """Every pending request's report at once (the node stops).

        `endpoints` as for `ready`; None: the graph cannot be asked any more (the context is shut
        down), so a client not named by then is reported as such.
        """
        if endpoints is not None:
            return self.ready(endpoints, math.inf)
        reports = [
            f"{r.client or f'a client not named before the node stopped (GID {r.gid.hex()})'}"
            f" (request {r.sequence})"
            for r in self._pending
        ]
        self._pending.clear()
        return reports
