"""bag/recording.py: the recorder's ROS-free session, fed serialized messages as its workers ship them.

Messages are serialized by rclpy (the real interface package), the bag is read back by rosbags and
mcap + mcap_ros2 (lubrig_testkit.crosscheck), never by the project's reader.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
from builtin_interfaces.msg import Time
from lubrig_testkit.crosscheck import read_mcap, read_rosbags
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64

from lubrig_interfaces.msg import BandVelocityBlock, FlowProgress, RigStateBlock
from lubrig_ros.app.interface.contract import resolve, select_topics
from lubrig_ros.bag.reader import RIG_STATE_FIELDS
from lubrig_ros.bag.recording import REQUIRED_MATCH_WAIT_S, SIM_HOLD_NS, WALL_CLOCK_NS, RecordingSession

NS = "/lubrig"
MS = 1_000_000
CONFIG = "case: 1\nduration: 1.0\n"


def _stamp(ns: int) -> Time:
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def _block(first: int, n: int, segment: int = 0, t0_ns: int | None = None) -> bytes:
    msg = RigStateBlock()
    msg.header.stamp = _stamp(first * MS if t0_ns is None else t0_ns)
    msg.sample_period = 1e-3
    msg.first_sample_index = first
    msg.segment = segment
    values = [float(first + i) for i in range(n)]
    for field in RIG_STATE_FIELDS:
        setattr(msg, field, values)
    return serialize_message(msg)


def _clock(ns: int) -> bytes:
    return serialize_message(Clock(clock=_stamp(ns)))


def _session(
    tmp_path: Path, names: list[str], sim: bool, run_config: str | None = CONFIG
) -> RecordingSession:
    return RecordingSession(tmp_path / "bag", select_topics(NS, names), run_config, sim, NS)


def _index(session: RecordingSession, name: str) -> int:
    return next(i for i, s in enumerate(session.streams) if s.spec.name == resolve(NS, name))


def test_blocks_are_written_counted_and_reported_as_flow_progress(tmp_path: Path) -> None:
    session = _session(tmp_path, ["state_block"], sim=False)
    reports: list[tuple[int, int, int]] = []
    session.on_progress = lambda seg, n, t: reports.append((seg, n, t))
    k = _index(session, "state_block")
    session.start()
    session.matched([k])
    assert reports == [(0, 0, 0)]  # subscribed and matched: the sim belt may start
    session.handle([(k, 1, _block(0, 250)), (k, 2, _block(250, 250))])
    assert reports[1:] == [(0, 250, 249 * MS), (0, 500, 499 * MS)]
    session.close()
    assert session.problems() == []
    values = read_rosbags(session.writer.path)
    assert values[resolve(NS, "state_block")] == [float(i) for i in range(500)]
    assert read_mcap(session.writer.path) == values
    config_topic = resolve(NS, "run_config")
    assert values[config_topic] == [CONFIG]  # written first, though never received


def test_first_report_waits_for_the_required_streams_readers_to_match(tmp_path: Path) -> None:
    """A writer's match alone is half of one: the run starts on the recorder's own readers' match."""
    session = _session(tmp_path, ["state_block", "band_velocity_block", "state"], sim=False)
    session.required = (resolve(NS, "state_block"), resolve(NS, "band_velocity_block"))
    reports: list[tuple[int, int, int]] = []
    session.on_progress = lambda seg, n, t: reports.append((seg, n, t))
    session.matched([_index(session, "state_block"), _index(session, "state")])
    assert reports == []  # band_velocity_block's reader has not matched belt_drive yet
    session.matched([_index(session, "band_velocity_block")])
    assert reports == [(0, 0, 0)]
    session.matched([_index(session, "band_velocity_block")])
    assert reports == [(0, 0, 0)]  # once
    assert session.ready_without == ()
    session.close()


def test_first_report_waits_for_a_required_stream_only_so_long(tmp_path: Path) -> None:
    """A required stream nobody publishes must not hold the run for ever: named, then reported."""
    session = _session(tmp_path, ["state_block", "band_velocity_block"], sim=False)
    session.required = (resolve(NS, "band_velocity_block"),)
    reports: list[tuple[int, int, int]] = []
    session.on_progress = lambda seg, n, t: reports.append((seg, n, t))
    session.heartbeat()
    assert reports == []  # nothing matched: no report, no heartbeat
    session.matched([_index(session, "state_block")])
    session.heartbeat()
    assert reports == [] and session.ready_without == ()
    assert session.state_matched_at is not None
    session.state_matched_at -= REQUIRED_MATCH_WAIT_S
    session.heartbeat()
    assert reports == [(0, 0, 0)]
    assert session.ready_without == (resolve(NS, "band_velocity_block"),)
    session.close()


def test_first_report_waits_for_every_stream_with_a_publisher_on_the_graph(tmp_path: Path) -> None:
    """A lossless replay starts on this report: a reader that has not matched a publisher the
    graph shows would drop that publisher's first messages (/clock at 0 s, seen beside two hogs)."""
    session = _session(tmp_path, ["state_block", "/clock", "band_velocity_block"], sim=True)
    reports: list[tuple[int, int, int]] = []
    session.on_progress = lambda seg, n, t: reports.append((seg, n, t))
    state, clock, band = (_index(session, n) for n in ("state_block", "/clock", "band_velocity_block"))
    names = [s.spec.name for s in session.streams]
    one = dict.fromkeys(names, 1)
    session.graph(0, one, {state: 1, clock: 0})  # worker 0 reads state_block and /clock
    session.graph(1, one, {band: 0})
    session.matched([state])
    assert reports == [] and session.unmatched_publishers() == sorted(names[1:])
    session.graph(0, one, {state: 1, clock: 1})
    session.heartbeat()
    assert reports == []  # the band's reader still lags (another worker)
    session.graph(1, one, {band: 1})
    assert reports == [(0, 0, 0)]
    session.graph(1, one, {band: 0})  # after the first report: no second one
    assert reports == [(0, 0, 0)] and session.ready_lagging == ()
    session.close()


def test_a_reader_is_held_to_a_publisher_another_worker_has_discovered(tmp_path: Path) -> None:
    """Each worker discovers each publisher on its own: the one that reads /clock may not know the
    replay's /clock writer yet, though the one that reads state_block does (a discovery message
    lost on the way). Its own view shows nothing to wait for; the other's does."""
    session = _session(tmp_path, ["state_block", "/clock"], sim=True)
    reports: list[tuple[int, int, int]] = []
    session.on_progress = lambda seg, n, t: reports.append((seg, n, t))
    state, clock = _index(session, "state_block"), _index(session, "/clock")
    session.graph(1, {"/clock": 0, resolve(NS, "state_block"): 0}, {clock: 0})
    session.graph(0, {"/clock": 1, resolve(NS, "state_block"): 1}, {state: 1})
    session.matched([state])
    assert reports == [] and session.unmatched_publishers() == ["/clock"]
    session.graph(1, {"/clock": 1, resolve(NS, "state_block"): 1}, {clock: 1})
    assert reports == [(0, 0, 0)]
    session.close()


def test_first_report_waits_for_a_lagging_stream_only_so_long(tmp_path: Path) -> None:
    """A publisher that never matches (another type or QoS) must not hold the run: named, then reported."""
    session = _session(tmp_path, ["state_block", "/clock"], sim=True)
    reports: list[tuple[int, int, int]] = []
    session.on_progress = lambda seg, n, t: reports.append((seg, n, t))
    state, clock = _index(session, "state_block"), _index(session, "/clock")
    session.graph(0, {"/clock": 1, resolve(NS, "state_block"): 1}, {state: 1, clock: 0})
    session.matched([state])
    session.heartbeat()
    assert reports == []
    assert session.state_matched_at is not None
    session.state_matched_at -= REQUIRED_MATCH_WAIT_S
    session.heartbeat()
    assert reports == [(0, 0, 0)]
    assert session.ready_lagging == ("/clock",)
    session.close()


def test_a_lost_block_is_a_gap_named_in_the_problems_and_accounting_json(tmp_path: Path) -> None:
    session = _session(tmp_path, ["state_block"], sim=False)
    reports: list[tuple[int, int, int]] = []
    session.on_progress = lambda seg, n, t: reports.append((seg, n, t))
    k = _index(session, "state_block")
    session.handle([(k, 1, _block(0, 100)), (k, 2, _block(200, 100))])
    assert reports[-1][:2] == (0, 100)  # taken in order: the flow window does not pass the gap
    (line,) = session.problems()
    assert line.startswith(f"{resolve(NS, 'state_block')}: 100 samples missing in 1 gap(s)")
    session.close()
    data = json.loads(session.write_accounting().read_text())
    assert data["complete"] is False and data["problems"] == [line]


def test_a_malformed_message_is_counted_never_fatal(tmp_path: Path) -> None:
    session = _session(tmp_path, ["state_block", "flow_progress"], sim=False, run_config=None)
    k, p = _index(session, "state_block"), _index(session, "flow_progress")
    session.handle([(k, 1, b"\x00\x01\x00\x00garbage"), (p, 2, b"\x00\x01"), (k, 3, _block(0, 10))])
    session.close()
    assert session.malformed == {resolve(NS, "state_block"): 1, resolve(NS, "flow_progress"): 1}
    assert session.accounts[resolve(NS, "state_block")].samples == 10
    assert any("1 malformed messages" in line for line in session.problems())


def test_the_plant_s_flow_progress_announces_samples_not_yet_taken(tmp_path: Path) -> None:
    session = _session(tmp_path, ["state_block", "flow_progress"], sim=False, run_config=None)
    k, p = _index(session, "state_block"), _index(session, "flow_progress")
    announce = FlowProgress(participant=resolve(NS, "plant"), segment=0, samples=300)
    other = FlowProgress(participant=resolve(NS, "analysis"), segment=0, samples=900)
    session.handle(
        [(k, 1, _block(0, 100)), (p, 2, serialize_message(announce)), (p, 3, serialize_message(other))]
    )
    assert session.behind() == 200  # the plant's announcement counts, another participant's does not
    session.handle([(k, 4, _block(100, 200))])
    assert session.behind() == 0
    session.close()


def _band(first: int, n: int, segment: int = 0) -> bytes:
    """Band samples with indices first … first + n − 1 (band sample k = index + 1 makes state sample k)."""
    msg = BandVelocityBlock(sample_period=1e-3, first_sample_index=first, segment=segment)
    msg.header.stamp = _stamp((first + 1) * MS)
    msg.band_velocity = [0.01] * n
    return serialize_message(msg)


def _rig_session(tmp_path: Path) -> tuple[RecordingSession, list[tuple[int, int]], int, int, int]:
    """A sim rig's recorder (progress per block, band and state required), reported ready."""
    session = _session(tmp_path, ["state_block", "band_velocity_block", "flow_progress"], sim=False)
    session.required = (resolve(NS, "state_block"), resolve(NS, "band_velocity_block"))
    reports: list[tuple[int, int]] = []
    session.on_progress = lambda seg, n, t: reports.append((seg, n))
    k, b, p = (_index(session, n) for n in ("state_block", "band_velocity_block", "flow_progress"))
    session.matched([k, b])
    assert reports == [(0, 0)]
    return session, reports, k, b, p


def test_a_rig_s_recorder_reports_only_samples_it_holds_of_band_and_state(tmp_path: Path) -> None:
    """Band sample k becomes state sample k: with the band's second block lost on the way, the
    recorder reports no state sample beyond what the band it holds made, until the copy comes."""
    session, reports, k, b, _p = _rig_session(tmp_path)
    session.handle([(b, 1, _band(0, 100)), (k, 2, _block(0, 101))])
    assert reports[-1] == (0, 101)  # state samples 0 … 100: the initial state and band 0 … 99
    session.handle([(k, 3, _block(101, 100))])  # its band block (indices 100 … 199) not here
    assert reports[-1] == (0, 101)
    session.handle([(b, 4, _band(100, 100))])  # sent again after the writer's heartbeat
    assert reports[-1] == (0, 201)
    session.close()
    assert session.problems() == []


def test_a_rig_s_recorder_counts_a_band_tail_the_plant_took_and_it_lacks_as_a_gap(tmp_path: Path) -> None:
    """The plant's FlowProgress says which band samples exist: one the bag lacks at the end is a gap."""
    session, reports, k, b, p = _rig_session(tmp_path)
    announce = FlowProgress(participant=resolve(NS, "plant"), segment=0, samples=201)
    session.handle([(b, 1, _band(0, 100)), (k, 2, _block(0, 201)), (p, 3, serialize_message(announce))])
    assert reports[-1] == (0, 101)
    assert session.behind() == 100  # band indices 100 … 199
    session.close()
    (line,) = session.problems()
    assert line.startswith(f"{resolve(NS, 'band_velocity_block')}: 100 samples missing in 1 gap(s)")


def test_a_recorder_without_the_band_required_reports_state_alone(tmp_path: Path) -> None:
    """A lossless replay's recorder (nothing required): the state blocks alone, as before."""
    session = _session(tmp_path, ["state_block", "band_velocity_block"], sim=False)
    reports: list[tuple[int, int]] = []
    session.on_progress = lambda seg, n, t: reports.append((seg, n))
    session.handle([(_index(session, "state_block"), 1, _block(0, 201))])
    assert reports == [(0, 201)]
    session.close()


def test_sim_time_places_unstamped_messages_by_clock_and_holds_them_until_it_arrives(tmp_path: Path) -> None:
    session = _session(tmp_path, ["/clock", "state_block", "band_velocity"], sim=True)
    c, k, v = (_index(session, n) for n in ("/clock", "state_block", "band_velocity"))
    recv = time.time_ns()  # receive times: the system clock, far from rig time
    session.handle([(c, recv, _clock(5 * MS)), (k, recv + 1, _block(5, 10))])
    band = serialize_message(Float64(data=0.25))
    session.handle([(v, recv + 2 * MS, band)])  # after the newest /clock: may still be placed by one
    assert len(session.held) == 1
    session.handle([(c, recv + 3 * MS, _clock(7 * MS))])  # /clock of 7 ms received after it
    assert session.held == []
    session.close()
    times = _log_times(session.writer.path)
    assert times["/clock"] == [5 * MS, 7 * MS]
    assert times[resolve(NS, "state_block")] == [5 * MS]  # its header stamp, not its receive time
    assert times[resolve(NS, "band_velocity")] == [5 * MS]  # the /clock received before it
    assert times[resolve(NS, "run_config")] == [5 * MS]  # at the first log time of the run


def test_sim_time_forced_after_the_hold_and_wall_clock_stamps_placed_by_clock(tmp_path: Path) -> None:
    session = _session(tmp_path, ["/clock", "state_block", "band_velocity"], sim=True, run_config=None)
    c, k, v = (_index(session, n) for n in ("/clock", "state_block", "band_velocity"))
    now = time.time_ns()
    session.handle([(c, now - 2 * SIM_HOLD_NS, _clock(3 * MS))])
    session.handle([(v, now - SIM_HOLD_NS - MS, serialize_message(Float64(data=1.0)))])  # held too long
    assert session.held == []
    wall = WALL_CLOCK_NS + 123  # a node on the wall clock: not rig time
    session.handle([(k, now - 2 * SIM_HOLD_NS + 1, _block(0, 5, t0_ns=wall))])
    session.close()
    times = _log_times(session.writer.path)
    assert times[resolve(NS, "band_velocity")] == [3 * MS]
    assert times[resolve(NS, "state_block")] == [3 * MS]


def _log_times(bag: Path) -> dict[str, list[int]]:
    from mcap.reader import make_reader

    out: dict[str, list[int]] = {}
    (mcap_file,) = bag.glob("*.mcap")
    with mcap_file.open("rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages(log_time_order=True):
            out.setdefault(channel.topic, []).append(message.log_time)
    return out


@pytest.mark.parametrize("per_block", [True, False])
def test_heartbeat_reports_what_is_taken(tmp_path: Path, per_block: bool) -> None:
    session = _session(tmp_path, ["state_block"], sim=False, run_config=None)
    session.progress_per_block = per_block
    reports: list[tuple[int, int, int]] = []
    session.on_progress = lambda seg, n, t: reports.append((seg, n, t))
    k = _index(session, "state_block")
    session.matched([k])
    session.handle([(k, 1, _block(0, 50))])
    assert [r[:2] for r in reports] == ([(0, 0), (0, 50)] if per_block else [(0, 0)])
    session.last_progress -= 1.0  # the heartbeat interval has passed
    session.heartbeat()
    assert reports[-1][:2] == (0, 50)
    session.close()
