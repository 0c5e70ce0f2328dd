"""Band profiles and YAML presets: shapes, validation, round trips, the Table 1 cases."""

import numpy as np
import pytest

from lubrig_ros.core.params import ParameterError, RigParameters
from lubrig_ros.core.presets import default_config, from_mapping, load_case, load_config
from lubrig_ros.core.profiles import (
    ConstantBand,
    RegularCycle,
    SinusoidalBand,
    TableBand,
    profile_from_dict,
    profile_to_dict,
)

TABLE1 = {
    1: (1e-7, 2e-7, 0.01, 0.2, 4.76),
    2: (1e-7, 2e-7, 0.1, 0.2, 3.33),
    3: (1e-7, 2e-7, 1, 0.2, 0.83),
    4: (1e-7, 10e-7, 0.01, 0.2, 4.76),
    5: (1e-7, 10e-7, 0.1, 0.2, 3.33),
    6: (1e-7, 10e-7, 1, 0.2, 0.83),
    7: (1e-7, 10e-7, 0.08, 0.02, 10),
    8: (1e-7, 10e-7, 0.04, 0.01, 20),
    9: (1e-7, 2e-7, 0.01, 0.02, 33.3),
    10: (1e-7, 10e-7, 0.01, 0.02, 33.3),
}


def test_cycle_shape_follows_the_study():
    band = RegularCycle(1e-7, 2e-7, plateau_time=0.1, ramp_time=0.2)
    t = np.array([0.0, 0.05, 0.1, 0.12, 0.15, 0.2, 0.25, 0.29, 0.3, 0.3 + 0.05])
    v = band(t)
    expected = [1e-7, 1.5e-7, 2e-7, 2e-7, 2e-7, 1.5e-7, 1e-7, 1e-7, 1e-7, 1.5e-7]
    assert np.allclose(v, expected, rtol=1e-12)
    assert band.fundamental_hz == pytest.approx(1 / 0.3)


@pytest.mark.parametrize("number", sorted(TABLE1))
def test_cases_match_table1_and_use_paper_convention(number):
    v1, v2, tc, tr, f = TABLE1[number]
    config = load_case(number)
    assert config.rig.convention == "paper"
    band = config.band
    assert (band.low_velocity, band.high_velocity, band.plateau_time, band.ramp_time) == (v1, v2, tc, tr)
    assert band.fundamental_hz == pytest.approx(f, rel=0.01)
    assert config.rig == RigParameters(convention="paper")  # the study's rig otherwise


def test_profile_dict_round_trip(tmp_path):
    csv = tmp_path / "p.csv"
    csv.write_text("# recorded\ntime_s,band_velocity_m_s\n0,1e-7\n1,3e-7\n")
    for profile in (
        ConstantBand(2e-8),
        RegularCycle(1e-7, 1e-6, 0.08, 0.02),
        SinusoidalBand(1.5e-7, 5e-8, 2.0),
        TableBand.from_csv(csv),
    ):
        assert profile_from_dict(profile_to_dict(profile)) == profile
    assert TableBand.from_csv(csv)(0.5) == pytest.approx(2e-7)
    assert TableBand.from_csv(csv)(5.0) == pytest.approx(3e-7)  # held after the end


@pytest.mark.parametrize(
    ("make", "needle"),
    [
        (lambda: RegularCycle(2e-7, 1e-7), "must be greater than low_velocity"),
        (lambda: RegularCycle(1e-7, 2e-7, plateau_time=-1), "plateau_time=-1"),
        (lambda: ConstantBand(float("nan")), "velocity=nan"),
        (lambda: SinusoidalBand(frequency=0), "frequency=0"),
        (lambda: TableBand((0, 0), (1e-7, 1e-7)), "strictly increasing"),
        (lambda: profile_from_dict({"kind": "sawtooth"}), "kind='sawtooth'"),
        (lambda: profile_from_dict({"kind": "constant", "speed": 1}), "['speed']"),
    ],
)
def test_bad_profiles_name_the_value(make, needle):
    with pytest.raises(ParameterError) as info:
        make()
    assert needle in str(info.value)


def test_bad_csv_rows(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,band_velocity_m_s\n0,1e-7\n0.5,fast\n")
    with pytest.raises(ParameterError, match="row 3"):
        TableBand.from_csv(bad)
    bad.write_text("0,1e-7\n1,nan\n")
    with pytest.raises(ParameterError, match="non-finite"):
        TableBand.from_csv(bad)


def test_config_merging_and_errors(tmp_path):
    config = from_mapping({"rig": {"damping_ratio": 0.05}, "band": {"kind": "constant", "velocity": "1e-6"}})
    assert config.rig.damping_ratio == 0.05 and config.rig.mass == 0.1
    assert config.band == ConstantBand(1e-6)  # YAML 1.1 reads 1e-6 as a string: accepted
    with pytest.raises(ParameterError, match=r"unknown rig parameter\(s\) \['massive'\]"):
        from_mapping({"rig": {"massive": 1}})
    with pytest.raises(ParameterError, match="unknown config section"):
        from_mapping({"rigg": {}})
    with pytest.raises(ParameterError, match=r"rtol=1\.0"):
        from_mapping({"simulation": {"rtol": 1.0}})
    printed = from_mapping({"rig": {"friction": {"contact_area": "printed"}}})
    assert printed.rig.friction.contact_area == 28.3e-12
    broken = tmp_path / "broken.yaml"
    broken.write_text("rig: [unclosed\n")
    with pytest.raises(ParameterError, match="not valid YAML"):
        load_config(broken)


def test_config_yaml_round_trip(tmp_path):
    for config in (default_config(), load_case(7)):
        path = tmp_path / "c.yaml"
        path.write_text(config.to_yaml())
        assert load_config(path) == config
