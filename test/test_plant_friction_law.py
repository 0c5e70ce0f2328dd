"""The plant's friction parameters derive from the run's friction law (core.friction_laws).

A run configuration with `friction: {law: stribeck, ...}` gets the Stribeck law's fields as
`friction.<field>` parameters; through the plant session (no DDS) it equals core.run.simulate
bit for bit; parameter updates are checked by the law's own validation; `friction.law` selects
another law with its own defaults.
"""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import pytest

from lubrig_ros.app.interface import contract
from lubrig_ros.app.plant.session import (
    PlantSession,
    PlantSettings,
    config_from,
    config_parameters,
    law_of,
    parameter_defaults,
    runtime_parameters,
)
from lubrig_ros.core.params import ParameterError
from lubrig_ros.core.presets import default_config, from_mapping
from lubrig_ros.core.run import band_samples, simulate
from lubrig_ros.core.stribeck import StribeckParameters

STRIBECK = {
    "rig": {"damping_ratio": 0.05, "friction": {"law": "stribeck", "viscous_coefficient": 2000.0}},
    "band": {"kind": "constant", "velocity": 1.0e-6},
    "simulation": {"duration": 0.3},
}
STRIBECK_FIELDS = [f.name for f in fields(StribeckParameters) if f.name != "normal_force"]


@pytest.fixture(scope="module")
def stribeck():
    return from_mapping(STRIBECK)


def test_plant_parameters_are_the_laws_fields():
    names = [p.name for p in contract.plant_parameters("stribeck")]
    assert [n for n in names if n.startswith("friction.")] == [
        "friction.law",
        *(f"friction.{n}" for n in STRIBECK_FIELDS),
    ]
    assert "friction.shear_modulus" not in names
    assert contract.parameter("plant", "friction.shear_modulus")  # the default law's
    units = {p.name: p.unit for p in contract.plant_parameters("stribeck")}
    assert units["friction.stribeck_velocity"] == "m/s" and units["friction.viscous_coefficient"] == "s/m"
    assert {f"friction.{n}" for n in STRIBECK_FIELDS} <= runtime_parameters("stribeck")
    assert "friction.law" in config_parameters("stribeck")
    assert "friction.law" not in runtime_parameters("stribeck")  # fixed at start
    with pytest.raises(ParameterError, match=r"friction law='coulomb' is not valid; expected one of"):
        contract.plant_parameters("coulomb")


def test_stribeck_defaults_rebuild_the_configuration(stribeck):
    assert law_of(stribeck) == "stribeck"
    defaults = parameter_defaults(stribeck)
    assert set(defaults) == set(config_parameters("stribeck"))
    assert defaults["friction.law"] == "stribeck"
    assert defaults["friction.viscous_coefficient"] == 2000.0
    assert defaults["rig.normal_force"] == stribeck.rig.normal_force
    assert config_from(stribeck, defaults) == stribeck
    changed = config_from(stribeck, {"friction.static_coefficient": 0.2})
    assert changed.rig.friction == StribeckParameters(static_coefficient=0.2, viscous_coefficient=2000.0)


def test_stribeck_run_through_the_plant_session_equals_core_simulate(stribeck):
    samples = []
    session = PlantSession(
        stribeck,
        PlantSettings("sim"),
        config=config_from(stribeck, parameter_defaults(stribeck)),
        on_sample=samples.append,
    )
    for value in band_samples(stribeck, 0, stribeck.samples):
        session.band_input(float(value))
    ref = simulate(stribeck)
    assert session.complete and len(samples) == stribeck.samples + 1
    assert np.array_equal([s.displacement for s in samples], ref.displacement)
    assert np.array_equal([s.velocity for s in samples], ref.velocity)
    assert np.array_equal([s.friction_coefficient for s in samples], ref.friction_coefficient)
    # and not the junction law's run (the law really is Stribeck)
    junction = simulate(from_mapping({**STRIBECK, "rig": {"damping_ratio": 0.05}}))
    assert not np.array_equal(junction.friction_coefficient, ref.friction_coefficient)


def test_updates_are_checked_by_the_laws_own_validation(stribeck):
    session = PlantSession(stribeck, PlantSettings("sim"))
    current = parameter_defaults(stribeck)
    assert session.check_update(current, {"friction.stribeck_exponent": 2.0}) is None
    reason = session.check_update(current, {"friction.stribeck_exponent": 11.0})
    assert reason is not None and "stribeck_exponent=11.0" in reason and "(0, 10]" in reason
    # a junction-law field is not a parameter of this plant: not configuration, ignored
    assert session.check_update(current, {"friction.shear_modulus": -1.0}) is None


def test_friction_law_selects_another_law_with_its_defaults():
    base = default_config()  # junction kinetics
    config = config_from(base, {"friction.law": "stribeck"})
    assert config.rig.friction == StribeckParameters(normal_force=base.rig.normal_force)
    assert parameter_defaults(base, "stribeck")["friction.static_coefficient"] == 0.16
    back = config_from(config, {"friction.law": "junction_kinetics"})
    assert law_of(back) == "junction_kinetics"


def test_plant_node_runs_a_stribeck_configuration(tmp_path, stribeck, procs, probe):
    """A real plant + belt_drive (separate processes, DDS) with a Stribeck YAML equals simulate."""
    from std_msgs.msg import Bool

    from lubrig_ros.nodes import common

    config_file = tmp_path / "stribeck.yaml"
    config_file.write_text(stribeck.to_yaml())
    ns = common.DEFAULT_NAMESPACE
    probe.subscribe(f"{ns}/run_complete", Bool, common.LATCHED_QOS)
    me = probe.consume_blocks(ns)  # a required consumer: belt_drive paces on it too
    procs.node("plant", config_file=config_file, wait_for_subscriber="probe")
    procs.node("belt_drive", config_file=config_file, required_consumers=f"['{me}']")
    done = probe.wait_for(lambda: any(m.data for m in probe.messages[f"{ns}/run_complete"]), 60)
    assert done, procs.log("plant") + procs.log("belt_drive")
    n = stribeck.samples + 1
    blocks = probe.messages[f"{ns}/state_block"]
    assert probe.wait_for(lambda: sum(len(b.displacement) for b in blocks) >= n, 5)
    codes = procs.stop_all()
    assert "friction law stribeck" in procs.log("plant")
    x = np.concatenate([b.displacement for b in blocks])
    assert np.array_equal(x, simulate(stribeck).displacement)  # bit-identical, sample for sample
    assert all(code == 0 for code in codes.values()), (codes, procs.logs())
