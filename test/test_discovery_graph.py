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


def test_a_client_is_named_by_its_endpoint_its_process_only_when_waiting_is_over():
    endpoints = [
        (_gid(OTHER, 3), "/", "viewer"),
        (_gid(PROBE, 7), "/rig2", "probe"),
        (_gid(PROBE, 9), UNKNOWN_NODE, UNKNOWN_NODE),
    ]
    for final in (False, True):
        assert client_name(endpoints, _gid(PROBE, 7), final) == "/rig2/probe"
        assert client_name(endpoints, _gid(OTHER, 3), final) == "/viewer"
        assert client_name([], _gid(PROBE, 7), final) is None
        assert client_name(endpoints[2:], _gid(PROBE, 11), final) is None
    # the endpoint is there but its node is not discovered yet, or the endpoint is not listed: the
    # process's other endpoint (maybe the client's own reply reader) names it only in the end
    for gid in (_gid(PROBE, 9), _gid(PROBE, 11)):
        assert client_name(endpoints, gid) is None
        assert client_name(endpoints, gid, final=True) == "a client in the process of /rig2/probe"
    # a longer listed GID (zero padded storage) matches on the request header's bytes
    assert client_name([(_gid(PROBE, 7) + bytes(8), "/", "probe")], _gid(PROBE, 7)) == "/probe"


def test_callers_are_named_as_soon_as_known_reported_in_order_unknown_after_the_settle():
    graph: list[tuple[bytes, str, str]] = [(_gid(PROBE, 9), UNKNOWN_NODE, UNKNOWN_NODE)]
    queue = CallerQueue(settle=1.5)
    queue.add(_gid(PROBE, 9), 1, now=10.0)
    graph.append((_gid(OTHER, 3), "/", "viewer"))
    queue.add(_gid(OTHER, 3), 1, now=10.1)
    # the first request's node is unknown: it waits, and the second's report waits behind it, its
    # client named already: a short-lived caller may leave the graph before the first is known
    assert queue.ready(graph, now=10.2) == [] and len(queue) == 2
    del graph[1]
    graph[0] = (_gid(PROBE, 9), "/rig2", "probe")
    assert queue.ready(graph, now=10.3) == ["/rig2/probe (request 1)", "/viewer (request 1)"]
    assert len(queue) == 0 and queue.ready(graph, now=10.4) == []
    # never named by its endpoint: its process names it once the settle is over, not before
    graph.append((_gid(OTHER, 4), UNKNOWN_NODE, UNKNOWN_NODE))
    queue.add(_gid(OTHER, 4), 2, now=20.0)
    graph.append((_gid(OTHER, 5), "/", "viewer"))
    assert queue.ready(graph, now=21.49) == []
    assert queue.ready(graph, now=21.5) == ["a client in the process of /viewer (request 2)"]
    # nothing of its process in the graph: unknown, with its GID
    stranger = _gid(bytes(range(50, 62)), 13)
    queue.add(stranger, 3, now=30.0)
    assert queue.ready(graph, now=31.0) == []
    unknown = f"an unknown client (GID {stranger.hex()}, of no node the ROS graph knows) (request 3)"
    assert queue.ready(graph, now=31.5) == [unknown]


def test_a_stopping_node_reports_every_waiting_caller_at_once():
    graph = [
        (_gid(PROBE, 9), "/rig2", "probe"),
        (_gid(OTHER, 4), UNKNOWN_NODE, UNKNOWN_NODE),
        (_gid(OTHER, 5), "/", "viewer"),
    ]
    stranger = _gid(bytes(range(50, 62)), 13)
    queue = CallerQueue(settle=1.5)
    queue.add(stranger, 4, now=40.0)
    queue.add(_gid(OTHER, 4), 5, now=40.0)
    queue.add(_gid(PROBE, 9), 6, now=40.0)
    # the graph can still be asked: the final answers (the process fallback included)
    assert queue.flush(graph) == [
        f"an unknown client (GID {stranger.hex()}, of no node the ROS graph knows) (request 4)",
        "a client in the process of /viewer (request 5)",
        "/rig2/probe (request 6)",
    ]
    assert len(queue) == 0
    # it cannot (the context is shut down): a client named already keeps its name, the others are
    # said not to have been named, not to be unknown to the graph
    queue.add(_gid(PROBE, 9), 7, now=50.0)
    assert queue.ready(graph, now=50.0) == ["/rig2/probe (request 7)"]
    queue.add(_gid(OTHER, 4), 8, now=50.0)
    queue.add(_gid(PROBE, 9), 9, now=50.0)
    queue.add(stranger, 10, now=50.0)
    queue.ready(graph, now=50.1)  # request 9's client is named now, held behind request 8
    assert queue.flush(None) == [
        f"a client not named before the node stopped (GID {_gid(OTHER, 4).hex()}) (request 8)",
        "/rig2/probe (request 9)",
        f"a client not named before the node stopped (GID {stranger.hex()}) (request 10)",
    ]
    assert len(queue) == 0
