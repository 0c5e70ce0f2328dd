"""The launcher resolves a run once and hands every node the file (ROS-free part)."""

from __future__ import annotations

import argparse

import pytest

from lubrig_ros.cli.main import CommandError
from lubrig_ros.cli.rig import resolve_run, select_config, write_run_config
from lubrig_ros.core.params import ParameterError
from lubrig_ros.core.presets import config_dir, default_config, load_case, load_config
from lubrig_ros.core.run import simulate


def test_case_with_overrides_round_trips_through_the_file(tmp_path):
    config = resolve_run(case=3, duration=0.5, convention="physical")
    assert config.name == "case03" and config.duration == 0.5 and config.rig.convention == "physical"
    assert load_case(3).rig.convention == "paper"  # the override did something
    path = write_run_config(config, tmp_path)
    assert path == (tmp_path / "run_config.yaml").resolve()
    assert load_config(path) == config  # what a node reads from config_file is the run
    # and integrates to the same trajectory, bit for bit
    a, b = simulate(load_config(path)), simulate(config)
    assert (a.displacement == b.displacement).all() and (a.velocity == b.velocity).all()


def test_file_and_default_selection(tmp_path):
    source = config_dir() / "stickslip.yaml"
    assert resolve_run(config_file=source) == load_config(source)
    assert resolve_run() == default_config()
    assert load_config(write_run_config(resolve_run(), tmp_path)) == default_config()


def test_bad_selection_names_the_value():
    with pytest.raises(ParameterError, match="case=11"):
        resolve_run(case=11)
    args = argparse.Namespace(case=None, config="/no/such.yaml", duration=None, convention=None)
    with pytest.raises(CommandError, match=r"no/such\.yaml"):
        select_config(args)
