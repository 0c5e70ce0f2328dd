"""The plant's exit_when_complete (what launch/rig.launch.py sets): the node ends by itself, status 0.

Sim: once the run is complete (run_complete true), with every sample of the run delivered to a
reader first. Realtime: once the sample at `duration` is published, the duration counted from
its first sample. Nothing here asserts a wall-clock rate beyond that the realtime node ends at
all and not before its duration of samples (bench/bench_realtime.py measures timing).
"""

from __future__ import annotations

from std_msgs.msg import Bool

from lubrig_ros.app.interface import contract
from lubrig_ros.nodes import common

NS = "/lubrig"


def _samples(blocks: list) -> list[int]:
    return [b.first_sample_index + i for b in blocks for i in range(len(b.displacement))]


def test_sim_plant_ends_when_its_run_is_complete(procs, probe):
    duration = 1.0
    probe.subscribe(f"{NS}/run_complete", Bool, common.LATCHED_QOS)
    me = probe.consume_blocks(NS)
    plant = procs.node(
        "plant", case=1, duration=duration, exit_when_complete=True, wait_for_subscriber="probe"
    )
    belt = procs.node("belt_drive", case=1, duration=duration, required_consumers=f"['{me}']")
    assert plant.wait(timeout=120) == 0, procs.logs()
    assert "run complete: the node ends (exit_when_complete)" in plant.errors() + plant.output()
    n = round(duration * 1000)
    # the plant waited for its readers' acknowledgements: every sample 0..N arrived before it ended
    assert probe.wait_for(lambda: len(_samples(probe.messages[f"{NS}/state_block"])) >= n + 1, 10)
    assert _samples(probe.messages[f"{NS}/state_block"]) == list(range(n + 1))
    assert any(m.data for m in probe.messages[f"{NS}/run_complete"])
    assert belt.running()  # the plant alone ends; a launcher stops the rest (rig.launch.py: Shutdown)
    assert belt.stop() == 0, belt.log()


def test_realtime_plant_ends_after_its_duration_of_samples(procs, probe):
    duration = 1.0
    me = probe.consume_blocks(NS)
    assert me == "/probe"
    # no band source: the plant holds its initial band value (held_samples); normal scheduling
    plant = procs.node(
        "plant",
        mode="realtime",
        case=1,
        duration=duration,
        exit_when_complete=True,
        realtime_priority=0,
        wait_for_subscriber="probe",
    )
    status = plant.wait(timeout=60)
    # 0, or 3 on a machine too loaded to hold real time (then it says so): either way it ended
    assert status in (0, contract.EXIT_REAL_TIME_NOT_HELD), plant.log()
    log = plant.errors() + plant.output()
    assert "realtime: sample 1000 published (1 s): the node ends (exit_when_complete)" in log, log
    blocks = probe.messages[f"{NS}/state_block"]
    assert probe.wait_for(lambda: _samples(blocks) and _samples(blocks)[-1] >= 1000, 10), plant.log()
    if status == 0:  # held real time: no gap, and nothing after the block of sample N
        taken = _samples(blocks)
        assert taken == list(range(len(taken))), (taken[:3], len(taken), plant.log())
        assert taken[-1] < 1000 + 20, (taken[-1], plant.log())  # output_block_length
