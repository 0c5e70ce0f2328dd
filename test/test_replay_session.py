"""The replay's state machine without ROS: pause, resume, step, seek, rate, until, loop, lossless.

Time is given to the session (a fake clock), so every due time is asserted exactly.
"""

from __future__ import annotations

import pytest

from lubrig_ros.app.interface.cdr import SampleSpan
from lubrig_ros.app.recording.replay import Done, Entry, Publish, ReplaySession, Wait
from lubrig_ros.app.recording.replay_flow import LosslessFlow
from lubrig_ros.core.errors import InputError

T0 = 10_000_000_000
STEP = 100_000_000  # 0.1 s between messages


def entries(n: int = 10) -> list[Entry]:
    return [Entry("/a", T0 + k * STEP, bytes([k])) for k in range(n)]


def drain(s: ReplaySession, now: float) -> list[int]:
    """Everything due at `now`, as message numbers."""
    out = []
    while isinstance(a := s.next(now), Publish):
        out.append(a.entry.data[0])
    return out


def test_paced_by_log_time_over_rate() -> None:
    s = ReplaySession(entries(), origin_ns=T0, now=100.0, rate=2.0)
    assert drain(s, 100.0) == [0]
    wait = s.next(100.0)
    assert isinstance(wait, Wait) and wait.seconds == pytest.approx(0.05)
    assert drain(s, 100.0499) == []
    assert drain(s, 100.05) == [1]
    assert drain(s, 100.45) == [2, 3, 4, 5, 6, 7, 8, 9]
    assert isinstance(s.next(200.0), Done)
    assert s.published == 10


def test_pause_holds_everything_and_resume_goes_on_from_the_paused_bag_time() -> None:
    s = ReplaySession(entries(), origin_ns=T0, now=0.0)
    assert drain(s, 0.0) == [0]
    assert s.pause(0.05) and not s.pause(0.06)
    assert s.next(1000.0) == Wait(None)
    assert s.bag_time_ns(1000.0) == T0 + 50_000_000
    assert s.resume(1000.0) and not s.resume(1000.0)
    assert drain(s, 1000.0499) == []
    assert drain(s, 1000.05) == [1]
    assert s.toggle(1000.06) is True and s.toggle(1000.07) is False


def test_step_gives_exactly_the_next_message_and_only_when_paused() -> None:
    s = ReplaySession(entries(3), origin_ns=T0, now=0.0, paused=True)
    assert s.next(50.0) == Wait(None)
    assert [s.step(0.0).data[0] for _ in range(2)] == [0, 1]  # type: ignore[union-attr]
    assert s.next(99.0) == Wait(None)
    s.resume(100.0)  # from message 1's time: message 2 is 0.1 s later
    assert drain(s, 100.0999) == []
    assert drain(s, 100.1) == [2]
    assert "not paused" in str(s.step(0.0))
    s.pause(101.0)
    assert "end" in str(s.step(0.0))


def test_seek_goes_to_the_first_message_at_or_after_the_time() -> None:
    s = ReplaySession(entries(), origin_ns=T0, now=0.0, paused=True)
    s.seek(0.55, 0.0)
    assert s.step(0.0).data[0] == 6  # type: ignore[union-attr]
    s.seek(0.3, 0.0)
    assert s.step(0.0).data[0] == 3  # type: ignore[union-attr]
    s.resume(5.0)
    assert drain(s, 5.0) == []  # message 4 is 0.1 s after message 3
    assert drain(s, 5.1) == [4]
    s.seek(0.0, 6.0)  # while playing: at once from the start
    assert drain(s, 6.0) == [0]
    with pytest.raises(
        InputError, match=r"seek 0\.95 is invalid: expected seconds of bag time in \[0, 0\.9\]"
    ):
        s.seek(0.95, 7.0)
    with pytest.raises(InputError, match="seek nan"):
        s.seek(float("nan"), 7.0)


def test_rate_change_keeps_the_bag_time_reached() -> None:
    s = ReplaySession(entries(), origin_ns=T0, now=0.0)
    assert drain(s, 0.0) == [0]
    s.set_rate(0.5, 0.05)  # 0.05 s of bag time reached; 0.05 s left take 0.1 s now
    assert drain(s, 0.1499) == []
    assert drain(s, 0.15 + 1e-9) == [1]
    s.set_rate(10.0, 0.15)
    assert drain(s, 0.16) == [2]
    with pytest.raises(InputError, match=r"rate 0 is invalid: expected a time scale in \(0, 1000\]"):
        s.set_rate(0, 1.0)
    s.pause(1.0)
    s.set_rate(4.0, 2.0)
    assert s.rate == 4.0 and s.paused


def test_start_and_until_bound_the_played_range_and_loop_repeats_it() -> None:
    s = ReplaySession(entries(), origin_ns=T0, now=0.0, start_s=0.25, until_s=0.5, rate=1000.0)
    assert drain(s, 1.0) == [3, 4, 5]  # 0.3, 0.4, 0.5 s: the last one at or before --until
    assert isinstance(s.next(2.0), Done)
    assert s.bounds_s() == (0.0, 0.5)
    s = ReplaySession(entries(), origin_ns=T0, now=0.0, start_s=0.25, until_s=0.45, rate=1000.0, loop=True)
    assert drain(s, 1.0) == [3, 4]
    assert drain(s, 2.0) == [3, 4]  # again from --start
    s = ReplaySession(entries(), origin_ns=T0, now=0.0, start_s=0.85, until_s=0.88, loop=True)
    assert isinstance(s.next(0.0), Done)  # nothing in the range: no endless loop


# ---- lossless ----------------------------------------------------------------------------
def blocks(first: int, n: int, size: int = 10, segment: int = 0) -> list[Entry]:
    out = []
    for b in range(n):
        k = first + b * size
        span = SampleSpan(T0 + k * 1_000_000, segment, k, size, 1e6)
        out.append(Entry("/lubrig/state_block", span.stamp_ns, bytes(4), span))
    return out


def firsts(s: ReplaySession, now: float) -> list[int]:
    out = []
    while isinstance(a := s.next(now), Publish):
        assert a.entry.span is not None
        out.append(a.entry.span.first_index)
    return out


def test_lossless_sends_no_message_of_any_topic_before_every_first_report() -> None:
    """A /clock before the first state block is held too: the subscriber's first report says its
    readers have matched, and a message sent before that could reach a reader that drops it."""
    flow = LosslessFlow("/lubrig_replay", ("/a",), window=30)
    clock = Entry("/clock", T0, bytes([7]))
    s = ReplaySession([clock, *blocks(0, 2)], origin_ns=T0, now=0.0, rate=1000.0, flow=flow)
    wait = s.next(1.0)
    assert isinstance(wait, Wait) and wait.reason == "waiting for the first flow_progress of /a"
    flow.report("/a", 0, 0)
    action = s.next(1.0)
    assert isinstance(action, Publish) and action.entry is clock
    assert firsts(s, 1.0) == [0, 10]


def test_lossless_sends_no_further_than_the_window_beyond_the_slowest_subscriber() -> None:
    flow = LosslessFlow("/lubrig_replay", ("/a", "/b"), window=30)
    s = ReplaySession(blocks(0, 10), origin_ns=T0, now=0.0, rate=1000.0, flow=flow)
    wait = s.next(1.0)
    assert isinstance(wait, Wait) and wait.reason == "waiting for the first flow_progress of /a, /b"
    flow.report("/a", 0, 0)
    flow.report("/b", 0, 0)
    assert firsts(s, 1.0) == [0, 10, 20]  # samples 0..29: sample 29 = covered 0 + 30 - 1
    wait = s.next(1.0)
    assert isinstance(wait, Wait) and "waiting for /a" in wait.reason
    flow.report("/a", 0, 20)  # took samples 0..19
    assert firsts(s, 1.0) == []  # /b has taken nothing
    flow.report("/b", 0, 30)
    assert firsts(s, 1.0) == [30, 40]  # /a covered 19: up to sample 49
    flow.report("/a", 0, 40)
    assert firsts(s, 1.0) == [50]  # /b (covered 29) is the slowest now
    flow.report("/a", 0, 999)  # beyond what was sent: not a report of this stretch
    flow.report("/b", 0, 999)
    assert firsts(s, 1.0) == []


def test_lossless_seek_waits_for_the_previous_stretch_then_starts_a_new_gate() -> None:
    flow = LosslessFlow("/lubrig_replay", ("/a",), window=20)
    s = ReplaySession(blocks(0, 10), origin_ns=T0, now=0.0, rate=1000.0, flow=flow)
    flow.report("/a", 0, 0)
    assert firsts(s, 1.0) == [0, 10]
    s.seek(0.06, 0.5)  # block 60..69: a new stretch
    wait = s.next(1.0)
    assert isinstance(wait, Wait) and "waiting for /a" in wait.reason  # 0..19 still in flight
    flow.report("/a", 0, 20)
    assert firsts(s, 1.0) == [60, 70]  # /a counts as having taken everything before 60
    flow.report("/a", 0, 20)  # a late copy of an old report: ignored
    assert firsts(s, 1.0) == []
    flow.report("/a", 0, 70)
    assert firsts(s, 1.0) == [80]
    s.pause(1.0)
    assert "waiting for /a" in str(s.step(0.0))
    flow.report("/a", 0, 90)
    assert s.step(0.0).span.first_index == 90  # type: ignore[union-attr]


def test_lossless_window_is_checked_against_the_block_length() -> None:
    with pytest.raises(ValueError, match="flow_window=0"):
        LosslessFlow("/r", ("/a",), window=0)
    with pytest.raises(InputError, match="lossless replay needs at least one subscriber"):
        LosslessFlow("/r", (), window=10)
    flow = LosslessFlow("/r", ("/a",), window=10_000)
    flow.check_blocks(1000)
    with pytest.raises(InputError, match="--flow-window: flow_window=10000 is too large for block_length=10"):
        flow.check_blocks(10)


def test_lossless_loop_waits_for_the_pass_to_be_taken_then_plays_it_again() -> None:
    flow = LosslessFlow("/lubrig_replay", ("/a",), window=100)
    s = ReplaySession(blocks(0, 3), origin_ns=T0, now=0.0, rate=1000.0, loop=True, flow=flow)
    flow.report("/a", 0, 0)
    assert firsts(s, 1.0) == [0, 10, 20]
    wait = s.next(2.0)  # the loop starts over only when /a has taken the whole pass
    assert isinstance(wait, Wait) and "waiting for /a" in wait.reason
    flow.report("/a", 0, 30)
    assert firsts(s, 3.0) == [0, 10, 20]
    flow.report("/a", 0, 30)  # the old pass's count again: says nothing about this one
    assert isinstance(s.next(4.0), Wait)
    flow.report("/a", 0, 10)
    flow.report("/a", 0, 30)
    assert firsts(s, 5.0) == [0, 10, 20]


def test_lossless_end_waits_until_everything_sent_was_taken() -> None:
    flow = LosslessFlow("/lubrig_replay", ("/a",), window=100)
    s = ReplaySession(blocks(0, 2), origin_ns=T0, now=0.0, rate=1000.0, flow=flow)
    flow.report("/a", 0, 0)
    assert firsts(s, 1.0) == [0, 10]
    assert isinstance(s.next(2.0), Wait)
    flow.report("/a", 0, 20)
    assert isinstance(s.next(2.0), Done)


def test_paused_loop_steps_over_the_end_to_the_start() -> None:
    s = ReplaySession(entries(3), origin_ns=T0, now=0.0, start_s=0.1, loop=True, paused=True)
    assert [s.step(0.0).data[0] for _ in range(4)] == [1, 2, 1, 2]  # type: ignore[union-attr]
    assert s.next(1.0) == Wait(None)  # paused at the end of a loop: waiting, not done
