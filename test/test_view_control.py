"""The view's opt-in ways back to the rig, driven by Foxglove's own client against real nodes.

`view --allow-services | --allow-parameters | --allow-publish` (app/view/access.py,
nodes/view_control.py, nodes/view_parameters.py): the npm client of test/support/foxglove_client
calls the plant's pause and reset, reads and sets plant parameters (a bad value is refused with the
node's reason and left unchanged), publishes band velocity into a rig-in-the-loop plant, and sees
none of it advertised when the options are off. Assertions are on what came back and on what the
rig did (its states, its log), never on timing.
"""

from __future__ import annotations

import json
import signal
import subprocess
from collections.abc import Callable

import pytest
from lubrig_testkit.harness import wait_until
from test_view_foxglove import CLIENT_DIR, CLIENT_SLACK_S, NS, Deadline, _client_ready, _serve

pytestmark = pytest.mark.ros

PLANT = f"{NS}/plant"
PERTURBATION = f"{PLANT}.initial_perturbation"
CONTROL_CAPABILITIES = {"services", "parameters", "clientPublish"}


@pytest.fixture
def deadline() -> Deadline:
    return Deadline()


def _client(url: str, deadline: Deadline, logs: Callable[[], str], actions: list, *topics: str) -> list[dict]:
    """Run Foxglove's client with `actions` until they are done and it has TOPIC=COUNT of each."""
    _client_ready()
    seconds = deadline.left(reserve=CLIENT_SLACK_S)
    argv = ["node", str(CLIENT_DIR / "client.mjs"), url, f"{seconds:.0f}", "--actions", json.dumps(actions)]
    try:
        done = subprocess.run(
            [*argv, *topics], capture_output=True, text=True, timeout=seconds + CLIENT_SLACK_S
        )
    except subprocess.TimeoutExpired as exc:
        raise AssertionError(f"the Foxglove client did not end: {exc.stderr!r}\n{logs()}") from None
    assert done.returncode == 0, f"{done.stderr}\n{logs()}"
    lines = [json.loads(line) for line in done.stdout.splitlines() if line.strip()]
    replies = [x for x in lines if "topic" not in x and "advertise" not in x]
    assert lines and lines[-1] == {"done": True, "complete": True}, f"{replies}\n{logs()}"
    assert not [x for x in lines if "error" in x], lines
    return lines


def _capabilities(lines: list[dict]) -> set[str]:
    return set(next(x["serverInfo"]["capabilities"] for x in lines if "serverInfo" in x))


def _of(lines: list[dict], key: str) -> list[dict]:
    return [x[key] for x in lines if key in x]


def _stops_cleanly(procs) -> None:
    """Ctrl-C ends the view (its bridges with it) with status 0 and its summary."""
    view = procs["view"]
    assert view.stop(signal.SIGINT, 60) == 0, view.log()
    assert "view: stopped" in view.output()


def test_read_only_by_default_advertises_no_way_back(procs, deadline):
    """Without the options: no services, parameters or client publishing are advertised."""
    procs.node("plant", mode="realtime", max_lag=10.0)
    url = _serve(procs, deadline)
    lines = _client(url, deadline, procs.logs, [{"wait": 1500}], f"{NS}/state=1")
    assert not _capabilities(lines) & CONTROL_CAPABILITIES, _capabilities(lines)
    assert not _of(lines, "service")


def test_client_pauses_and_resets_the_rig(procs, deadline):
    """--allow-services: pause and reset reach the plant; its replies come back; a new segment runs."""
    plant = procs.node("plant", mode="realtime", max_lag=10.0)
    procs.node("belt_drive", mode="realtime")
    url = _serve(procs, deadline, "--allow-services", "--rate", "state=20")
    actions = [
        {"call": f"{PLANT}/pause", "raw": "00"},  # malformed: a failure, nothing paused
        {"call": f"{PLANT}/pause", "request": {"data": True}},
        {"wait": 500},
        {"call": f"{PLANT}/pause", "request": {"data": False}},
        {"call": f"{PLANT}/reset"},
        {"until": {"topic": f"{NS}/state", "field": "segment", "value": 1}},
    ]
    lines = _client(url, deadline, procs.logs, actions, f"{NS}/state=1")
    assert {"services"} <= _capabilities(lines)
    services = {s["name"]: s for s in _of(lines, "service")}
    assert services[f"{PLANT}/reset"]["type"] == "std_srvs/srv/Trigger"
    assert services[f"{PLANT}/pause"]["request"] == "std_srvs/srv/SetBool_Request"
    assert services[f"{PLANT}/pause"]["encoding"] == "cdr"
    replies = _of(lines, "serviceResponse")
    failures = _of(lines, "serviceFailure")
    assert len(failures) == 1 and "malformed request" in failures[0]["message"], failures
    assert [r["service"] for r in replies] == [f"{PLANT}/pause", f"{PLANT}/pause", f"{PLANT}/reset"]
    assert [r["message"] for r in replies[:2]] == [
        {"success": True, "message": "paused"},
        {"success": True, "message": "running"},
    ]
    assert replies[2]["message"]["success"] and "segment 1" in replies[2]["message"]["message"]
    assert _of(lines, "until"), "no state of the new segment reached the client"
    # the plant names the view as the caller of each (its own log)
    wait_until(lambda: f"{PLANT}/reset called by {NS}/view" in plant.errors(), deadline.left(), "caller")
    assert plant.errors().count(f"{PLANT}/pause called by {NS}/view") == 2, plant.log()
    _stops_cleanly(procs)
    assert "services: 3 calls forwarded, 1 failed" in procs["view"].output()


def test_client_sets_a_parameter_and_a_bad_value_is_refused_by_the_node(procs, deadline):
    """--allow-parameters: get and set through the plant's parameter services; its refusal comes back."""
    procs.node("plant", mode="realtime", max_lag=10.0)
    url = _serve(procs, deadline, "--allow-parameters")
    actions = [
        {"get": [PERTURBATION], "retry": True},  # until the view has found the plant
        {"set": [{"name": PERTURBATION, "value": 0.25}]},
        {"set": [{"name": PERTURBATION, "value": 5.0}]},  # outside -1..1
        {"set": [{"name": f"{PLANT}.mode", "value": "sim"}]},  # read-only
        {"set": [{"name": PERTURBATION, "value": "big"}]},  # a string for a double
        {"set": [{"name": f"{NS}/nobody.x", "value": 1}]},  # no such rig node
        {"get": [PERTURBATION]},
        {"get": []},
    ]
    lines = _client(url, deadline, procs.logs, actions)
    assert {"parameters"} <= _capabilities(lines)
    answers = [{p["name"]: p["value"] for p in a["values"]} for a in _of(lines, "parameters")]
    before = answers[0][PERTURBATION]  # the run configuration's (case 1: 0.01)
    assert isinstance(before, float) and before != 0.25, answers
    assert answers[1] == {PERTURBATION: 0.25}  # taken
    assert answers[2] == {PERTURBATION: 0.25}  # refused: unchanged
    assert answers[3] == {f"{PLANT}.mode": "realtime"}  # refused: unchanged
    assert answers[4] == {PERTURBATION: 0.25}  # refused: unchanged
    assert answers[5] == {}  # nothing of a node that is not the rig's
    assert answers[6] == {PERTURBATION: 0.25}
    statuses = [s["message"] for s in _of(lines, "status")]
    refusals = [m for m in statuses if "refused" in m]
    assert len(refusals) == 3 and "initial_perturbation = 5.0" in refusals[0], refusals
    assert PLANT in refusals[0] and "range" in refusals[0].lower(), refusals  # the node's reason
    assert "mode = 'sim'" in refusals[1] and "read-only" in refusals[1].lower(), refusals
    assert "initial_perturbation = 'big'" in refusals[2] and "type" in refusals[2].lower(), refusals
    assert any(f"{NS}/nobody.x" in m and f"{PLANT}" in m for m in statuses), statuses  # valid nodes
    every = answers[7]
    assert every[f"{PLANT}.mode"] == "realtime" and every[PERTURBATION] == 0.25
    assert all(name.startswith(f"{NS}/") for name in every)
    _stops_cleanly(procs)
    assert "parameters: 1 set, 3 refused by their node" in procs["view"].output()


def test_parameter_changes_made_elsewhere_reach_a_subscribed_client(procs, probe, deadline):
    """--allow-parameters: a change by another ROS node (here the test's probe) is pushed."""
    import threading

    procs.node("plant", mode="realtime", max_lag=10.0)
    url = _serve(procs, deadline, "--allow-parameters")
    stop = threading.Event()

    def set_elsewhere() -> None:  # again and again: one set lands after the client subscribed
        while not stop.wait(1.0):
            assert probe.set_parameter("lubrig/plant", "initial_perturbation", -0.5).successful

    worker = threading.Thread(target=set_elsewhere, daemon=True)
    worker.start()
    actions = [
        {"wait": 1000},
        {"subscribe": [PERTURBATION]},
        {"untilParameter": {"name": PERTURBATION, "value": -0.5}},
    ]
    try:
        lines = _client(url, deadline, procs.logs, actions)
    finally:
        stop.set()
        worker.join(30)
    updates = [p for update in _of(lines, "parameterUpdate") for p in update]
    assert updates and all(p == {"name": PERTURBATION, "value": -0.5} for p in updates), updates


def test_band_input_is_refused_beside_a_belt_drive(procs, deadline):
    """--allow-publish: a realtime plant (belt_drive's samples) takes no band input from a client."""
    procs.node("plant", mode="realtime", max_lag=10.0)
    url = _serve(procs, deadline, "--allow-publish")
    band = {"topic": f"{NS}/band_velocity", "schemaName": "std_msgs/msg/Float64", "encoding": "cdr"}
    lines = _client(
        url, deadline, procs.logs, [{"publish": {**band, "values": [2.5e-7] * 3}}, {"untilStatus": "refused"}]
    )
    statuses = [s["message"] for s in _of(lines, "status")]
    assert any("mode 'realtime'" in m and "rig_in_loop" in m for m in statuses), statuses
    _stops_cleanly(procs)
    assert f"{NS}/band_velocity: 0 client messages republished, 3 refused" in procs["view"].output()


def test_client_publishes_band_velocity_into_a_rig_in_the_loop(procs, deadline):
    """--allow-publish: Float64 on <ns>/band_velocity drives the plant; other topics and NaN refused."""
    procs.node("plant", mode="rig_in_loop", max_lag=10.0)
    url = _serve(procs, deadline, "--allow-publish", "--rate", "state=0")
    band = {"topic": f"{NS}/band_velocity", "schemaName": "std_msgs/msg/Float64"}
    actions = [
        {"publish": {**band, "encoding": "cdr", "values": ["NaN"]}},
        {"publish": {"topic": f"{NS}/state", "schemaName": "std_msgs/msg/Float64", "encoding": "cdr",
                     "values": [1.0]}},
        {"publish": {**band, "encoding": "cdr", "values": [2.5e-7] * 400, "periodMs": 5}},
        {"until": {"topic": f"{NS}/state", "field": "band_velocity", "value": 2.5e-7}},
        {"publish": {**band, "encoding": "json", "values": [3.5e-7] * 400, "periodMs": 5}},
        {"until": {"topic": f"{NS}/state", "field": "band_velocity", "value": 3.5e-7}},
    ]  # fmt: skip
    lines = _client(url, deadline, procs.logs, actions, f"{NS}/state=1")
    info = next(x["serverInfo"] for x in lines if "serverInfo" in x)
    assert "clientPublish" in info["capabilities"] and "cdr" in info["supportedEncodings"]
    assert len(_of(lines, "until")) == 2  # the plant integrated both values
    statuses = [s["message"] for s in _of(lines, "status")]
    assert any("nan" in m.lower() and "finite" in m for m in statuses), statuses
    assert any(f"'{NS}/state' refused" in m and f"{NS}/band_velocity" in m for m in statuses), statuses
    _stops_cleanly(procs)
    # the NaN and the refused channel's message dropped; 800 values republished
    assert f"{NS}/band_velocity: 800 client messages republished, 2 refused" in procs["view"].output()
