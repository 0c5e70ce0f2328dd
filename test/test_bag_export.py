"""`lubrig bag export|crop|filter|merge` on a recorded sim run (real `lubrig rig`, real processes).

The tables are read back with pyarrow (its CSV and Parquet readers) and compared with `lubrig
simulate`'s timeseries.csv of the same case, sample for sample; the new bags are read back with
the `mcap` package (and decoded from their own schemas by mcap-ros2-support) and verified by
`lubrig bag check`.
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest
from lubrig_testkit.harness import Processes, ros_env
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from pyarrow import csv, parquet

DURATION = 2.0  # s of rig time at 1 kHz: 2001 state samples in blocks
N = round(DURATION * 1000)
STATE, BAND, CONFIG = "/lubrig/state_block", "/lubrig/band_velocity_block", "/lubrig/run_config"
#: timeseries.csv column -> export column of the state_block table (the same field, same unit).
SAME = {
    "displacement_m": "displacement_m",
    "velocity_m_s": "velocity_m_s",
    "friction_coefficient": "friction_coefficient",
    "band_velocity_m_s": "band_velocity_m_s",
    "relative_velocity_m_s": "relative_velocity_m_s",
}
Message = tuple[str, int, bytes]


def lubrig(*args: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "lubrig_ros.cli.main", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )


@pytest.fixture(scope="module")
def run(ros_module_domain: int, tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, Path]]:
    """(bag of a recorded `lubrig rig` sim run of case 1, `lubrig simulate`'s output of the same)."""
    root = tmp_path_factory.mktemp("export")
    procs = Processes(ros_env(ros_module_domain), root / "logs")
    try:
        args = (
            "rig",
            "--case",
            "1",
            "--duration",
            f"{DURATION:g}",
            "--no-report",
            "--run-dir",
            str(root / "run"),
        )
        res = procs.run_module("lubrig_ros.cli.main", *args, timeout=240)
    finally:
        procs.stop_all(timeout=10)
    assert res.returncode == 0, res.stdout + res.stderr
    sim = lubrig("simulate", "--case", "1", "--duration", f"{DURATION:g}", "--out", str(root / "sim"))
    assert sim.returncode == 0, sim.stderr
    yield root / "run" / "bag", root / "sim"


def messages(bag: Path) -> list[Message]:
    """(topic, log time, payload) of every message, in file order, by the mcap package."""
    (mcap_file,) = bag.glob("*.mcap")
    with open(mcap_file, "rb") as f:
        return [
            (ch.topic, m.log_time, m.data) for _s, ch, m in make_reader(f).iter_messages(log_time_order=False)
        ]


def block_spans(bag: Path) -> dict[tuple[str, int], int]:
    """(topic, log time) -> log time of the last sample, of every block, decoded by mcap-ros2-support."""
    (mcap_file,) = bag.glob("*.mcap")
    spans = {}
    with open(mcap_file, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _s, ch, m, msg in reader.iter_decoded_messages(topics=[STATE, BAND]):
            n = len(msg.band_velocity)
            spans[(ch.topic, m.log_time)] = m.log_time + round((n - 1) * msg.sample_period * 1e9)
    return spans


def latched_topics(bag: Path) -> set[str]:
    """Topics whose channel offers transient_local durability (rosbag2's offered_qos_profiles)."""
    (mcap_file,) = bag.glob("*.mcap")
    with open(mcap_file, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    return {
        ch.topic
        for ch in summary.channels.values()
        if "transient_local" in ch.metadata["offered_qos_profiles"]
    }


def check(bag: Path) -> None:
    res = lubrig("bag", "check", str(bag))
    assert res.returncode == 0, res.stdout + res.stderr


def reference(sim: Path) -> pa.Table:
    return csv.read_csv(sim / "timeseries.csv")


def same_samples(table: pa.Table, ref: pa.Table) -> None:
    """The state table holds the run sample for sample: the same doubles, rig time to the stamp's ns."""
    assert table.num_rows == ref.num_rows == N + 1
    assert table["sample_index"].to_pylist() == list(range(N + 1))
    assert set(table["segment"].to_pylist()) == {0}
    for ref_name, name in SAME.items():
        assert np.array_equal(table[name].to_numpy(), ref[ref_name].to_numpy()), name
    # a block's stamp is whole nanoseconds: rig time is that plus i · sample_period
    np.testing.assert_allclose(table["rig_time_s"].to_numpy(), ref["time_s"].to_numpy(), rtol=0, atol=1e-9)
    np.testing.assert_allclose(table["log_time_s"].to_numpy(), ref["time_s"].to_numpy(), rtol=0, atol=1e-9)


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_export_equals_simulate_sample_for_sample(run: tuple[Path, Path], tmp_path: Path, fmt: str) -> None:
    bag, sim = run
    out = tmp_path / "tables"
    res = lubrig("bag", "export", str(bag), "--format", fmt, "--out", str(out))
    assert res.returncode == 0, res.stderr
    read = csv.read_csv if fmt == "csv" else parquet.read_table
    state = read(out / f"lubrig.state_block.{fmt}")
    band = read(out / f"lubrig.band_velocity_block.{fmt}")
    ref = reference(sim)
    same_samples(state, ref)
    assert np.array_equal(band["band_velocity_m_s"].to_numpy(), ref["band_velocity_m_s"].to_numpy()[1:])
    assert band["sample_index"].to_pylist() == list(range(N))
    assert state["skipped"].to_pylist() == [0] * (N + 1)  # a sim run skips nothing
    assert state["lateness_s"].null_count == N + 1  # and has no realtime timing: no lateness
    assert (out / "config.yaml").read_text() == (sim / "config.yaml").read_text()
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["config.yaml", f"lubrig.state_block.{fmt}", f"lubrig.band_velocity_block.{fmt}"]
    )
    if fmt == "parquet":  # units in the schema as well
        fields = parquet.read_schema(out / "lubrig.state_block.parquet")
        assert fields.field("displacement_m").metadata == {b"unit": b"m"}
        assert fields.field("friction_force_N").metadata == {b"unit": b"N"}


def test_export_window_and_topics(run: tuple[Path, Path], tmp_path: Path) -> None:
    bag, sim = run
    out = tmp_path / "window"
    args = ("--topics", STATE, "--start", "0.5", "--end", "1.25", "--out", str(out))
    res = lubrig("bag", "export", str(bag), "--format", "parquet", *args)
    assert res.returncode == 0, res.stderr
    assert sorted(p.name for p in out.iterdir()) == ["config.yaml", "lubrig.state_block.parquet"]
    table = parquet.read_table(out / "lubrig.state_block.parquet")
    assert table["sample_index"].to_pylist() == list(range(500, 1251))  # both bounds kept
    ref = reference(sim).slice(500, 751)
    for ref_name, name in SAME.items():
        assert np.array_equal(table[name].to_numpy(), ref[ref_name].to_numpy()), name


def test_crop_keeps_every_message_holding_a_sample_in_range(run: tuple[Path, Path], tmp_path: Path) -> None:
    bag, _sim = run
    out = tmp_path / "crop"
    res = lubrig("bag", "crop", str(bag), "--start", "0.5", "--end", "1.2", "--out", str(out))
    assert res.returncode == 0, res.stderr
    check(out)
    t0 = min(t for _topic, t, _d in messages(bag))  # --start / --end count from the first log time
    lo, hi = t0 + 500_000_000, t0 + 1_200_000_000
    spans = block_spans(bag)
    expected = [
        (topic, t, data) for topic, t, data in messages(bag) if (spans.get((topic, t), t) >= lo and t <= hi)
    ]
    before: dict[str, Message] = {}  # latched topics: the latest message before the range
    for topic, t, data in messages(bag):
        if topic in latched_topics(bag) and t < lo:
            before[topic] = (topic, t, data)
    assert CONFIG in before
    got = messages(out)
    assert sorted(got) == sorted(expected + list(before.values()))
    assert any(spans[(STATE, t)] > hi for topic, t, _d in got if topic == STATE)  # whole blocks
    assert {topic for topic, _t, _d in got} >= {STATE, BAND, CONFIG}


def test_filter_then_merge_gives_back_the_topics(run: tuple[Path, Path], tmp_path: Path) -> None:
    bag, _sim = run
    state, band, merged = tmp_path / "state", tmp_path / "band", tmp_path / "merged"
    for out, topic in ((state, STATE), (band, BAND)):
        res = lubrig("bag", "filter", str(bag), "--topics", topic, "--out", str(out))
        assert res.returncode == 0, res.stderr
        check(out)
        assert messages(out) == [m for m in messages(bag) if m[0] == topic]
    res = lubrig("bag", "merge", str(state), str(band), "--out", str(merged))
    assert res.returncode == 0, res.stderr
    check(merged)
    got = messages(merged)
    assert sorted(got) == sorted(m for m in messages(bag) if m[0] in (STATE, BAND))
    assert [t for _topic, t, _d in got] == sorted(t for _topic, t, _d in got)  # by log time
    assert (merged / "run_config.yaml").read_text() == (bag / "run_config.yaml").read_text()


def test_column_units_have_one_home() -> None:
    """Every sample field has its unit in core.schema; timeseries.csv names its columns the same way."""
    from lubrig_ros.app.plant.output import BLOCK_FIELDS
    from lubrig_ros.bag.export import columns_of
    from lubrig_ros.core.schema import SAMPLE_UNITS, unit_column
    from lubrig_ros.core.trajectory import Trajectory

    assert set(BLOCK_FIELDS) <= set(SAMPLE_UNITS)
    assert all(unit_column(name, SAMPLE_UNITS[name]) == column for name, column in Trajectory.COLUMNS)
    names = [c.name for c in columns_of("lubrig_interfaces/msg/RigStateBlock")]
    assert names[:4] == ["sample_index", "segment", "rig_time_s", "log_time_s"]
    assert names[4 : 4 + len(BLOCK_FIELDS)] == [unit_column(f, SAMPLE_UNITS[f]) for f in BLOCK_FIELDS]


def test_realtime_layout_rows(tmp_path: Path) -> None:
    """Per-sample RigState as they are; a realtime block's lateness per sample and its declared skip."""
    from lubrig_ros.bag.layout import typestore
    from lubrig_ros.bag.writer import BagWriter

    store = typestore()
    types = store.types
    header, stamp = types["std_msgs/msg/Header"], types["builtin_interfaces/msg/Time"]
    from lubrig_ros.app.plant.output import BLOCK_FIELDS

    fields = BLOCK_FIELDS
    base = 1_800_000_000 * 10**9  # a wall-clock stamp, as a realtime plant's
    writer = BagWriter(tmp_path / "bag", run_config="name: rt\n")
    for k in range(5):
        t = base + k * 10**6
        values = {f: float(k + i / 10) for i, f in enumerate(fields)}
        msg = types["lubrig_interfaces/msg/RigState"](header(stamp(*divmod(t, 10**9)), ""), k, 0, **values)
        writer.write(
            "/lubrig/state",
            "lubrig_interfaces/msg/RigState",
            t + 500,
            bytes(store.serialize_cdr(msg, msg.__msgtype__)),
        )
    arrays = {f: np.arange(8, 12, dtype=float) + i / 10 for i, f in enumerate(fields)}
    block = types["lubrig_interfaces/msg/RigStateBlock"](
        header(stamp(*divmod(base + 8 * 10**6, 10**9)), ""),
        1e-3,
        8,
        0,
        **arrays,
        lateness=np.array([1e-4, 2e-4, 0.0, 5e-5]),
        skipped=3,
    )
    writer.write(
        "/lubrig/state_block",
        block.__msgtype__,
        base + 9 * 10**6,
        bytes(store.serialize_cdr(block, block.__msgtype__)),
    )
    writer.close()
    out = tmp_path / "tables"
    res = lubrig("bag", "export", str(tmp_path / "bag"), "--out", str(out))
    assert res.returncode == 0, res.stderr
    state = csv.read_csv(out / "lubrig.state.csv")
    assert state["sample_index"].to_pylist() == [0, 1, 2, 3, 4]
    assert state["velocity_m_s"].to_pylist() == [k + 0.1 for k in range(5)]
    assert state["log_time_s"].to_pylist() == [(base + k * 10**6 + 500) / 1e9 for k in range(5)]
    assert state["rig_time_s"].to_pylist() == [(base + k * 10**6) / 1e9 for k in range(5)]
    assert "lateness_s" not in state.column_names
    blocks = csv.read_csv(out / "lubrig.state_block.csv")
    assert blocks["sample_index"].to_pylist() == [8, 9, 10, 11]
    assert blocks["lateness_s"].to_pylist() == [1e-4, 2e-4, 0.0, 5e-5]
    assert blocks["skipped"].to_pylist() == [3, 0, 0, 0]
    assert blocks["belt_travel_m"].to_pylist() == [8.6, 9.6, 10.6, 11.6]
    assert (out / "config.yaml").read_text() == "name: rt\n"


def test_chunk_damaged_half_way_leaves_no_table_and_no_bag(tmp_path: Path) -> None:
    """The cheap check passes (no chunk decompressed); the CRC of the damaged chunk stops the read."""
    from lubrig_testkit.bagdamage import write_bag

    bag = tmp_path / "bag"
    write_bag(bag)
    with open(bag / "bag.mcap", "r+b") as f:
        summary = make_reader(f).get_summary()
        assert summary is not None and len(summary.chunk_indexes) > 3
        last = summary.chunk_indexes[-2]
        at = last.chunk_start_offset + last.chunk_length - 8  # inside its compressed records
        f.seek(at)
        byte = f.read(1)
        f.seek(at)
        f.write(bytes([byte[0] ^ 0xFF]))
    for args in (("export", "--out", str(tmp_path / "t")), ("filter", "--out", str(tmp_path / "f"))):
        res = lubrig("bag", args[0], str(bag), *args[1:])
        assert res.returncode == 2 and "damaged" in res.stderr and len(res.stderr.splitlines()) == 1, (
            res.stderr
        )
        assert not Path(args[2]).exists()


def test_merge_refuses_two_runs(tmp_path: Path) -> None:
    """Bags of two run configurations are not merged (one line, exit 2, no output)."""
    from lubrig_testkit.bagdamage import write_bag

    from lubrig_ros.bag.writer import BagWriter

    write_bag(tmp_path / "a")
    other = BagWriter(tmp_path / "b", run_config="name: other\n")
    other.write("/lubrig/displacement", "std_msgs/msg/Float64", 0, b"\x00\x01\x00\x00" + bytes(8))
    other.close()
    res = lubrig("bag", "merge", str(tmp_path / "a"), str(tmp_path / "b"), "--out", str(tmp_path / "m"))
    assert res.returncode == 2 and len(res.stderr.splitlines()) == 1, res.stderr
    assert "different run configurations" in res.stderr and str(tmp_path / "b") in res.stderr
    assert not (tmp_path / "m").exists()
