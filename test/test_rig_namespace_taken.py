"""Two rigs in one namespace on one ROS domain: the second is refused; band input from two sources.

Real processes: `lubrig rig` twice without --namespace on one domain (the user's mistake of the
issue), then node processes started by hand. Asserted: the second launcher exits 2 with one line
naming the first rig's nodes and starts nothing, the first finishes its run and its bag verifies
with every sample once (no second rig's samples in it); a launcher's node alone (a rig starting,
its nodes not yet on the graph) holds the namespace against `lubrig rig` and a plant started by
hand, not against a plant without a start-up check (as `lubrig rig` starts its own), and no longer
once it has left; a plant started where another plant runs refuses (exit 2, naming it); a band
publisher other than the declared source is reported (WARN on /diagnostics and in the plant's
log, naming it).
"""

from __future__ import annotations

import re
import subprocess
import sys

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from lubrig_testkit.crosscheck import read_rosbags
from lubrig_testkit.harness import run, wait_until

from lubrig_interfaces.msg import BandVelocityBlock
from lubrig_ros.app.interface import contract
from lubrig_ros.app.processes.rig_plan import LAUNCHER_NODE, NODES, RECORDER_NODE_PREFIX
from lubrig_ros.bag.verify import verify_bag
from lubrig_ros.cli.rig_ros import LauncherPresence
from lubrig_ros.core.presets import load_case
from lubrig_ros.core.run import simulate
from lubrig_ros.nodes.interfaces import qos_profile

pytestmark = pytest.mark.ros


def resolve_node(name: str) -> str:
    """The fully qualified name of a node of the default namespace."""
    return contract.resolve(contract.DEFAULT_NAMESPACE, name)


LUBRIG = [sys.executable, "-m", "lubrig_ros.cli.main"]
DURATION = 400.0  # rig s: a sim run long enough (tens of wall s) for a second launcher meanwhile


@pytest.mark.slow  # a whole recorded `lubrig rig` run beside a second launcher
def test_a_second_rig_in_the_same_namespace_is_refused(ros_env, tmp_path):
    first_dir, second_dir = tmp_path / "first", tmp_path / "second"
    first = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "lubrig_ros.cli.main",
            "rig",
            "--case",
            "1",
            "--duration",
            str(DURATION),
            "--run-dir",
            str(first_dir),
            "--no-report",
        ],
        env=ros_env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        plant_log = first_dir / "logs" / "plant.log"
        # the first rig's run is going: its plant announced itself (the recorder has subscribed)
        wait_until(
            lambda: plant_log.exists() and "flow_progress as" in plant_log.read_text(),
            180,
            "the first rig's run started",
        )
        second = subprocess.run(
            [
                sys.executable,
                "-m",
                "lubrig_ros.cli.main",
                "rig",
                "--case",
                "7",
                "--duration",
                "1",
                "--run-dir",
                str(second_dir),
            ],
            env=ros_env,
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )
        # the first rig was still running (not yet stopping) when the second one looked
        assert "run complete" not in plant_log.read_text(), "the first run ended too soon for the test"
        out, err = first.communicate(timeout=600)
    finally:
        if first.poll() is None:
            first.kill()
            first.communicate()
    assert second.returncode == 2, second.stdout + second.stderr
    lines = second.stderr.strip().splitlines()
    assert len(lines) == 1, second.stderr
    assert lines[0].startswith("lubrig rig: error: --namespace /lubrig is taken on ROS_DOMAIN_ID "), lines
    # that rig's nodes named, as many as discovery had found by then: each node process is a
    # participant discovered on its own, and beside two hogs the plant was not yet among them
    # once in a suite run (docs/testing.md); every name must be one of the first rig's nodes
    named = re.search(r"another rig runs there \(([^)]*)\)", lines[0])
    assert named, lines
    rig_nodes, recorder = (
        {resolve_node(n) for n in (*NODES, LAUNCHER_NODE)},
        resolve_node(RECORDER_NODE_PREFIX),
    )
    names = named.group(1).split(", ")
    assert names and all(n in rig_nodes or n.startswith(recorder) for n in names), names
    assert "--namespace /lubrig_2" in lines[0], lines  # what would be valid
    assert not second_dir.exists()  # refused before anything was written or started
    # while it looked, its run folder was staged beside (cli/rig_gate.py): not left behind either
    assert not list(tmp_path.glob(".lubrig-rig-starting-*"))

    assert first.returncode == 0, out + err
    result = verify_bag(first_dir / "bag")
    assert not result.structural and not result.problems, result.problems
    # every sample of the first rig once, and nothing else: the run, bit for bit
    x = np.array(read_rosbags(first_dir / "bag")["/lubrig/state_block"])
    ref = simulate(load_case(1).with_overrides(duration=DURATION))
    assert np.array_equal(x, ref.displacement)


def test_a_launchers_node_holds_the_namespace_until_it_leaves(ros_env, procs, tmp_path, monkeypatch):
    for key, value in ros_env.items():  # this process's participant on the test's domain
        monkeypatch.setenv(key, value)
    launcher = resolve_node(LAUNCHER_NODE)
    presence = LauncherPresence(contract.DEFAULT_NAMESPACE)
    try:
        assert presence.node.get_fully_qualified_name() == launcher
        # another `lubrig rig` there is refused, naming the launcher's node
        second = run(
            [*LUBRIG, "rig", "--case", "7", "--duration", "1", "--run-dir", str(tmp_path / "second")], ros_env
        )
        assert second.returncode == 2, second.stdout + second.stderr
        lines = second.stderr.strip().splitlines()
        assert len(lines) == 1 and f"another rig runs there ({launcher})" in lines[0], lines
        assert not (tmp_path / "second").exists()
        # a plant started by hand (its own 1.5 s check) refuses, naming it
        checked = procs.node("plant", case=1, mode="sim")
        assert checked.wait(timeout=120) == 2, checked.log()
        fatal = [line for line in (checked.errors() + checked.output()).splitlines() if "[FATAL]" in line]
        assert len(fatal) == 1 and f"({launcher})" in fatal[0], checked.log()
        # the launcher's own plant has no check of its own: it starts
        own = procs.node("plant", case=1, mode="sim", namespace_settle=0.0)
        wait_until(
            lambda: "flow_progress as" in own.errors(), 120, "the unchecked plant announced", alive=(own,)
        )
        assert own.stop() == 0, own.log()
    finally:
        presence.close()
    # gone from the graph: a plant's check passes again
    later = procs.node("plant", case=1, mode="sim")
    wait_until(
        lambda: "flow_progress as" in later.errors(), 120, "a plant after the launcher left", alive=(later,)
    )


def test_a_plant_where_another_plant_runs_refuses_to_start(procs):
    first = procs.node("plant", case=1, mode="sim")
    wait_until(lambda: "flow_progress as" in first.errors(), 120, "the first plant started", alive=(first,))
    second = procs.node("plant", case=1, mode="sim")
    assert second.wait(timeout=120) == 2, second.log()
    fatal = [
        line for line in second.errors().splitlines() + second.output().splitlines() if "[FATAL]" in line
    ]
    assert len(fatal) == 1, second.log()
    assert "namespace /lubrig is taken on ROS_DOMAIN_ID" in fatal[0] and "(/lubrig/plant)" in fatal[0], fatal
    assert "this plant does not start" in fatal[0], fatal
    assert first.running(), first.log()  # the plant that was there first goes on


def _band_sources(probe) -> list[DiagnosticStatus]:
    return [
        s for a in probe.messages["/diagnostics"] for s in a.status if s.name == "/lubrig/plant: band sources"
    ]


def test_a_second_band_publisher_is_warned_about_naming_it(procs, probe):
    probe.subscribe("/diagnostics", DiagnosticArray, qos_profile(contract.topic("/diagnostics").qos))
    plant = procs.node("plant", case=1, mode="sim", band_source="belt_drive")
    belt = procs.node("belt_drive", case=1, mode="sim")
    # the declared source alone: the status is ok and lists it
    wait_until(
        lambda: any(
            s.level == DiagnosticStatus.OK
            and "/lubrig/belt_drive" in dict((v.key, v.value) for v in s.values)["publishers"]
            for s in _band_sources(probe)
        ),
        60,
        "band sources ok with belt_drive",
        alive=(plant, belt),
    )
    assert "band input from" not in plant.output() + plant.errors()
    spec = contract.topic("band_velocity_block")
    probe.publisher(spec.resolved("/lubrig").name, BandVelocityBlock, qos_profile(spec.qos))
    wait_until(
        lambda: any(s.level == DiagnosticStatus.WARN for s in _band_sources(probe)),
        60,
        "band sources WARN",
        alive=(plant, belt),
    )
    warn = next(s for s in _band_sources(probe) if s.level == DiagnosticStatus.WARN)
    assert warn.message.startswith("band input from /probe besides the declared source /lubrig/belt_drive"), (
        warn.message
    )

    def warned_in_log() -> bool:
        log = plant.output() + plant.errors()
        return any("[WARN]" in line and "band input from /probe" in line for line in log.splitlines())

    wait_until(warned_in_log, 30, "the warning in the plant's log", alive=(plant,))
