"""`lubrig report` reads its bag once, and the once-read bag gives what the per-call reader gives.

The reads are counted with an audit hook (sys.addaudithook): Python raises an `open` event for
every file any code in the process opens (builtins.open, io.open, os.open) and an `mmap.__new__`
event for every memory map, so the count is of the real reads of the .mcap file, whoever makes
them; nothing of the reader is replaced. The report runs in this process (cli.main), on a bag
written by the project's BagWriter (lubrig_testkit.bagdamage, the sim recorder's layout) and on a
legacy-layout bag (lubrig_testkit.legacy).
"""

from __future__ import annotations

import json
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
from lubrig_testkit.bagdamage import write_bag
from lubrig_testkit.legacy import write_legacy_bag

from lubrig_ros.bag import Bag, check_bag, read_arrays
from lubrig_ros.cli.main import main
from lubrig_ros.report.frombag import read_run

_EVENTS: list[tuple[str, object]] | None = None  # collecting while not None


def _hook(event: str, args: tuple[object, ...]) -> None:
    if _EVENTS is None:
        return
    if (event == "open" and str(args[0]).endswith(".mcap")) or event == "mmap.__new__":
        _EVENTS.append((event, args[0]))


sys.addaudithook(_hook)  # a hook cannot be removed: it collects only inside _reads_of_mcap


@contextmanager
def _reads_of_mcap() -> Iterator[list[tuple[str, object]]]:
    """The opens of .mcap files and the memory maps made inside the block."""
    global _EVENTS
    _EVENTS = []
    try:
        yield _EVENTS
    finally:
        _EVENTS = None


@pytest.fixture(scope="module")
def current_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    bag = tmp_path_factory.mktemp("one_read") / "bag"
    write_bag(bag)
    return bag


def test_report_opens_and_maps_the_mcap_once(
    current_bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`lubrig report BAG`: one open of the .mcap file, one memory map of it, and a full report."""
    out = tmp_path / "report"
    with _reads_of_mcap() as events:
        code = main(["report", str(current_bag), "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    assert [e for e, _ in events] == ["open", "mmap.__new__"], events
    summary = json.loads((out / "summary.json").read_text())
    assert summary["samples"] > 0 and summary["recording"]["streams"], summary
    assert (out / "report.md").is_file() and (out / "wavelet.png").is_file()


def test_legacy_layout_is_read_once_too(tmp_path: Path) -> None:
    """The legacy layout (JointState + Float64 topics) is rebuilt from the same one read."""
    bag = tmp_path / "legacy"
    config, traj = write_legacy_bag(bag, 0.5)
    with _reads_of_mcap() as events:
        run = read_run(bag)
    assert [e for e, _ in events] == ["open", "mmap.__new__"], events
    assert run.config.to_yaml() == config.to_yaml()  # type: ignore[attr-defined]
    np.testing.assert_array_equal(run.trajectory.displacement, traj.displacement)  # type: ignore[attr-defined]


def test_bag_read_once_agrees_with_the_per_call_reader(current_bag: Path) -> None:
    """Bag (the verifier's walk keeps the payloads) and read_arrays (the tolerant scan): the same arrays."""
    bag = Bag(current_bag)
    once, scanned = bag.arrays(), read_arrays(current_bag)
    assert once.keys() == scanned.keys() and once
    for topic, arrays in scanned.items():
        assert once[topic].msgtype == arrays.msgtype
        np.testing.assert_array_equal(once[topic].t, arrays.t, err_msg=topic)
        assert once[topic].fields.keys() == arrays.fields.keys(), topic
        for name, values in arrays.fields.items():
            if values.dtype != object:
                np.testing.assert_array_equal(once[topic][name], values, err_msg=f"{topic} {name}")
    assert bag.summary() == check_bag(current_bag)
    with _reads_of_mcap() as events:
        bag.summary(), bag.arrays(), bag.arrays([next(iter(once))])
    assert events == []


def test_bag_info_reads_the_mcap_once(current_bag: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`lubrig bag info BAG --verify`: one open and one map, the summary and the verdict printed."""
    with _reads_of_mcap() as events:
        code = main(["bag", "info", str(current_bag), "--verify"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert [e for e, _ in events] == ["open", "mmap.__new__"], events
    assert "Messages:" in out and "state_block" in out, out
