"""Who holds a namespace, drives the band, called a service (app/processes/discovery.py): plain graph data."""

from __future__ import annotations

from lubrig_ros.app.processes.discovery import (
    UNKNOWN_NODE,
    CallerQueue,
    band_source_problem,
    client_name,
    extra_publishers,
    rig_occupants,
)

RIG = ("plant", "belt_drive", "analysis", "lubrig_recorder")


def test_rig_nodes_and_publishers_hold_a_namespace_subscribers_elsewhere_do_not():
    nodes = [
        ("/lubrig", "plant"),
        ("/lubrig", "view"),
        ("/lubrig", "lubrig_recorder_w0"),
        ("/other", "plant"),
    ]
    publishers = {"/lubrig/state_block": [("/replay", "lubrig_replay"), (UNKNOWN_NODE, UNKNOWN_NODE)]}
    held = rig_occupants("/lubrig", nodes, publishers, RIG)
    assert held == ["/lubrig/lubrig_recorder_w0", "/lubrig/plant", "/replay/lubrig_replay"]
    assert rig_occupants("/lubrig", [("/lubrig", "view"), ("/lubrig", "plantation")], {}, RIG) == []


def test_extra_publishers_count_a_second_node_of_the_own_name():
    own = "/lubrig/plant"
    assert extra_publishers({"/lubrig/state_block": [("/lubrig", "plant")]}, own) == []
    twice = {"/lubrig/state_block": [("/lubrig", "plant"), ("/lubrig", "plant")]}
    assert extra_publishers(twice, own) == [own]
    assert extra_publishers({"/lubrig/run_complete": [("/", "fake")]}, own) == ["/fake"]


def test_band_source_problems():
    belt = [("/lubrig", "belt_drive")]
    assert band_source_problem({"/lubrig/band_velocity_block": belt}, "belt_drive", "/lubrig") is None
    other = {"/lubrig/band_velocity_block": belt, "/lubrig/band_velocity": [("/", "probe")]}
    text = band_source_problem(other, "belt_drive", "/lubrig")
    assert text is not None and text.startswith(
        "band input from /probe besides the declared source /lubrig/belt_drive"
    )
    twice = {"/lubrig/band_velocity_block": belt * 2}
    assert "two nodes named /lubrig/belt_drive" in (
        band_source_problem(twice, "/lubrig/belt_drive", "/lubrig") or ""
    )
    assert band_source_problem({"/lubrig/band_velocity": [("/", "rig_sw")]}, "", "/lubrig") is None
    text = band_source_problem(other, "", "/lubrig")
    assert text is not None and "2 publishers (/lubrig/belt_drive, /probe)" in text


PROBE = bytes(range(12))  # a participant's GID prefix (the process)
OTHER = bytes(range(100, 112))


def _gid(participant: bytes, entity: int) -> bytes:
    return participant + entity.to_bytes(4, "big")


def test_a_client_is_named_by_its_endpoint_else_by_its_process_never_while_its_node_is_unknown():
    endpoints = [
        (_gid(OTHER, 3), "/", "viewer"),
        (_gid(PROBE, 7), "/rig2", "probe"),
        (_gid(PROBE, 9), UNKNOWN_NODE, UNKNOWN_NODE),
    ]
    assert client_name(endpoints, _gid(PROBE, 7)) == "/rig2/probe"
    assert client_name(endpoints, _gid(OTHER, 3)) == "/viewer"
    # the endpoint itself is there but its node is not discovered yet: nobody, not its process
    assert client_name(endpoints, _gid(PROBE, 9)) is None
    # an endpoint not listed (GID of an entity the rmw does not list): its process names it
    assert client_name(endpoints, _gid(PROBE, 11)) == "a client in the process of /rig2/probe"
    assert client_name(endpoints[2:], _gid(PROBE, 11)) is None
    assert client_name([], _gid(PROBE, 7)) is None
    # a longer listed GID (zero padded storage) matches on the request header's bytes
    assert client_name([(_gid(PROBE, 7) + bytes(8), "/", "probe")], _gid(PROBE, 7)) == "/probe"


def test_callers_wait_for_the_graph_in_order_at_most_the_settle_then_are_reported_unknown():
    graph: list[tuple[bytes, str, str]] = [(_gid(PROBE, 9), UNKNOWN_NODE, UNKNOWN_NODE)]

    def lookup(gid: bytes) -> str | None:
        return client_name(graph, gid)

    queue = CallerQueue(settle=1.5)
    queue.add(_gid(PROBE, 9), 1, now=10.0)
    queue.add(_gid(OTHER, 3), 1, now=10.1)
    graph.append((_gid(OTHER, 3), "/", "viewer"))
    # the first request's node is unknown: it waits, and the second (named) waits behind it
    assert queue.ready(lookup, now=10.2) == [] and len(queue) == 2
    graph[0] = (_gid(PROBE, 9), "/rig2", "probe")
    assert queue.ready(lookup, now=10.3) == ["/rig2/probe (request 1)", "/viewer (request 1)"]
    assert len(queue) == 0 and queue.ready(lookup, now=10.4) == []
    # a client never named (no endpoint of its process listed): reported unknown once the settle
    # is over, with its GID, not before
    stranger = _gid(bytes(range(50, 62)), 13)
    queue.add(stranger, 2, now=20.0)
    assert queue.ready(lookup, now=21.49) == []
    assert queue.ready(lookup, now=21.5) == [
        f"an unknown client (GID {stranger.hex()}, not in the ROS graph after 1.5 s) (request 2)"
    ]
    assert len(queue) == 0
