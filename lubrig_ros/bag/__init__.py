"""Recording and reading rig data as rosbag2 bags (MCAP storage, zstd chunks).

Public API:

- :class:`Bag` — a bag read once: its check, summary, messages and arrays from one walk of the file.
- :class:`BagWriter` — write serialized CDR messages with log times; ``flush()``; ``close()``.
- :func:`check_bag` / :func:`bag_info` — full integrity check and summary (topics, counts, duration,
  custom_data with the run configuration).
- :func:`read_messages` — (topic, type, log_time_ns, cdr) in log-time order.
- :func:`read_arrays` — numpy arrays per topic (``arrays["/lubrig/displacement"]["data"]``).
- :func:`repair_bag` — rebuild summary/index and metadata.yaml after a crash (a tool the caller
  runs; ``BagWriter.close`` never repairs).
"""

from lubrig_ros.bag.errors import BagError
from lubrig_ros.bag.layout import RUN_CONFIG_KEY, VERSION_KEY, find_mcap
from lubrig_ros.bag.reader import (
    Bag,
    BagSummary,
    TopicArrays,
    TopicSummary,
    bag_info,
    check_bag,
    read_arrays,
    read_messages,
)
from lubrig_ros.bag.repair import RepairReport, repair_bag
from lubrig_ros.bag.writer import BagWriter

__all__ = [
    "RUN_CONFIG_KEY",
    "VERSION_KEY",
    "Bag",
    "BagError",
    "BagSummary",
    "BagWriter",
    "RepairReport",
    "TopicArrays",
    "TopicSummary",
    "bag_info",
    "check_bag",
    "find_mcap",
    "read_arrays",
    "read_messages",
    "repair_bag",
]
