"""Who holds a namespace, who drives the band (app/processes/discovery.py): the rules on plain graph data."""

from __future__ import annotations

from lubrig_ros.app.processes.discovery import (
    UNKNOWN_NODE,
    band_source_problem,
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
