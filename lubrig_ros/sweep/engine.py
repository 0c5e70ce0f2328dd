"""Run a sweep's pending points on Dask (embedded LocalCluster or a remote scheduler) or serially.

The driver submits every pending point, writes each record durably as soon as it arrives (so a
killed sweep resumes where it stopped), shows progress with an estimate of the time left, then
assembles the table and the maps from the records on disk.
"""

from __future__ import annotations

import logging
import os
import sys
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

from lubrig_ros.core.errors import InputError

from .point import run_point, warm_up
from .spec import Point, SweepSpec
from .store import SweepStore

#: --scheduler values besides a scheduler address.
LOCAL, SERIAL = "local", "serial"
ADDRESS_PREFIXES = ("tcp://", "tls://", "inproc://", "ucx://")


def check_scheduler(scheduler: str, workers: int | None) -> None:
    """Validate --scheduler and --workers before any work."""
    if scheduler not in (LOCAL, SERIAL) and not scheduler.startswith(ADDRESS_PREFIXES):
        raise InputError(
            f"--scheduler {scheduler!r} is not valid; expected {LOCAL!r}, {SERIAL!r} or an address like tcp://host:8786"
        )
    if workers is not None:
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise InputError(f"--workers {workers!r} is not valid; expected an integer >= 1")
        if scheduler not in (LOCAL,):
            raise InputError(f"--workers applies to --scheduler {LOCAL!r} only (got {scheduler!r})")


class Progress:
    """Progress lines on a stream (stderr): points done, rate, estimated time left."""

    def __init__(self, name: str, total: int, resumed: int, stream: TextIO | None, interval: float = 1.0):
        self.name, self.total, self.resumed = name, total, resumed
        self.stream, self.interval = stream, interval
        self.done = self.failed = 0
        self.start = time.perf_counter()
        self.last = -float("inf")

    def restart(self) -> None:
        """Start the clock now (after the cluster start and warm-up)."""
        self.start = time.perf_counter()

    def update(self, record: dict[str, Any]) -> None:
        """Count one finished point; print at most every `interval` seconds, and at the end."""
        self.done += 1
        self.failed += record.get("status") != "ok"
        now = time.perf_counter()
        pending = self.total - self.resumed
        if self.stream is None or (now - self.last < self.interval and self.done < pending):
            return
        self.last = now
        elapsed = now - self.start
        rate = self.done / elapsed if elapsed > 0 else float("inf")
        left = (pending - self.done) / rate if rate > 0 else float("inf")
        print(
            f"sweep {self.name}: {self.resumed + self.done}/{self.total} points"
            f" ({self.resumed} resumed, {self.failed} failed), {rate:.3g} points/s,"
            f" about {_duration(left)} left",
            file=self.stream,
            flush=True,
        )


def _duration(seconds: float) -> str:
    if seconds != seconds or seconds == float("inf"):
        return "? s"
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.1f} h"


@dataclass
class SweepResult:
    """What a sweep run did."""

    directory: Path
    total: int
    resumed: int
    computed: int
    failed: int
    wall_seconds: float
    warm_up_seconds: dict[str, float] = field(default_factory=dict)
    table: Path | None = None
    figures: list[Path] = field(default_factory=list)


def _serial(
    points: list[Point], point_function: Callable[[Point], dict[str, Any]] = run_point
) -> Iterator[dict[str, Any]]:
    for point in points:
        yield point_function(point)


def _dask(
    points: list[Point],
    scheduler: str,
    workers: int | None,
    warm: dict[str, float],
    ready: Callable[[], None],
    worker_timeout: float = 60.0,
    point_function: Callable[[Point], dict[str, Any]] = run_point,
) -> Iterator[dict[str, Any]]:
    from distributed import Client, LocalCluster, as_completed

    cluster = None
    if scheduler == LOCAL:
        cluster = LocalCluster(
            n_workers=workers or os.cpu_count() or 1,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            silence_logs=logging.ERROR,
        )
        client = Client(cluster)
    else:
        client = Client(scheduler, timeout="30s")
    try:
        if cluster is None:  # a remote scheduler may have no worker: fail instead of waiting forever
            try:
                client.wait_for_workers(1, timeout=worker_timeout)
            except TimeoutError:
                raise InputError(
                    f"no Dask worker joined {scheduler} within {worker_timeout:g} s; start one with "
                    f"`dask worker {scheduler} --nthreads 1` (or raise --worker-timeout)"
                ) from None
        warm.update(client.run(warm_up))
        ready()  # cluster up and kernels loaded: the progress estimate starts here
        futures = client.map(
            point_function, points, pure=False, key=[f"lubrig-sweep-{p.point_id}" for p in points]
        )
        by_key = {future.key: point for future, point in zip(futures, points, strict=True)}
        for future in as_completed(futures):
            point = by_key[future.key]
            try:
                yield future.result()
            except Exception as exc:  # worker lost, unpicklable result, ...: the point failed
                yield {
                    "point_id": point.point_id,
                    "index": point.index,
                    "values": point.values,
                    "status": "error",
                    "error": f"{type(exc).__name__}: {exc}",
                    "finished_at": time.time(),
                }
            future.release()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def run_sweep(
    spec: SweepSpec,
    out: str | Path,
    *,
    workers: int | None = None,
    scheduler: str = LOCAL,
    retry_failed: bool = False,
    figures: bool = True,
    progress: TextIO | None = sys.stderr,
    on_record: Callable[[dict[str, Any]], None] | None = None,
    worker_timeout: float = 60.0,
    point_function: Callable[[Point], dict[str, Any]] = run_point,
) -> SweepResult:
    """Compute every point of `spec` not already finished in `out`; write the table and maps.

    `point_function` (a picklable top-level function of a Point returning its record, never
    raising; default run_point) lets a study measure more per point on the same engine.
    """
    check_scheduler(scheduler, workers)
    store = SweepStore(out, spec)
    store.check()  # before any write: a bad directory leaves nothing behind
    clock = time.perf_counter()
    done = store.finished()
    if retry_failed:
        done = {key: rec for key, rec in done.items() if rec.get("status") == "ok"}
    pending = [p for p in spec.points if p.point_id not in done]
    store.open()
    run_id = uuid.uuid4().hex[:12]
    store.journal(
        {"event": "start", "pid": os.getpid(), "pending": len(pending), "resumed": len(done)}, run_id
    )
    bar = Progress(spec.name, len(spec.points), len(done), progress)
    warm: dict[str, float] = {}
    failed = 0
    if pending:
        if scheduler == SERIAL:
            warm["serial"] = warm_up()
            records = _serial(pending, point_function)
        else:
            records = _dask(pending, scheduler, workers, warm, bar.restart, worker_timeout, point_function)
        for record in records:
            store.write(record, run_id)
            failed += record["status"] != "ok"
            bar.update(record)
            if on_record is not None:
                on_record(record)
    store.journal({"event": "end", "computed": len(pending), "failed": failed}, run_id)
    all_records = list(store.finished().values())
    table = store.write_table(all_records)
    paths: list[Path] = []
    if figures:
        from ..figures.sweep import write_maps

        paths = write_maps(table, store.directory)
    return SweepResult(
        directory=store.directory,
        total=len(spec.points),
        resumed=len(done),
        computed=len(pending),
        failed=failed,
        wall_seconds=time.perf_counter() - clock,
        warm_up_seconds=warm,
        table=table,
        figures=paths,
    )
