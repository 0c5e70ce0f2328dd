"""Bag files without ROS: truncation, corruption, repair, clear errors from info/replay.

`bag info` of a good bag and the replay node run as real processes; the other `lubrig` calls use
the same main() in-process (lubrig_testkit.cli), which is cheaper.
"""

from __future__ import annotations

import shutil
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from lubrig_testkit.cli import lubrig as _cli
from lubrig_testkit.crosscheck import read_mcap, read_rosbags

from lubrig_ros.bag import BagError, BagWriter, check_bag, repair_bag

N = 3000


def _f64(x: float) -> bytes:
    return b"\x00\x01\x00\x00" + struct.pack("<d", x)


def _write(path: Path, finalize: bool = True) -> BagWriter:
    w = BagWriter(path, run_config="a: 1\n")
    for k in range(N):
        w.write("/lubrig/displacement", "std_msgs/msg/Float64", 10_000 + k * 1_000_000, _f64(k))
        if k % 1000 == 999:
            w.flush()
    if finalize:
        w.close()
    return w


def _cli_process(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "lubrig_ros.cli.main", *args],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )


def _one_error_line(res: subprocess.CompletedProcess[str], *needles: str) -> None:
    assert res.returncode != 0
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1, res.stderr
    for needle in needles:
        assert needle in lines[0], lines[0]


@pytest.fixture
def bag(tmp_path: Path) -> Path:
    _write(tmp_path / "bag")
    return tmp_path / "bag"


def test_finalized_bag_reads_back_everywhere(bag: Path) -> None:
    assert read_rosbags(bag)["/lubrig/displacement"] == [float(k) for k in range(N)]
    assert read_mcap(bag)["/lubrig/displacement"] == [float(k) for k in range(N)]
    res = _cli_process("bag", "info", str(bag))
    assert res.returncode == 0 and "/lubrig/displacement" in res.stdout and str(N) in res.stdout


def test_truncated_bag_refused_by_info_and_replay(bag: Path) -> None:
    mcap = next(bag.glob("*.mcap"))
    data = mcap.read_bytes()
    mcap.write_bytes(data[: len(data) * 2 // 3])
    _one_error_line(_cli("bag", "info", str(bag)), "damaged", "repair")
    _one_error_line(_cli("replay", str(bag)), "damaged")
    res = subprocess.run(
        [sys.executable, "-m", "lubrig_ros.nodes.replay", str(bag)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    _one_error_line(res, "damaged")


def test_corrupted_chunk_refused_then_repair_skips_it(bag: Path) -> None:
    mcap = next(bag.glob("*.mcap"))
    data = bytearray(mcap.read_bytes())
    # damage the second chunk's zstd frame (rosbags writes no chunk CRC, so a flipped payload
    # byte can go unnoticed; a damaged frame is detected)
    second = data.find(b"\x28\xb5\x2f\xfd", data.find(b"\x28\xb5\x2f\xfd") + 4)
    data[second + 4 : second + 12] = b"\xff" * 8
    mcap.write_bytes(bytes(data))
    with pytest.raises(BagError, match="damaged"):
        check_bag(bag)
    _one_error_line(_cli("replay", str(bag)), "damaged")
    report = repair_bag(bag)
    assert len(report.damaged_chunks) == 1
    values = read_rosbags(bag)["/lubrig/displacement"]
    assert values == read_mcap(bag)["/lubrig/displacement"]
    assert 0 < len(values) < N and values == sorted(values)
    assert report.backup is not None and report.backup.exists()  # nothing is thrown away


def test_unfinalized_bag_repaired_up_to_last_flush(tmp_path: Path) -> None:
    w = _write(tmp_path / "bag", finalize=False)  # flushed at 1000, 2000, 3000
    w.write("/lubrig/displacement", "std_msgs/msg/Float64", 1, _f64(-1.0))  # never flushed
    crashed = tmp_path / "crashed"
    shutil.copytree(tmp_path / "bag", crashed)  # the on-disk state at a hard kill
    _one_error_line(_cli("bag", "info", str(crashed)), "metadata.yaml", "repair")
    res = _cli("bag", "repair", "--in-place", str(crashed))  # default: a new bag beside it
    assert res.returncode == 0, res.stderr
    assert read_rosbags(crashed)["/lubrig/displacement"] == [float(k) for k in range(N)]
    assert read_mcap(crashed)["/lubrig/displacement"] == [float(k) for k in range(N)]
    assert check_bag(crashed).run_config == "a: 1\n"
    assert "nothing to repair" in _cli("bag", "repair", str(crashed)).stdout


def test_writer_refuses_existing_or_unwritable(tmp_path: Path) -> None:
    (tmp_path / "f").write_text("x")
    with pytest.raises(BagError, match="already exists"):
        BagWriter(tmp_path / "f")
    with pytest.raises(BagError, match="not writable"):
        BagWriter(tmp_path / "f" / "bag")
    _one_error_line(_cli("bag", "info", str(tmp_path / "missing")), "does not exist")
