"""Crash-safe rosbag2/MCAP writer on top of rosbags' rosbag2 Writer.

Chunks are zstd-compressed. rosbags closes a chunk every 1 MiB; :meth:`BagWriter.flush` also
closes the pending chunk and flushes it to disk, so that after a hard kill the file is readable
up to the last flush (see :mod:`lubrig_ros.bag.repair`, which the caller runs explicitly).
"""

from __future__ import annotations

import contextlib
import os
import time
from pathlib import Path

from rosbags.interfaces import (
    Connection,
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode

from lubrig_ros import __version__
from lubrig_ros.app.fileio import write_text_atomic
from lubrig_ros.bag.errors import BagError
from lubrig_ros.bag.layout import CONFIG_SIDECAR, RUN_CONFIG_KEY, VERSION_KEY, typestore


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
    """A rosbag2 bag (MCAP storage, zstd chunks) holding serialized CDR messages.

    Usage: ``w = BagWriter(path, run_config=text); w.write(topic, msgtype, t_ns, cdr); w.flush();
    w.close()``. Any OSError while writing (disk full, ...) is raised as BagError; the writer is
    then dead (``failed``) and :meth:`close` only tries to finalize what was flushed.
    """

    def __init__(self, path: str | Path, run_config: str | None = None) -> None:
        self.path = Path(path)
        check_output_path(self.path)
        self.run_config = run_config
        self._writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        self._writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        self._writer.set_custom_data(VERSION_KEY, __version__)
        if run_config is not None:
            self._writer.set_custom_data(RUN_CONFIG_KEY, run_config)
        self._connections: dict[str, Connection] = {}
        self.counts: dict[str, int] = {}
        self.failed: str | None = None
        self.closed = False
        try:
            self._writer.open()
        except OSError as exc:
            raise BagError(f"cannot create bag {str(self.path)!r}: {exc.strerror or exc}") from exc
        except Exception as exc:  # rosbags WriterError
            raise BagError(f"cannot create bag {str(self.path)!r}: {exc}") from exc
        if run_config is not None:
            self._guard(lambda: self._write_sidecar(run_config))
        self.last_flush = time.monotonic()

    def set_run_config(self, text: str) -> None:
        """Store the run configuration (YAML) in metadata custom_data."""
        if text != self.run_config:
            self._guard(lambda: self._write_sidecar(text))
        self.run_config = text
        self._writer.set_custom_data(RUN_CONFIG_KEY, text)

    def _write_sidecar(self, text: str) -> None:
        write_text_atomic(self.path / CONFIG_SIDECAR, text, durable=True)

    def add_topic(self, topic: str, msgtype: str, depth: int = 1000, latched: bool = False) -> None:
        """Declare a topic (done implicitly by write with default QoS)."""
        if topic in self._connections:
            return
        if msgtype not in typestore().fielddefs:
            raise BagError(f"topic {topic!r}: message type {msgtype!r} is unknown to the type store")
        self._guard(
            lambda: self._connections.__setitem__(
                topic,
                self._writer.add_connection(
                    topic, msgtype, typestore=typestore(), offered_qos_profiles=[make_qos(depth, latched)]
                ),
            )
        )
        self.counts[topic] = 0

    def write(self, topic: str, msgtype: str, timestamp_ns: int, data: bytes) -> None:
        """Append one serialized message with its log time."""
        if topic not in self._connections:
            self.add_topic(topic, msgtype)
        conn = self._connections[topic]
        self._guard(lambda: self._writer.write(conn, timestamp_ns, data))
        self.counts[topic] += 1

    def flush(self) -> None:
        """Close the pending chunk (if it holds messages) and push it to the disk."""
        storage = self._writer.storage
        if storage is None or self.failed:
            return

        def _flush() -> None:
            if storage.chunk.msgs:  # rosbags McapWriter internals: pending chunk
                storage.close_chunk()
            storage.bio.flush()
            os.fsync(storage.bio.fileno())

        self._guard(_flush)
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
        try:
            self._writer.close()
        except OSError as exc:
            self.failed = f"cannot finalize bag {str(self.path)!r}: {exc.strerror or exc}"
            self.closed = False
            self.close()
            raise BagError(self.failed) from exc

    def _abort(self) -> None:
        storage = self._writer.storage
        self._writer.storage = None
        if storage is not None:
            with contextlib.suppress(OSError):
                storage.bio.close()

    def _guard(self, action: object) -> None:
        if self.failed:
            raise BagError(self.failed)
        try:
            action()  # type: ignore[operator]
        except OSError as exc:
            self.failed = f"writing bag {str(self.path)!r} failed: {exc.strerror or exc}"
            raise BagError(self.failed) from exc

