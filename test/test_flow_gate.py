"""Sim flow control (app/flow.py FlowGate) without DDS: send limits, readiness, segments."""

from __future__ import annotations

import pytest

from lubrig_ros.app.flow import FlowGate, qualified_name
from lubrig_ros.core.params import ParameterError

PLANT = "/lubrig/plant"
REC = "/lubrig/lubrig_recorder"


def test_nothing_before_the_plant_has_reported():
    gate = FlowGate(window=300, plant=PLANT)
    assert not gate.ready() and gate.missing() == [PLANT]
    assert gate.limit(1000) == 0
    assert gate.report(PLANT, 0, 0)
    assert gate.ready() and gate.limit(1000) == 300


def test_a_required_consumer_holds_the_start_until_it_reports():
    gate = FlowGate(window=300, plant=PLANT, required=(REC, "/probe"))
    gate.report(PLANT, 0, 0)
    gate.report(REC, 0, 0)
    assert gate.missing() == ["/probe"] and gate.limit(1000) == 0
    gate.report("/probe", 0, 0)
    assert gate.limit(1000) == 300


def test_the_slowest_participant_sets_the_limit():
    gate = FlowGate(window=200, plant=PLANT, required=(REC,))
    gate.report(PLANT, 0, 0)
    gate.report(REC, 0, 0)
    # plant integrated band samples 1..200 (201 state samples with the initial one)
    gate.report(PLANT, 0, 201)
    assert gate.limit() == 200  # the recorder has taken nothing yet
    gate.report(REC, 0, 101)  # took the initial sample and 100 more
    assert gate.slowest() == (REC, 100) and gate.limit() == 300
    gate.report(REC, 0, 201)
    assert gate.limit() == 400 and gate.limit(350) == 350


def test_others_and_stale_reports_are_ignored():
    gate = FlowGate(window=10, plant=PLANT)
    assert not gate.report("/other/node", 0, 5)
    assert gate.report(PLANT, 0, 50)
    assert not gate.report(PLANT, 0, 40)  # late duplicate going backwards
    assert not gate.report(PLANT, -1, 0) and not gate.report(PLANT, 0, -3)
    assert gate.limit() == 59


def test_a_reset_restarts_the_limit_and_keeps_the_old_backlog():
    gate = FlowGate(window=100, plant=PLANT, required=(REC,))
    gate.report(PLANT, 0, 0)
    gate.report(REC, 0, 0)
    gate.report(PLANT, 0, 101)
    gate.report(REC, 0, 41)  # 60 state samples of segment 0 still in flight to the recorder
    gate.report(PLANT, 1, 0)  # reset: segment 1, nothing published yet
    assert gate.segment == 1
    assert gate.covered(REC) == -60 and gate.limit() == 40
    gate.report(REC, 0, 101)  # caught up with segment 0
    assert gate.limit() == 100
    gate.report(REC, 1, 31)
    gate.report(PLANT, 1, 101)
    assert gate.limit() == 130


def test_a_consumer_two_segments_behind_counts_every_segment_in_between():
    gate = FlowGate(window=100, plant=PLANT, required=(REC,))
    gate.report(REC, 0, 0)
    for segment, total in ((0, 51), (1, 21), (2, 0)):
        gate.report(PLANT, segment, total)
    assert gate.covered(REC) == -(51 + 21) and gate.limit() == 28


def test_window_and_names_are_checked():
    with pytest.raises(ParameterError, match="flow_window=0"):
        FlowGate(window=0, plant=PLANT)
    with pytest.raises(ParameterError, match="plant"):
        FlowGate(window=10, plant="")
    assert FlowGate(window=1, plant=PLANT, required=(PLANT, REC, REC)).required == (REC,)
    assert qualified_name("/lubrig", "lubrig_recorder") == REC
    assert qualified_name("/rigA", "/probe") == "/probe"
    assert qualified_name("/", "probe") == "/probe"
    for bad in ("", "2rec", "rec-1", "/a//b", "rec/"):
        with pytest.raises(ParameterError, match="required consumer"):
            qualified_name("/lubrig", bad)


def test_window_one_still_progresses():
    """The smallest window does not deadlock: the plant's report of band sample k frees k + 1."""
    gate = FlowGate(window=1, plant=PLANT)
    gate.report(PLANT, 0, 0)
    sent = 0
    for _ in range(5):
        limit = gate.limit(5)
        assert limit == sent + 1
        sent = limit
        gate.report(PLANT, 0, sent + 1)  # initial state + band samples 1..sent
    assert gate.limit(5) == 5
