"""Damage matrix (issue 21): bags that never lie — metadata.yaml against the MCAP, field by field.

One bag of the current layout (lubrig_testkit.bagdamage.write_bag: BagWriter, case 1 for 0.5 s,
RigStateBlock and BandVelocityBlock blocks, the run configuration, several chunks) is damaged in
each way of bagdamage.CASES: metadata.yaml disagreeing with the MCAP file in every field it holds
(file names, times, counts, storage, compression, custom_data, ros_distro, version and per topic
its name, type, serialization format, QoS, type hash and count), a metadata.yaml that is missing,
unreadable or of the wrong shape, and damage of the MCAP file and its directory. For each,
`lubrig bag check`, `lubrig report`, `lubrig replay` (refused before any ROS node starts) and
`lubrig bag repair` run in one child process (a time limit per command against a hang): check
names the field and exits 1, report and replay refuse with one line, none raises a traceback;
repair's output verifies with `lubrig bag check` and holds every message with its payload
unchanged (read back by the independent mcap reader, CRCs validated, and by rosbags through the
rebuilt metadata.yaml), or it names what it could not keep, or it refuses with one line where
nothing is left to rebuild from.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import textwrap
from typing import Any

import pytest
import yaml
from lubrig_testkit.bagdamage import ALL_FIELDS, BAND_BLOCK, CASES, INFO, NS, STATE_BLOCK, messages, write_bag
from mcap.reader import make_reader
from rosbags.rosbag2 import Reader

TIMEOUT = 600  # s for the whole child process: a guard against a hang, not a speed assertion

DRIVER = textwrap.dedent(
    """
    import json, signal, sys, traceback
    from lubrig_testkit.cli import lubrig

    def alarm(*_):
        raise TimeoutError("command hung")

    signal.signal(signal.SIGALRM, alarm)
    results = {}
    for name, commands in json.loads(sys.argv[1]).items():
        results[name] = {}
        for key, args in commands.items():
            signal.alarm(60)
            try:
                res = lubrig(*args)
                results[name][key] = [res.returncode, res.stdout, res.stderr]
            except BaseException:
                results[name][key] = [None, "", traceback.format_exc()]
            finally:
                signal.alarm(0)
    print(json.dumps(results))
    """
)


@pytest.fixture(scope="module")
def matrix(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    root = tmp_path_factory.mktemp("damage")
    original = root / "original" / "bag"
    original.parent.mkdir()
    write_bag(original)
    commands: dict[str, dict[str, list[str]]] = {}
    for name, (damage, _needle, _repair) in CASES.items():
        bag = root / name / "bag"
        shutil.copytree(original, bag)
        damage(bag)
        repaired = root / name / "bag_repaired"
        commands[name] = {
            "check": ["bag", "check", str(bag)],
            "report": ["report", str(bag), "--out", str(root / name / "report")],
            "replay": ["replay", str(bag)],
            "repair": ["bag", "repair", str(bag)],
            "check_repaired": ["bag", "check", str(repaired)],
        }
    res = subprocess.run(
        [sys.executable, "-c", DRIVER, json.dumps(commands)],
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
        check=False,
    )
    assert res.returncode == 0, res.stderr
    results = json.loads(res.stdout.strip().splitlines()[-1])
    return {"root": root, "original": original, "results": results}


def test_the_matrix_is_large_enough() -> None:
    assert len(CASES) >= 40


def test_the_original_bag_verifies(matrix: dict[str, Any]) -> None:
    """The bag every case starts from is sound (so each finding is the damage's)."""
    from lubrig_testkit.cli import lubrig

    res = lubrig("bag", "check", str(matrix["original"]))
    assert res.returncode == 0 and " OK: fully verified" in res.stdout, res.stdout + res.stderr
    with open(matrix["original"] / "bag.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and len(summary.chunk_indexes) >= 4


def _no_traceback(name: str, key: str, result: list[Any]) -> None:
    code, out, err = result
    assert code is not None and "Traceback" not in out + err, f"{name} {key}:\n{out}\n{err}"


@pytest.mark.parametrize("name", list(CASES))
def test_check_names_the_damage_and_report_and_replay_refuse(matrix: dict[str, Any], name: str) -> None:
    results, (_damage, needle, _repair) = matrix["results"][name], CASES[name]
    for key in ("check", "report", "replay"):
        _no_traceback(name, key, results[key])
        code, out, err = results[key]
        assert code != 0, f"{name} {key} accepted a damaged bag:\n{out}"
        assert " OK" not in out + err, f"{name} {key} said OK:\n{out}"
        assert len(err.strip().splitlines()) == 1, f"{name} {key}: expected one error line:\n{err}"
    code, out, err = results["check"]
    assert code == 1, err
    problems = [line for line in out.splitlines() if line.startswith("problem ")] or [err]
    assert any(needle in line for line in problems), f"{name}: {needle!r} not among\n" + "\n".join(problems)
    for key in ("report", "replay"):
        assert "repair" in results[key][2] or "found 0" in results[key][2], results[key][2]


def test_every_field_of_metadata_yaml_is_named(matrix: dict[str, Any]) -> None:
    """metadata.yaml disagreeing with the MCAP in every field at once: each is its own problem line."""
    out = matrix["results"]["all_fields"]["check"][1]
    problems = [line for line in out.splitlines() if line.startswith("problem ")]
    missing = [f for f in ALL_FIELDS if not any(f in line for line in problems)]
    assert not missing, f"not named: {missing}\n" + "\n".join(problems)
    for topic in (f"{NS}/run_config", STATE_BLOCK, BAND_BLOCK):
        named = [line for line in problems if f"topic {topic}:" in line]
        assert len(named) == 5, named  # type, serialization format, QoS, type hash, count


@pytest.mark.parametrize("name", list(CASES))
def test_repair_output_verifies_or_names_what_it_could_not_keep(matrix: dict[str, Any], name: str) -> None:
    root, results = matrix["root"], matrix["results"][name]
    expected = CASES[name][2]
    _no_traceback(name, "repair", results["repair"])
    code, out, err = results["repair"]
    repaired = root / name / "bag_repaired"
    if expected == "refused":
        assert code == 2 and len(err.strip().splitlines()) == 1, err
        assert not repaired.exists()
        return
    assert code == 0, f"{name}:\n{out}\n{err}"
    assert "verified:" in out and "still wrong" not in out, out
    assert ("not kept:" in out) == ("not kept" in expected), out
    if "dropped" in expected:
        assert "dropped" in out and "dropped nothing" not in out, out
    check_code, check_out, check_err = results["check_repaired"]
    original = messages(matrix["original"] / "bag.mcap")
    got = messages(repaired / "bag_repaired.mcap")
    assert all(original[key] == data for key, data in got.items()), "a kept payload changed"
    with Reader(repaired) as reader:  # rosbags, driven by the rebuilt metadata.yaml
        assert sum(1 for _ in reader.messages()) == len(got)
    if "dropped" in expected:
        assert 0 < len(got) < len(original)
        return  # the dropped samples are gaps now: check names them (continuity), not the file
    assert check_code == 0, f"{name}: the repaired bag does not verify:\n{check_out}\n{check_err}"
    assert got == original


def test_repair_keeps_the_records_run_configuration(matrix: dict[str, Any]) -> None:
    """An edited custom_data is not kept: the file's rosbag2 record is what the bag recorded."""
    repaired = matrix["root"] / "custom_data_run_config" / "bag_repaired"
    info = yaml.safe_load((repaired / "metadata.yaml").read_text())[INFO]
    original = yaml.safe_load((matrix["original"] / "metadata.yaml").read_text())[INFO]
    assert info["custom_data"] == original["custom_data"]
    assert "lubrig_ros.run_config" in matrix["results"]["custom_data_run_config"]["repair"][1]
