"""One run selection (app/selection.py): case | file | default + overrides, for every command."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from lubrig_ros.app.selection import RunSelection, base_config, select_run
from lubrig_ros.cli.main import main
from lubrig_ros.core.params import ParameterError, RigParameters
from lubrig_ros.core.presets import default_config, load_case, load_config
from lubrig_ros.core.profiles import ConstantBand
from lubrig_ros.core.stability import unstable_intervals


def test_sources_and_not_given_values() -> None:
    assert base_config() == default_config()
    assert base_config(0, "") == default_config()  # the nodes' parameter defaults
    assert base_config(3) == load_case(3) == RunSelection(case="3").resolve()
    path = Path(__file__).resolve().parents[1] / "config" / "stickslip.yaml"
    assert base_config(None, path) == load_config(path) == RunSelection(config_file=path).resolve()
    with pytest.raises(ParameterError, match="both given"):  # one source, as on the command line
        base_config(2, path)


def test_overrides_keep_what_is_not_given() -> None:
    config = select_run(
        1,
        convention="physical",
        duration=2.5,
        contact_area="printed",
        band=ConstantBand(3e-7),
        damping_ratio=0.05,
    )
    case = load_case(1)
    assert config.rig.convention == "physical" and config.duration == 2.5
    assert config.rig.damping_ratio == 0.05 and config.band == ConstantBand(3e-7)
    assert config.rig.friction.contact_area == pytest.approx(28.3e-12)
    assert (config.rig.mass, config.sample_rate, config.name) == (case.rig.mass, case.sample_rate, case.name)
    assert select_run(1) == case  # nothing overridden: the case itself


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"case": 11}, "case=11"),
        ({"case": "x"}, "case='x'"),
        ({"case": True}, "case=True"),
        ({"case": 1, "config_file": Path("a.yaml")}, "both given"),
    ],
)
def test_bad_selection_names_the_value(kwargs: dict, needle: str) -> None:
    with pytest.raises(ParameterError, match=needle):
        RunSelection(**kwargs)


def _json(capsys: pytest.CaptureFixture[str], *argv: str) -> dict:
    assert main(list(argv)) == 0
    return json.loads(capsys.readouterr().out)


def test_stability_honours_case_and_config(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    # case 1 is in the paper convention: the default rig's physical convention no longer applies
    report = _json(capsys, "stability", "--case", "1", "--json")
    assert report["convention"] == "paper" and [r["zeta"] for r in report["results"]] == [0.01]
    expected = unstable_intervals(0.01, RigParameters(convention="paper"))
    assert report["results"][0]["unstable_intervals"] == [list(i) for i in expected]
    config = tmp_path / "rig.yaml"
    config.write_text("rig:\n  damping_ratio: 0.2\n  natural_frequency: 20.0\n  convention: paper\n")
    report = _json(capsys, "stability", "--config", str(config), "--json")
    assert report["convention"] == "paper" and report["results"][0]["zeta"] == 0.2
    rig = RigParameters(natural_frequency=20.0, damping_ratio=0.2, convention="paper")
    assert report["results"][0]["unstable_intervals"] == [list(i) for i in unstable_intervals(0.2, rig)]
    # explicit options still override the selected run
    report = _json(
        capsys, "stability", "--config", str(config), "--convention", "physical", "--zeta", "0.01", "--json"
    )
    assert report["convention"] == "physical" and report["results"][0]["zeta"] == 0.01


def test_friction_honours_config(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    default = _json(capsys, "friction", "--at", "1e-7", "--json")
    config = tmp_path / "f.yaml"
    config.write_text("rig:\n  friction:\n    contact_area: printed\n")
    printed = _json(capsys, "friction", "--config", str(config), "--at", "1e-7", "--json")
    assert printed["contact_area_m2"] == pytest.approx(28.3e-12)
    assert printed["points"][0]["mu"] == pytest.approx(default["points"][0]["mu"] / 10, rel=1e-9)
    override = _json(capsys, "friction", "--config", str(config), "--contact-area", "corrected", "--json")
    assert override["contact_area_m2"] == pytest.approx(2.83e-10)


def test_bad_source_is_one_line(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["stability", "--case", "12"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("lubrig stability: error:") and "case='12'" in err and "\n" not in err
    assert main(["friction", "--config", str(tmp_path / "none.yaml")]) == 2
    assert "none.yaml" in capsys.readouterr().err
