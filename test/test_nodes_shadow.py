"""Shadow mode end to end: a synthetic real rig drives a rig_in_loop plant, the recorder records.

The "real rig" (lubrig_testkit.shadow_rig, a process of its own) is the independent reference
integrator (scipy LSODA) with parameters of the test's choosing; it sends its band ahead in
blocks and each measured displacement after the plant has taken that band value. The plant pairs
them by number (app/plant/session.py, "Shadow"), so nothing here depends on timing: the expected
residual of every pair is computed independently — the rig's measured value minus the reference
integrator run with the plant's parameters over the band sequence the plant recorded it
integrated — and the recorded one must equal it to the integrators' tolerance:

* TOLERANCE = 1e-8 of the rig's displacement range: the project's Radau IIA (rtol 1e-11, the
  default) and LSODA (rtol 1e-12) agree to 9e-11 of the range over these 3 s of case 4 from
  equilibrium (measured: 8.5e-19 m of a 9.1e-9 m range), so the bound leaves a factor 100.

With the plant's own parameters the residual is zero to that bound; with the rig's ζ, f0 and G
of test_fit (0.012, 10.3 Hz, 4.1e6 Pa) it is up to about 2e-9 m, and matches the expected one in
sign and size. That bag, with 1 % measurement noise, is then fitted by `lubrig fit BAG`, which
must recover the rig's parameters within test_fit's tolerances (2 standard errors and 5 %).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from lubrig_testkit.cli import lubrig
from lubrig_testkit.harness import Processes
from lubrig_testkit.reference_rig import ReferenceRig, reference_state

from lubrig_interfaces.msg import ShadowBlock, StabilityFlags, WaveletFrame
from lubrig_ros.app.interface.contract import DEFAULT_NAMESPACE, resolve
from lubrig_ros.bag.reader import read_arrays
from lubrig_ros.cli.rig import recorder_command
from lubrig_ros.core.presets import load_case

pytestmark = [pytest.mark.ros, pytest.mark.slow]

SAMPLES = 3000  # band values of the rig (3 s at 1 kHz)
TOLERANCE = 1e-8  # of the displacement range (module docstring)
TRUTH = {"damping_ratio": 0.012, "natural_frequency": 10.3, "shear_modulus": 4.1e6}
SHADOW = resolve(DEFAULT_NAMESPACE, "shadow_block")
STATE = resolve(DEFAULT_NAMESPACE, "state_block")


def _shadow_run(
    procs: Processes, tmp: Path, truth: dict[str, float], noise: float, probe, analysed: bool = False
) -> dict:
    """A recorded rig_in_loop run with shadow, driven by the synthetic rig; what the test needs.

    The probe takes the shadow blocks as the recorder does: the plant is stopped once every pair
    has been published (their count, not a wait of some seconds, says when).
    """
    config = load_case(4).with_overrides(duration=SAMPLES / 1000, initial_perturbation=0.0)
    run_yaml = tmp / "run.yaml"
    run_yaml.write_text(config.to_yaml())
    bag = tmp / "bag"
    # before the recorder and the plant: on the graph by the plant's start, so its wait (every
    # discovered subscription matched, nodes/graph.delivers_to) covers the probe's too
    probe.subscribe(SHADOW, ShadowBlock)
    recorder = procs.command("recorder", recorder_command(bag, run_yaml, "rig_in_loop"))
    recorder.wait_for_output("recording", timeout=90)
    # max_lag far beyond any stall of a loaded machine: the loop catches up, never skips
    plant = procs.node(
        "plant",
        mode="rig_in_loop",
        shadow=True,
        config_file=str(run_yaml),
        max_lag=10.0,
        wait_for_subscriber="lubrig_recorder",
        state_per_sample=False,
    )
    measured_topics = [resolve(DEFAULT_NAMESPACE, f"measured/{n}") for n in ("stability", "wavelet_frame")]
    if analysed:
        procs.node("analysis", config_file=str(run_yaml), publish_period=0.1, window=1024)
        probe.subscribe(measured_topics[0], StabilityFlags)
        probe.subscribe(measured_topics[1], WaveletFrame)
    record = tmp / "rig.npz"
    args = ["--config", str(run_yaml), "--samples", str(SAMPLES), "--out", str(record)]
    args += ["--truth", json.dumps(truth), "--noise", str(noise), "--wait-for-subscriber", "lubrig_recorder"]
    rig = procs.run_module("lubrig_testkit.shadow_rig", *args, timeout=300)
    assert rig.returncode == 0, rig.stdout + rig.stderr + procs.logs()
    assert json.loads(rig.stdout.strip().splitlines()[-1])["measured"] == SAMPLES
    if analysed:  # the measured signal analysed beside the model's
        for topic in measured_topics:
            assert probe.wait_for(lambda t=topic: len(probe.messages[t]) >= 2, 60), procs.logs()
    # the last pairs go out with the next state block: wait for every one, then stop
    published = lambda: sum(len(m.sample_index) for m in probe.messages[SHADOW])  # noqa: E731
    if not probe.wait_for(lambda: published() >= SAMPLES, 120):
        pytest.fail(f"{published()} of {SAMPLES} pairs published\n{rig.stdout}\n{plant.log()}")
    assert plant.stop() == 0, plant.log()
    assert recorder.stop() == 0, recorder.log()
    arrays = read_arrays(bag, [SHADOW, STATE])
    return {"rig": dict(np.load(record)), "shadow": arrays[SHADOW], "state": arrays[STATE], "config": config}


def _pairs(run: dict) -> dict[str, np.ndarray]:
    """The recorded pairs in number order, with what the test computes for each."""
    shadow, state, config = run["shadow"], run["state"], run["config"]
    index = np.asarray(shadow["sample_index"], np.int64)
    assert np.all(np.asarray(shadow["segment"]) == 0)
    order = np.argsort(index, kind="stable")
    index = index[order]
    # every band value paired once, in order: pair i is band value (number) i
    assert index.size == SAMPLES and np.all(np.diff(index) == 1), (index.size, index[:5], index[-5:])
    rig = run["rig"]
    pick = lambda name: np.asarray(shadow[name], float)[order]  # noqa: E731
    np.testing.assert_array_equal(pick("measured_displacement"), rig["measured"])
    # the plant's samples: its recorded band is the rig's, value i at sample index[i]
    state_index = np.asarray(state["sample_index"], np.int64)
    assert np.array_equal(state_index, np.arange(state_index.size)), "state stream with a gap"
    band = np.asarray(state["band_velocity"], float)
    np.testing.assert_array_equal(band[index], rig["band"])
    np.testing.assert_array_equal(pick("simulated_displacement"), np.asarray(state["displacement"])[index])
    # independent: the reference integrator with the plant's parameters over the plant's band
    # history (held values before the rig started included), from the plant's equilibrium
    plant_rig = ReferenceRig()  # case 4's rig and friction law: the study's values
    assert config.rig.natural_frequency == plant_rig.natural_frequency
    gamma = 1.0 / plant_rig.omega0  # case 4: paper convention
    last = int(index[-1]) + 1
    t = np.arange(last) / 1000.0
    x0 = plant_rig.mu(float(band[0])) * plant_rig.normal_force / plant_rig.stiffness
    x_plant, _ = reference_state(t, band[:last], x0, gamma, plant_rig)
    return {
        "residual": pick("residual"),
        "rms": pick("residual_rms"),
        "expected": rig["measured"] - x_plant[index],
        "range": np.ptp(rig["x"]),
    }


def test_shadow_residual_is_zero_with_the_plant_s_own_parameters(procs, probe, tmp_path: Path) -> None:
    pairs = _pairs(_shadow_run(procs, tmp_path, {}, noise=0.0, probe=probe, analysed=True))
    bound = TOLERANCE * pairs["range"]
    np.testing.assert_allclose(pairs["residual"], pairs["expected"], rtol=0, atol=bound)
    assert np.max(np.abs(pairs["residual"])) <= bound
    assert pairs["rms"][-1] <= bound


def test_shadow_residual_of_another_rig_and_its_bag_fitted(procs, probe, tmp_path: Path) -> None:
    run = _shadow_run(procs, tmp_path, TRUTH, noise=0.01, probe=probe)
    pairs = _pairs(run)
    bound = TOLERANCE * pairs["range"]
    residual, expected = pairs["residual"], pairs["expected"]
    np.testing.assert_allclose(residual, expected, rtol=0, atol=bound)
    model_part = expected - (run["rig"]["measured"] - run["rig"]["x"])  # the noise taken out
    assert np.max(np.abs(model_part)) > 1000 * bound  # the rigs differ: a residual far from zero
    big = np.abs(expected) > 10 * bound
    assert np.array_equal(np.sign(residual[big]), np.sign(expected[big]))
    assert pairs["rms"][-1] == pytest.approx(np.sqrt(np.mean(expected**2)), rel=1e-6)
    # the same bag, fitted end to end
    bag = tmp_path / "bag"
    out = tmp_path / "fit"
    res = lubrig("fit", str(bag), "--case", "4", "--free", *TRUTH, "--out", str(out))
    assert res.returncode == 0, res.stdout + res.stderr
    document = json.loads((out / "fit.json").read_text())
    assert document["data"]["samples"] == SAMPLES
    assert "shadow" in document["data"]["source"]
    assert document["undetermined"] == {}
    for name, true in TRUTH.items():
        estimate = document["estimates"][name]
        value, error = estimate["value"], estimate["standard_error"]
        assert abs(value - true) <= 0.05 * abs(true), (name, value, true)
        assert abs(value - true) <= 2.0 * error, (name, value, true, error)
