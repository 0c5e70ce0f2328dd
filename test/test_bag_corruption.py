"""Corruption matrix (issue 15): every kind of damage is detected, named, refused and repaired.

One bag (BagWriter, a 1 s core run of case 1: JointState state, Float64 friction coefficient and
band velocity, the run configuration) is damaged in each way of CASES: truncations at several
offsets; single-byte flips in the header, a chunk's data, a chunk's CRC, a message index, the
summary and the footer; a wrong count or a deleted metadata.yaml; an empty directory. For each,
`lubrig bag check`, `lubrig bag info --verify`, `lubrig report`, `lubrig replay` and
`lubrig bag repair` run in a child process (one per command set, with a time limit against a
hang) and must give the documented outcome (docs/recording.md): the problem named (with its byte
offset), never "OK", never a traceback; repair keeps exactly the messages of the chunks that
verify, and its output is read back by an independent reader (mcap, CRCs validated) and rosbags.
The damaged offsets come from the independent mcap reader's view of the original file.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import shutil
import struct
import subprocess
import sys
import textwrap
from collections.abc import Callable
from pathlib import Path

import pytest
import yaml
from lubrig_testkit.legacy import write_legacy_bag
from mcap.exceptions import EndOfFile
from mcap.reader import make_reader
from mcap.records import Message
from mcap.stream_reader import StreamReader
from rosbags.rosbag2 import Reader

from lubrig_ros.bag import BagWriter
from lubrig_ros.bag.verify import verify_bag

DURATION = 1.0
TIMEOUT = 120  # s for the whole child process: a guard against a hang, not a speed assertion

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


def write_run_bag(path: Path) -> None:
    """A recorder-like bag of a short core run (what `lubrig report` reads)."""
    write_legacy_bag(path, DURATION)


def _count_messages(chunk_record: bytes) -> int:
    """Messages in one chunk record, read by mcap's stream reader."""
    n = 0
    with contextlib.suppress(EndOfFile):
        for record in StreamReader(io.BytesIO(chunk_record), skip_magic=True).records:
            n += isinstance(record, Message)
    return n


class Layout:
    """Offsets of the original file as the independent mcap reader sees them."""

    def __init__(self, mcap: Path) -> None:
        self.data = mcap.read_bytes()
        with open(mcap, "rb") as f:
            summary = make_reader(f).get_summary()
        assert summary is not None
        self.chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
        assert len(self.chunks) >= 4, "the test needs several chunks"
        self.per_chunk = []
        for c in self.chunks:
            raw = self.data[c.chunk_start_offset : c.chunk_start_offset + c.chunk_length]
            self.per_chunk.append(_count_messages(raw))
        self.total = sum(self.per_chunk)
        self.footer = len(self.data) - 8 - 29
        (self.summary_start,) = struct.unpack_from("<Q", self.data, self.footer + 9)

    def kept_before(self, cut: int) -> int:
        """Messages of the chunks that end before byte cut."""
        return sum(
            n
            for c, n in zip(self.chunks, self.per_chunk, strict=True)
            if c.chunk_start_offset + c.chunk_length <= cut
        )


def _flip(offset: int, mask: int = 0x01) -> Callable[[Path, bytes], None]:
    def damage(bag: Path, data: bytes) -> None:
        buf = bytearray(data)
        buf[offset] ^= mask
        (bag / "bag.mcap").write_bytes(bytes(buf))

    return damage


def _cut(offset: int) -> Callable[[Path, bytes], None]:
    def damage(bag: Path, data: bytes) -> None:
        (bag / "bag.mcap").write_bytes(data[:offset])

    return damage


def _no_metadata(bag: Path, _data: bytes) -> None:
    (bag / "metadata.yaml").unlink()


def _wrong_count(bag: Path, _data: bytes) -> None:
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())
    meta["rosbag2_bagfile_information"]["topics_with_message_count"][1]["message_count"] -= 1
    (bag / "metadata.yaml").write_text(yaml.safe_dump(meta))


def _empty(bag: Path, _data: bytes) -> None:
    shutil.rmtree(bag)
    bag.mkdir()


def cases(lay: Layout) -> dict[str, tuple[Callable[[Path, bytes], None], str, int | None]]:
    """name -> (damage, text the first problem line must contain, messages repair keeps | None)."""
    c1 = lay.chunks[1]
    o1 = c1.chunk_start_offset
    index_at = min(c1.message_index_offsets.values())
    size = len(lay.data)
    third, two_thirds = size // 3, 2 * size // 3
    return {
        "truncated_in_header": (_cut(12), "byte 8", None),
        "truncated_at_one_third": (_cut(third), "byte", lay.kept_before(third)),
        "truncated_at_two_thirds": (_cut(two_thirds), "byte", lay.kept_before(two_thirds)),
        "truncated_before_summary": (_cut(lay.summary_start), "footer", lay.total),
        "truncated_last_byte": (_cut(size - 1), "magic", lay.total),
        "flip_header_profile": (_flip(8 + 9 + 4, 0x04), "byte 8", lay.total),
        "flip_chunk_data": (_flip(o1 + c1.chunk_length // 2), f"byte {o1}", lay.total - lay.per_chunk[1]),
        "flip_chunk_crc": (_flip(o1 + 9 + 24), f"byte {o1}", lay.total - lay.per_chunk[1]),
        "flip_message_index": (_flip(index_at + 9 + 6 + 8), f"byte {index_at}", lay.total),
        "flip_summary": (_flip((lay.summary_start + lay.footer) // 2), "summary", lay.total),
        "flip_footer": (_flip(lay.footer + 9), "footer", lay.total),
        "metadata_deleted": (_no_metadata, "metadata.yaml is missing", lay.total),
        "metadata_count_wrong": (_wrong_count, "metadata.yaml counts", lay.total),
        "empty_directory": (_empty, "found 0", None),
    }


def _messages(bag: Path) -> dict[tuple[str, int], bytes]:
    """(topic, log time) -> payload, read by mcap with CRC validation (the independent reader)."""
    (mcap,) = bag.glob("*.mcap")
    out = {}
    with open(mcap, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        assert reader.get_summary() is not None
        for _schema, channel, message in reader.iter_messages():
            out[(channel.topic, message.log_time)] = message.data
    return out


@pytest.fixture(scope="module")
def matrix(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    root = tmp_path_factory.mktemp("corrupt")
    original = root / "original" / "bag"
    original.parent.mkdir()
    write_run_bag(original)
    lay = Layout(original / "bag.mcap")
    table = cases(lay)
    commands: dict[str, dict[str, list[str]]] = {}
    sha: dict[str, str] = {}
    for name, (damage, _needle, _kept) in table.items():
        bag = root / name / "bag"
        shutil.copytree(original, bag)
        damage(bag, lay.data)
        sha[name] = hashlib.sha256(b"".join(p.read_bytes() for p in sorted(bag.iterdir()))).hexdigest()
        commands[name] = {
            "check": ["bag", "check", str(bag)],
            "info": ["bag", "info", "--verify", str(bag)],
            "report": ["report", str(bag), "--out", str(root / name / "report")],
            "replay": ["replay", str(bag)],
            "repair": ["bag", "repair", str(bag)],
        }
    res = subprocess.run(
        [sys.executable, "-c", DRIVER, json.dumps(commands)],
        capture_output=True,
        text=True,
        timeout=TIMEOUT * 4,
        check=False,
    )
    assert res.returncode == 0, res.stderr
    results = json.loads(res.stdout.strip().splitlines()[-1])
    return {"root": root, "original": original, "layout": lay, "cases": table, "results": results, "sha": sha}


CASE_NAMES = [
    "truncated_in_header",
    "truncated_at_one_third",
    "truncated_at_two_thirds",
    "truncated_before_summary",
    "truncated_last_byte",
    "flip_header_profile",
    "flip_chunk_data",
    "flip_chunk_crc",
    "flip_message_index",
    "flip_summary",
    "flip_footer",
    "metadata_deleted",
    "metadata_count_wrong",
    "empty_directory",
]


def _no_traceback(name: str, key: str, result: list) -> None:
    code, out, err = result
    assert code is not None and "Traceback" not in out + err, f"{name} {key}:\n{err}"


@pytest.mark.parametrize("name", CASE_NAMES)
def test_damage_detected_named_and_refused(matrix: dict, name: str) -> None:
    results, (_damage, needle, _kept) = matrix["results"][name], matrix["cases"][name]
    for key in ("check", "info", "report", "replay"):
        _no_traceback(name, key, results[key])
        code, out, err = results[key]
        assert code != 0, f"{name} {key} accepted a damaged bag:\n{out}"
        assert " OK" not in out + err, f"{name} {key} said OK:\n{out}"
        lines = err.strip().splitlines()
        assert len(lines) == 1, f"{name} {key}: expected one error line:\n{err}"
    for key in ("check", "info"):
        line = results[key][2].strip()
        assert needle in line, f"{name} {key}: {needle!r} not in {line!r}"
    for key in ("report", "replay"):
        line = results[key][2].strip()
        assert "lubrig bag repair" in line or "does not exist" in line or "found 0" in line, line


@pytest.mark.parametrize("name", CASE_NAMES)
def test_repair_keeps_every_message_of_the_chunks_that_verify(matrix: dict, name: str) -> None:
    root, lay = matrix["root"], matrix["layout"]
    _damage, _needle, kept = matrix["cases"][name]
    code, out, err = matrix["results"][name]["repair"]
    _no_traceback(name, "repair", [code, out, err])
    bag = root / name / "bag"
    after = hashlib.sha256(b"".join(p.read_bytes() for p in sorted(bag.iterdir()))).hexdigest()
    assert after == matrix["sha"][name], "repair changed the original (default: a new bag beside it)"
    if kept is None:
        assert code == 2 and len(err.strip().splitlines()) == 1, err
        assert not (root / name / "bag_repaired").exists()
        return
    assert code == 0, err
    assert f"with {kept} messages" in out, out
    if kept < lay.total:
        assert "dropped" in out and "dropped nothing" not in out, out
    repaired = root / name / "bag_repaired"
    v = verify_bag(repaired)
    assert not v.structural, [p.line() for p in v.structural]
    got = _messages(repaired)
    assert len(got) == kept
    with Reader(repaired) as reader:
        assert sum(1 for _ in reader.messages()) == kept
    original = _messages(matrix["original"])
    assert all(original[key] == data for key, data in got.items()), "a kept payload changed"


def test_intact_bag_passes_and_repair_leaves_it(matrix: dict, tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    shutil.copytree(matrix["original"], bag)
    commands = (
        ["bag", "check", str(bag)],
        ["bag", "info", "--verify", str(bag)],
        ["bag", "repair", str(bag)],
    )
    for args in commands:
        res = subprocess.run(
            [sys.executable, "-m", "lubrig_ros.cli.main", *args],
            capture_output=True,
            text=True,
            timeout=TIMEOUT,
            check=False,
        )
        assert res.returncode == 0, res.stderr
        assert "Traceback" not in res.stderr
    assert "nothing to repair" in res.stdout
    assert not (tmp_path / "bag_repaired").exists()


@pytest.mark.parametrize("name", ["truncated_at_two_thirds", "flip_chunk_data", "empty_directory"])
def test_console_script_one_line(matrix: dict, name: str) -> None:
    """The console script itself (a fresh interpreter) on damaged bags: one line, exit status.

    A damaged bag is a problem found (exit 1); a directory that is no bag at all is bad input
    (exit 2, as `lubrig bag info`).
    """
    bag = matrix["root"] / name / "bag"
    res = subprocess.run(
        [sys.executable, "-m", "lubrig_ros.cli.main", "bag", "check", str(bag)],
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
        check=False,
    )
    expected = 2 if "not a bag" in res.stderr else 1
    assert name != "empty_directory" or expected == 2
    assert res.returncode == expected and len(res.stderr.strip().splitlines()) == 1, res.stderr
    assert matrix["cases"][name][1] in res.stderr


def test_report_after_repair(matrix: dict, tmp_path: Path) -> None:
    """A bag whose metadata.yaml was lost is reported on again once repaired."""
    repaired = matrix["root"] / "metadata_deleted" / "bag_repaired"
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "lubrig_ros.cli.main",
            "report",
            str(repaired),
            "--out",
            str(tmp_path / "report"),
        ],
        capture_output=True,
        text=True,
        timeout=TIMEOUT * 2,
        check=False,
    )
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "report" / "summary.json").is_file()


def test_every_byte_flip_inside_a_chunk_is_detected(tmp_path: Path) -> None:
    """Each single-byte change of one chunk record's data (compressed payload, CRC, sizes) is found."""
    bag = tmp_path / "bag"
    w = BagWriter(bag, flush_messages=50)
    for k in range(120):
        w.write(
            "/lubrig/displacement",
            "std_msgs/msg/Float64",
            1_000_000 * k,
            b"\x00\x01\x00\x00" + struct.pack("<d", 0.001 * k),
        )
    w.close()
    mcap = bag / "bag.mcap"
    data = mcap.read_bytes()
    lay_chunks = sorted(
        make_reader(io.BytesIO(data)).get_summary().chunk_indexes, key=lambda c: c.chunk_start_offset
    )
    chunk = lay_chunks[1]
    start = chunk.chunk_start_offset + 9  # the chunk record's body: times, sizes, CRC, data
    end = chunk.chunk_start_offset + chunk.chunk_length
    missed = []
    for pos in range(start, end):
        for mask in (0x01, 0x80):
            buf = bytearray(data)
            buf[pos] ^= mask
            mcap.write_bytes(bytes(buf))
            v = verify_bag(bag, continuity=False)
            if v.ok:
                missed.append((pos, mask))
    assert not missed, f"{len(missed)} byte flips went unnoticed, first {missed[:5]}"
    assert end - start > 100
