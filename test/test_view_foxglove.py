"""The live view over the Foxglove WebSocket protocol, read by a client nobody here wrote.

The view (`view` node, foxglove-sdk server) runs beside real rig nodes over real DDS; the client is
made of Foxglove's own npm packages (@foxglove/ws-protocol, @foxglove/rosmsg,
@foxglove/rosmsg2-serialization; test/support/foxglove_client, installed by `make setup`). It
subscribes to the state and wavelet image channels and decodes what it gets with the schemas the
server advertised. Assertions are about content and decimation (message counts bounded by the
display rate over the rig time covered, stamps at least one display period apart), never about
wall-clock rates.

Every test runs within TEST_BUDGET_S (its waits share one deadline; each is on a condition and
fails with the processes' logs), and what it started is stopped at its end (the procs fixture;
anything left on the test's ROS domain is killed and named by conftest.py).
"""

from __future__ import annotations

import itertools
import json
import math
import re
import shutil
import signal
import subprocess
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path

import pytest

from lubrig_ros.app.plant.output import BLOCK_FIELDS

NS = "/lubrig"
CLIENT_DIR = Path(__file__).parent / "support" / "foxglove_client"
#: s a test may take in all (start-ups of a few node processes under load, then the client's wait):
#: a guard against a hang, shared by the waits of one test.
TEST_BUDGET_S = 240.0
#: s the client (node) may take to start and to end after its own wait of `seconds` ran out
CLIENT_SLACK_S = 30.0
pytestmark = pytest.mark.ros


class Deadline:
    """The waits of one test: each gets what is left of TEST_BUDGET_S."""

    def __init__(self, budget: float = TEST_BUDGET_S) -> None:
        self.end = time.monotonic() + budget

    def left(self, reserve: float = 0.0) -> float:
        """s left (less `reserve`, kept for what follows); AssertionError if none."""
        left = self.end - time.monotonic() - reserve
        assert left > 0, f"the test's budget of {TEST_BUDGET_S:g} s is spent"
        return left


@pytest.fixture
def deadline() -> Deadline:
    return Deadline()


def _client_ready() -> None:
    if shutil.which("node") is None:
        pytest.fail("node (Node.js) is not installed: the Foxglove client of this test runs on it")
    if not (CLIENT_DIR / "node_modules" / "@foxglove" / "ws-protocol").is_dir():
        pytest.fail(f"the Foxglove client is not installed in {CLIENT_DIR}: run `make setup`")


def _serve(procs, deadline: Deadline, *args: str) -> str:
    """Start the view on a free port; its ws:// URL."""
    view = procs.script("view", "--port", "0", *args)
    # imports are slow under load; the client's wait keeps a minute of the budget
    view.wait_for_output("view: serving", deadline.left(reserve=60))
    match = re.search(r"ws://[0-9.]+:(\d+)", view.output())
    assert match, view.log()
    return match.group(0)


def _listen(
    url: str, deadline: Deadline, logs: Callable[[], str], *topics: str
) -> tuple[list[dict], list[dict]]:
    """Run Foxglove's client until it has TOPIC=COUNT messages of each topic (for what is left of
    the test's budget at most): (advertised channels, decoded messages). `logs`: the node
    processes' logs, shown when the client did not get them."""
    _client_ready()
    seconds = deadline.left(reserve=CLIENT_SLACK_S)
    argv = ["node", str(CLIENT_DIR / "client.mjs"), url, f"{seconds:.0f}", *topics]
    try:  # the client ends itself after `seconds`; the slack covers its start-up and exit
        done = subprocess.run(argv, capture_output=True, text=True, timeout=seconds + CLIENT_SLACK_S)
    except subprocess.TimeoutExpired as exc:  # run() has killed it
        raise AssertionError(f"the Foxglove client did not end: {exc.stderr!r}\n{logs()}") from None
    assert done.returncode == 0, f"{done.stderr}\n{logs()}"
    lines = [json.loads(line) for line in done.stdout.splitlines() if line.strip()]
    counts = Counter(x["topic"] for x in lines if "topic" in x)
    channels = [x["advertise"]["topic"] for x in lines if "advertise" in x]
    complete = lines and lines[-1] == {"done": True, "complete": True}
    assert complete, f"wanted {topics}, got {dict(counts)} on {channels}: {done.stderr}\n{logs()}"
    errors = [x for x in lines if "error" in x]
    assert not errors, errors
    advertised = [x["advertise"] for x in lines if "advertise" in x]
    messages = [x for x in lines if "topic" in x]
    return advertised, messages


def _numbers(value) -> list[float]:
    """Every number in a decoded message (nested)."""
    if isinstance(value, bool):
        return []
    if isinstance(value, int | float):
        return [float(value)]
    if isinstance(value, list):
        return [x for v in value for x in _numbers(v)]
    if isinstance(value, dict):
        return [x for v in value.values() for x in _numbers(v)]
    return []


def _stamp_ns(message: dict) -> int:
    stamp = message["header"]["stamp"]
    return int(stamp["sec"]) * 1_000_000_000 + int(stamp["nanosec"])


def _assert_shown_samples(states: list[dict], rate: float) -> None:
    """Samples of a block topic: the rate rule's samples and, between two of them, extremes only.

    The rate rule's samples are >= 1/rate apart, and every other sample shown lies between two of
    them (before the next is due), so they are found again greedily; each sample in between holds
    a value outside the range of the two around it, in some field of EXTREME_FIELDS, and there
    are at most two per field in each interval (app/view/display.py, Envelope).
    """
    from lubrig_ros.app.view.display import EXTREME_FIELDS

    period = round(1e9 / rate)
    anchors: list[int] = []
    for k, s in enumerate(states):
        if not anchors or _stamp_ns(s) >= _stamp_ns(states[anchors[-1]]) + period:
            anchors.append(k)
    _assert_decimated([_stamp_ns(states[k]) for k in anchors], rate)
    for a, b in itertools.pairwise(anchors):
        between = states[a + 1 : b]
        assert len(between) <= 2 * len(EXTREME_FIELDS)
        for s in between:
            assert any(
                not min(states[a][f], states[b][f]) <= s[f] <= max(states[a][f], states[b][f])
                for f in EXTREME_FIELDS
            ), (states[a], s, states[b])


def _assert_decimated(stamps: list[int], rate: float) -> None:
    """Consecutive stamps >= 1/rate apart, so count <= span * rate + 1."""
    period = round(1e9 / rate)
    gaps = [b - a for a, b in itertools.pairwise(stamps)]
    assert all(g >= period for g in gaps), [g for g in gaps if g < period][:5]
    assert len(stamps) <= (stamps[-1] - stamps[0]) / period + 1


def test_realtime_rig_state_and_wavelet_image_in_foxglove_client(procs, deadline):
    """Realtime rig (1 kHz states) with the view at 20 Hz for state: decoded, finite, decimated."""
    procs.node("plant", mode="realtime", max_lag=10.0)  # about the view, not about timing
    procs.node("belt_drive", mode="realtime")
    procs.node("analysis", window=256, n_scales=16, image_width=64, publish_period=0.2)
    url = _serve(procs, deadline, "--rate", "state=20")
    state, image = f"{NS}/state", f"{NS}/wavelet_image"
    advertised, messages = _listen(url, deadline, procs.logs, f"{state}=40", f"{image}=2")
    channels = {c["topic"]: c for c in advertised}
    # every channel: ROS 2 CDR with its ros2msg definition, as Foxglove decodes natively
    assert state in channels and image in channels, sorted(channels)
    assert {(c["encoding"], c["schemaEncoding"]) for c in advertised} == {("cdr", "ros2msg")}
    assert channels[image]["schemaName"] == "sensor_msgs/msg/Image"
    states = [m for m in messages if m["topic"] == state]
    images = [m for m in messages if m["topic"] == image]
    assert len(states) >= 40 and len(images) >= 2
    assert not any(m["trailingBytes"] for m in messages), "schema and payload disagree"
    for m in states:
        values = _numbers(m["message"])
        assert values and all(math.isfinite(v) for v in values), m
    stamps = [_stamp_ns(m["message"]) for m in states]
    _assert_shown_samples([m["message"] for m in states], 20.0)
    # the plant publishes one state per 1 ms of rig time: the view showed a small share of them
    assert len(states) <= (stamps[-1] - stamps[0]) / 1e6 / 40
    # log time is the rig time of the message
    assert all(int(m["logTime"]) == s for m, s in zip(states, stamps, strict=True))
    for m in images:
        img = m["message"]
        assert img["encoding"] == "rgb8" and img["width"] == 64 and img["height"] == 16
        assert img["data"]["bytes"] == img["height"] * img["step"] > 0


def _ramp_block(k: int, n: int = 100, spikes: frozenset[int] = frozenset()):
    """Block k of n samples 1 ms apart with known values; velocity 1e-3 m/s at the spike indices."""
    from lubrig_interfaces.msg import RigStateBlock

    msg = RigStateBlock()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(k * n * 1_000_000, 1_000_000_000)
    msg.sample_period = 1e-3
    msg.first_sample_index = k * n
    msg.segment = 0
    index = [k * n + i for i in range(n)]
    for name in BLOCK_FIELDS:  # every sample field, then the ones the view test reads
        setattr(msg, name, [0.0] * n)
    msg.displacement = [1e-9 * i for i in index]
    msg.velocity = [1e-3 if i in spikes else 2e-9 * i for i in index]
    msg.friction_coefficient = [0.1] * n
    msg.friction_force = [1.0] * n
    msg.band_velocity = [1e-7] * n
    msg.relative_velocity = [1e-7 - 2e-9 * i for i in index]
    msg.belt_travel = [1e-10 * i for i in index]
    return msg


def _serve_blocks(
    procs, probe, deadline: Deadline, rate: str, expect: str, spikes: frozenset[int] = frozenset()
):
    """Blocks published here (five times faster than real time) while the client listens."""
    import threading

    from rclpy.qos import QoSProfile, ReliabilityPolicy

    from lubrig_interfaces.msg import RigStateBlock

    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    pub = probe.publisher(f"{NS}/state_block", RigStateBlock, qos)
    url = _serve(procs, deadline, "--rate", rate)
    stop = threading.Event()

    def publish() -> None:
        k = 0
        while not stop.is_set():
            if pub.get_subscription_count() > 0:
                pub.publish(_ramp_block(k, spikes=spikes))
                k += 1
            time.sleep(0.02)  # 0.1 s of rig time per 20 ms

    worker = threading.Thread(target=publish, daemon=True)
    worker.start()
    try:
        return _listen(url, deadline, procs.logs, expect)
    finally:
        stop.set()
        worker.join(5)


def test_state_blocks_shown_as_decimated_rig_states(procs, probe, deadline):
    """RigStateBlock on <ns>/state_block (sim mode's plant output) arrives as RigState samples.

    The blocks come from a publisher in this test with known values, so every sample the client
    decodes is checked against the block it came from; rate 100 Hz over 1 kHz samples. The
    values rise monotonically: the view adds no extremes, so the samples are 10 ms apart.
    """
    advertised, messages = _serve_blocks(procs, probe, deadline, "state=100", f"{NS}/state=30")
    channels = {c["topic"]: c for c in advertised}
    assert channels[f"{NS}/state"]["schemaName"] == "lubrig_interfaces/msg/RigState"
    assert f"{NS}/state_block" not in channels  # shown as its samples only
    states = [m["message"] for m in messages if m["topic"] == f"{NS}/state"]
    assert len(states) >= 30
    for s in states:
        i = s["sample_index"]
        assert _stamp_ns(s) == i * 1_000_000
        assert s["displacement"] == pytest.approx(1e-9 * i, rel=1e-12)
        assert s["velocity"] == pytest.approx(2e-9 * i, rel=1e-12)
        assert s["relative_velocity"] == pytest.approx(1e-7 - 2e-9 * i, rel=1e-9)
        assert s["belt_travel"] == pytest.approx(1e-10 * i, rel=1e-12)
        assert s["segment"] == 0 and s["friction_coefficient"] == 0.1
    _assert_decimated([_stamp_ns(s) for s in states], 100.0)


def test_a_one_sample_slip_spike_survives_decimation(procs, probe, deadline):
    """A velocity spike of one sample between two displayed samples reaches the Foxglove client."""
    spikes = frozenset(range(1037, 100_000, 250))  # sample 37 of every 250: never on the 20 Hz grid
    _advertised, messages = _serve_blocks(procs, probe, deadline, "state=20", f"{NS}/state=60", spikes)
    states = [m["message"] for m in messages if m["topic"] == f"{NS}/state"]
    indices = [s["sample_index"] for s in states]
    assert indices == sorted(indices) and len(states) >= 60
    shown = [i for i in indices if i in spikes]
    assert shown and len(shown) == len(set(shown))  # spikes shown, each once
    # every display interval (between consecutive samples shown that are no spike) that holds a
    # spike shows one: two in one interval (the wall-clock ceiling can stretch it) show one
    plain = [i for i in indices if i not in spikes]
    for a, b in itertools.pairwise(plain):
        if any(a < k < b for k in spikes):
            assert any(a < k < b for k in shown), (a, b)
    for s in states:
        if s["sample_index"] in spikes:
            assert s["velocity"] == 1e-3 and s["displacement"] == pytest.approx(1e-9 * s["sample_index"])
    _assert_shown_samples(states, 20.0)


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_lubrig_rig_view_serves_a_realtime_run(procs, tmp_path, deadline):
    """`lubrig rig --view PORT --view-allow services`: the launcher starts the view with the nodes
    (services opened); the client gets states.

    The run is long (900 s) so that slow start-ups under load cannot end it first; the test stops it
    with Ctrl-C once the client has its messages (and the procs fixture at its end otherwise).
    """
    port = _free_port()
    rig = procs.script(
        "lubrig",
        "rig",
        "--case",
        "1",
        "--mode",
        "realtime",
        "--max-lag",
        "10",  # about the view, not about timing
        "--duration",
        "900",
        "--bag",
        str(tmp_path / "run"),
        "--no-recorder",
        "--no-report",
        "--view",
        str(port),
        "--view-allow",
        "services",
    )
    view_log = tmp_path / "run" / "logs" / "view.log"
    logs = lambda: f"{rig.log()}\n--- view.log:\n{view_log.read_text() if view_log.exists() else ''}"  # noqa: E731
    # the launcher says so once the view has printed its serving line
    rig.wait_for_output("live view on", deadline.left(reserve=60))
    assert "view: serving" in view_log.read_text(), logs()
    _channels, messages = _listen(f"ws://127.0.0.1:{port}", deadline, logs, f"{NS}/state=20")
    states = [m["message"] for m in messages if m["topic"] == f"{NS}/state"]
    assert len(states) >= 20
    assert all(math.isfinite(v) for s in states for v in _numbers(s))
    _assert_shown_samples(states, 50.0)  # the view's default for state
    assert "view: clients may act on the rig: services (" in view_log.read_text(), logs()
    # Ctrl-C: the launcher stops the nodes and the view (its own escalation is bounded), and exits
    # 130 (interrupted, as a shell says)
    assert rig.stop(signal.SIGINT, 60) == 130, logs()
    assert "interrupted, stopping the nodes" in rig.errors()
    assert "view: stopped" in view_log.read_text()
