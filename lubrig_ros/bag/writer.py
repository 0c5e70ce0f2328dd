"""Crash-safe rosbag2/MCAP writer on the `mcap` package's writer (chunk and summary CRC-32s).

The file is a rosbag2 bag as the rosbags writer made it before (metadata.yaml, profile ros2, one
ros2msg schema per type, cdr channels with their offered QoS, a "rosbag2" metadata record), with
what rosbag2 writes besides (each channel's RIHS01 ``topic_type_hash``, the real ``ros_distro``), and
every chunk carries the CRC-32 of its uncompressed records, the summary its CRC and the DataEnd
record the CRC of the whole data section, so any damage is detectable (lubrig_ros.bag.verify).

Bounded loss: a chunk is closed and handed to the operating system (no fsync) whenever the
pending messages span ``flush_period_ns`` of log time (rig time with --use-sim-time) or number
``flush_messages`` (or reach 1 MiB), so a SIGKILL or a full disk loses at most that much of what
the writer was given. :meth:`BagWriter.flush` also fsyncs (the recorder's wall-clock flush).
After a write error ``counts`` are re-read from the file: they are what is in the bag.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

from lubrig_ros import __version__
from lubrig_ros.app.fileio import write_text_atomic
from lubrig_ros.bag.errors import BagError
from lubrig_ros.bag.layout import CONFIG_SIDECAR, RUN_CONFIG_KEY, VERSION_KEY, typestore
from lubrig_ros.bag.mcapscan import Channel, Message, ScanResult, scan
from lubrig_ros.bag.meta import (
    MESSAGE_ENCODING,
    PROFILE,
    channel_metadata,
    message_definition,
    metadata_dict,
    metadata_texts,
    qos_text,
    type_hash,
)

#: Default flush bound: a chunk at least every 0.2 s of log (rig) time or every 1000 messages.
FLUSH_PERIOD_NS = 200_000_000
FLUSH_MESSAGES = 1000
CHUNK_BYTES = 1 << 20  # a chunk is closed at this size whatever the bound
_RECORD_OVERHEAD = 31  # bytes of an MCAP message record besides its payload


def _mcap_version() -> str:
    try:
        from importlib.metadata import version

        return version("mcap")
    except Exception:
        return "?"


LIBRARY = f"lubrig_ros-{__version__} mcap-python/{_mcap_version()}"


def has_leading_stamp(msgtype: str) -> bool:
    """True if the CDR payload starts with a time stamp (a Header or a Time first field)."""
    fields = typestore().fielddefs.get(msgtype)
    if not fields or not fields[1]:
        return False
    first = fields[1][0][1]
    return first[0].name == "NAME" and first[1] in {"std_msgs/msg/Header", "builtin_interfaces/msg/Time"}


def make_qos(depth: int, latched: bool) -> Qos:
    """The offered QoS stored with a topic: reliable, keep_last depth, volatile or latched."""
    zero = QosTime(0, 0)
    return Qos(
        QosHistory.KEEP_LAST,
        depth,
        QosReliability.RELIABLE,
        QosDurability.TRANSIENT_LOCAL if latched else QosDurability.VOLATILE,
        zero,
        zero,
        QosLiveliness.AUTOMATIC,
        zero,
        False,
    )


def serialize_string(text: str) -> bytes:
    """CDR bytes of a std_msgs/msg/String."""
    msgcls = typestore().types["std_msgs/msg/String"]
    return bytes(typestore().serialize_cdr(msgcls(data=text), "std_msgs/msg/String"))


def check_output_path(path: Path) -> None:
    """Raise BagError if a new bag cannot be created at path (exists, parent missing/unwritable)."""
    if path.exists():
        raise BagError(f"output {str(path)!r} already exists: give a new directory name")
    parent = path.absolute().parent
    if not parent.is_dir():
        raise BagError(f"output {str(path)!r} is not writable: parent {str(parent)!r} is not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise BagError(f"output {str(path)!r} is not writable: no write permission on {str(parent)!r}")


class BagWriter:
    """A rosbag2 bag (MCAP storage, zstd chunks with CRC-32s) holding serialized CDR messages.

    Usage: ``w = BagWriter(path, run_config=text); w.write(topic, msgtype, t_ns, cdr); w.flush();
    w.close()``. Any OSError while writing (disk full, ...) is raised as BagError; the writer is
    then dead (``failed``), ``counts`` hold what the file keeps, ``lost`` what it does not, and
    :meth:`close` only closes the file (repair is the caller's step: lubrig_ros.bag.repair).
    """

    FLUSH_PERIOD_NS = FLUSH_PERIOD_NS  # the default bound, for callers' option defaults
    FLUSH_MESSAGES = FLUSH_MESSAGES

    def __init__(
        self,
        path: str | Path,
        run_config: str | None = None,
        flush_period_ns: int = FLUSH_PERIOD_NS,
        flush_messages: int = FLUSH_MESSAGES,
    ) -> None:
        self.path = Path(path)
        check_output_path(self.path)
        if flush_period_ns <= 0 or flush_messages <= 0:
            raise BagError(f"flush bound {flush_period_ns} ns / {flush_messages} messages: expected both > 0")
        self.run_config = run_config
        self.flush_period_ns = int(flush_period_ns)
        self.flush_messages = int(flush_messages)
        self.mcap_path = self.path / f"{self.path.name}.mcap"
        self.custom_data: dict[str, str] = {VERSION_KEY: __version__}
        if run_config is not None:
            self.custom_data[RUN_CONFIG_KEY] = run_config
        self._channels: dict[str, int] = {}
        self._topic_info: dict[str, tuple[str, str]] = {}  # topic -> (msgtype, qos text)
        self._schemas: dict[str, int] = {}
        self._type_hashes: dict[str, str] = {}  # msgtype -> RIHS01 hash (its channels' topic_type_hash)
        self.counts: dict[str, int] = {}
        self.lost: dict[str, int] = {}
        self.failed: str | None = None
        self.closed = False
        self.chunks_flushed = 0
        self._pending = 0
        self._pending_bytes = 0
        self._pending_t0 = 0
        self._pending_t1 = 0
        self._start, self._end = 2**63 - 1, 0
        try:
            self.path.mkdir()
            self._stream: BinaryIO | None = open(self.mcap_path, "xb")  # noqa: SIM115 (kept open)
            self._mcap = McapWriter(
                self._stream,
                chunk_size=2**62,
                compression=CompressionType.ZSTD,
                enable_crcs=True,
                enable_data_crcs=True,
            )
            self._mcap.start(profile=PROFILE, library=LIBRARY)
            self._stream.flush()
        except OSError as exc:
            raise BagError(f"cannot create bag {str(self.path)!r}: {exc.strerror or exc}") from exc
        if run_config is not None:
            self._guard(lambda: self._write_sidecar(run_config))
        self.last_flush = time.monotonic()

    # ------------------------------------------------------------------ configuration
    def set_run_config(self, text: str) -> None:
        """Store the run configuration (YAML) in metadata custom_data."""
        if text != self.run_config:
            self._guard(lambda: self._write_sidecar(text))
        self.run_config = text
        self.custom_data[RUN_CONFIG_KEY] = text

    def _write_sidecar(self, text: str) -> None:
        write_text_atomic(self.path / CONFIG_SIDECAR, text, durable=True)

    def add_topic(self, topic: str, msgtype: str, depth: int = 1000, latched: bool = False) -> None:
        """Declare a topic (done implicitly by write with default QoS)."""
        if topic in self._channels:
            return
        if msgtype not in typestore().fielddefs:
            raise BagError(f"topic {topic!r}: message type {msgtype!r} is unknown to the type store")
        qos = qos_text([make_qos(depth, latched)])

        def _add() -> None:
            if msgtype not in self._schemas:
                encoding, text = message_definition(msgtype)
                self._schemas[msgtype] = self._mcap.register_schema(msgtype, encoding, text.encode())
                self._type_hashes[msgtype] = type_hash(msgtype)
            self._channels[topic] = self._mcap.register_channel(
                topic,
                MESSAGE_ENCODING,
                self._schemas[msgtype],
                channel_metadata(qos, self._type_hashes[msgtype]),
            )

        self._guard(_add)
        self._topic_info[topic] = (msgtype, qos)
        self.counts[topic] = 0

    # ------------------------------------------------------------------ writing
    def write(self, topic: str, msgtype: str, timestamp_ns: int, data: bytes) -> None:
        """Append one serialized message with its log time (flushes on the bound)."""
        if topic not in self._channels:
            self.add_topic(topic, msgtype)
        cid = self._channels[topic]
        self._guard(lambda: self._mcap.add_message(cid, timestamp_ns, bytes(data), timestamp_ns, 0))
        self.counts[topic] += 1
        self._start, self._end = min(self._start, timestamp_ns), max(self._end, timestamp_ns)
        if self._pending == 0:
            self._pending_t0 = self._pending_t1 = timestamp_ns
        else:
            self._pending_t0 = min(self._pending_t0, timestamp_ns)
            self._pending_t1 = max(self._pending_t1, timestamp_ns)
        self._pending += 1
        self._pending_bytes += len(data) + _RECORD_OVERHEAD
        if (
            self._pending >= self.flush_messages
            or self._pending_t1 - self._pending_t0 >= self.flush_period_ns
            or self._pending_bytes >= CHUNK_BYTES
        ):
            self._close_chunk(durable=False)

    @property
    def pending(self) -> int:
        """Messages given to write() and not yet handed to the operating system."""
        return self._pending

    def _close_chunk(self, durable: bool) -> None:
        stream = self._stream
        assert stream is not None

        def _flush() -> None:
            self._mcap.flush()  # closes the chunk (CRC-32) and its message index, stream.flush()
            if durable:
                os.fsync(stream.fileno())

        had = self._pending
        self._guard(_flush)
        if had:
            self.chunks_flushed += 1
        self._pending = self._pending_bytes = 0

    def flush(self) -> None:
        """Close the pending chunk (if it holds messages) and push it to the disk (fsync)."""
        if self._stream is None or self.failed or self.closed:
            return
        self._close_chunk(durable=True)
        self.last_flush = time.monotonic()

    def close(self) -> None:
        """Finalize: MCAP summary/index and metadata.yaml.

        After a write failure (``failed``) the file is only closed: the flushed chunks stay on
        disk unfinalized and the caller decides whether to run ``repair_bag`` (the recorder
        does; ``lubrig bag repair`` can retry later). close() never repairs by itself.
        """
        if self.closed:
            return
        self.closed = True
        if self.failed:
            self._abort()
            return
        topics = [(t, *self._topic_info[t], self.counts[t]) for t in self._channels]
        hashes = {t: self._type_hashes[self._topic_info[t][0]] for t in self._channels}
        meta = metadata_dict(self.mcap_path.name, topics, self._start, self._end, self.custom_data, hashes)
        yaml_text, record_text = metadata_texts(meta)
        stream = self._stream
        assert stream is not None

        def _finish() -> None:
            self._mcap.flush()
            self.chunks_flushed += 1 if self._pending else 0
            self._pending = self._pending_bytes = 0
            self._mcap.add_metadata("rosbag2", {"serialized_metadata": record_text})
            self._mcap.finish()
            stream.flush()
            os.fsync(stream.fileno())
            stream.close()
            write_text_atomic(self.path / "metadata.yaml", yaml_text, durable=True)

        try:
            self._guard(_finish)
        except BagError:
            self._abort()
            raise
        self._stream = None

    def _abort(self) -> None:
        stream, self._stream = self._stream, None
        if stream is not None:
            with contextlib.suppress(OSError):
                stream.close()

    def _guard(self, action: Callable[[], object]) -> None:
        if self.failed:
            raise BagError(self.failed)
        try:
            action()
        except OSError as exc:
            self._abort()
            lost = self._recount()
            self.failed = (
                f"writing bag {str(self.path)!r} failed: {exc.strerror or exc} "
                f"({lost} messages not yet flushed are lost)"
            )
            raise BagError(self.failed) from exc

    def _recount(self) -> int:
        """After a failure: counts := messages in the file's intact chunks; returns the loss."""
        on_disk = {t: 0 for t in self.counts}
        if self.mcap_path.is_file():
            topic_of: dict[int, str] = {}
            with contextlib.suppress(OSError):
                for rec in scan(self.mcap_path, ScanResult()):
                    if isinstance(rec, Channel):
                        topic_of[rec.id] = rec.topic
                    elif isinstance(rec, Message) and rec.channel_id in topic_of:
                        topic = topic_of[rec.channel_id]
                        on_disk[topic] = on_disk.get(topic, 0) + 1
        self.lost = {t: n - on_disk.get(t, 0) for t, n in self.counts.items() if n > on_disk.get(t, 0)}
        self.counts = on_disk
        return sum(self.lost.values())
