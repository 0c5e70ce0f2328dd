"""`lubrig sweep --scheduler tcp://...` on a real Dask cluster: separate scheduler and worker processes.

The cluster is `dask scheduler` plus one `dask worker --no-nanny` process per worker (so a worker's
pid is the pid recorded in the table's `worker` column, and SIGKILL of that process loses the worker
for good), all on 127.0.0.1 with free ports; the sweep is the `lubrig` console script.
"""

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest
import yaml
from distributed import Client

from lubrig_ros.sweep import load_spec, run_sweep

pytestmark = pytest.mark.slow  # a Dask scheduler and worker processes per test
BIN = Path(sys.executable).parent
LUBRIG, DASK = BIN / "lubrig", BIN / "dask"
TIMING = ("simulate_seconds", "point_seconds", "worker", "started_at", "finished_at")
KEY_PREFIX = "lubrig-sweep-"
CYCLE = {
    "rig": {"convention": "paper"},
    "band": {
        "kind": "cycle",
        "low_velocity": 1e-7,
        "high_velocity": 1e-6,
        "plateau_time": 0.01,
        "ramp_time": 0.2,
    },
}


def comparable(table):
    return table.drop_columns(list(TIMING))


def assert_same_table(got, expected):
    """Equal apart from timing columns; on failure name the columns and rows that differ."""
    a, b = comparable(got), comparable(expected)
    if a.equals(b):
        return
    rows_a, rows_b = a.to_pylist(), b.to_pylist()
    diffs = [
        (ra["index"], key, ra[key], rb[key])
        for ra, rb in zip(rows_a, rows_b, strict=False)
        for key in ra
        if ra[key] != rb.get(key)
    ]
    raise AssertionError(
        f"{len(rows_a)} vs {len(rows_b)} rows; differing (index, column, got, expected): {diffs[:12]}"
    )


def wait_for(condition, timeout, what, alive=()):
    """Poll `condition` until true; fail after `timeout` s or as soon as a process in `alive` exits."""
    deadline = time.monotonic() + timeout
    while not condition():
        for proc in alive:
            assert proc.poll() is None, f"{what}: process {proc.args[:2]} exited with {proc.returncode}"
        assert time.monotonic() < deadline, f"{what}: not within {timeout} s"
        time.sleep(0.02)


def stop(proc):
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)


@contextlib.contextmanager
def dask_cluster(tmp_path, n_workers, scheduler_env=None):
    """Yield (address, client, {worker pid: worker process}) of a fresh scheduler + workers."""
    scheduler_file = tmp_path / "scheduler.json"
    procs = []
    client = None
    try:
        scheduler = subprocess.Popen(
            [
                str(DASK),
                "scheduler",
                "--host",
                "127.0.0.1",
                "--port",
                "0",
                "--no-dashboard",
                "--scheduler-file",
                str(scheduler_file),
                "--idle-timeout",
                "300",
            ],
            cwd=tmp_path,
            env={**os.environ, **(scheduler_env or {})},
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        procs.append(scheduler)
        # the file is written once the scheduler listens (then read whole: it is small)
        wait_for(
            lambda: scheduler_file.exists() and scheduler_file.stat().st_size > 0,
            60,
            "scheduler file",
            [scheduler],
        )
        wait_for(lambda: "address" in scheduler_file.read_text(), 10, "scheduler address", [scheduler])
        address = json.loads(scheduler_file.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")
        workers = []
        for i in range(n_workers):
            workers.append(
                subprocess.Popen(
                    [
                        str(DASK),
                        "worker",
                        "--scheduler-file",
                        str(scheduler_file),
                        "--host",
                        "127.0.0.1",
                        "--nworkers",
                        "1",
                        "--nthreads",
                        "1",
                        "--no-nanny",
                        "--no-dashboard",
                        "--death-timeout",
                        "60",
                        "--local-directory",
                        str(tmp_path / f"worker{i}"),
                    ],
                    cwd=tmp_path,
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                )
            )
        procs.extend(workers)
        client = Client(address, timeout="30s")
        if n_workers:
            client.wait_for_workers(n_workers, timeout=90)
        pids = client.run(os.getpid)
        by_pid = {proc.pid: proc for proc in workers}
        assert set(pids.values()) == set(by_pid), "the workers are the processes started here"
        yield address, client, by_pid
    finally:
        if client is not None:
            client.close()
        for proc in reversed(procs):  # workers first, then the scheduler
            stop(proc)


def pid_of(row):
    return int(row["worker"].rsplit(":", 1)[1])


def sweep_spec(tmp_path, name, duration, num):
    path = tmp_path / f"{name}.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "name": name,
                "base": {**CYCLE, "simulation": {"duration": duration}},
                "axes": [
                    {"parameter": "band.plateau_time", "linspace": {"start": 0.01, "stop": 0.5, "num": num}}
                ],
            }
        )
    )
    return path


def serial_table(spec_path, out):
    return pq.read_table(
        run_sweep(load_spec(spec_path), out, scheduler="serial", progress=None, figures=False).table
    )


def test_remote_scheduler_sweep_equals_serial(tmp_path):
    spec_path = sweep_spec(tmp_path, "remote", 2.0, 4)
    out = tmp_path / "cluster"
    with dask_cluster(tmp_path, 2) as (address, client, workers):
        run = subprocess.run(
            [
                str(LUBRIG),
                "sweep",
                str(spec_path),
                "--out",
                str(out),
                "--scheduler",
                address,
                "--no-figures",
                "--quiet",
            ],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert run.returncode == 0, run.stderr
        assert "(0 resumed, 4 computed, 0 failed)" in run.stdout
        # the driver released its results: nothing of the sweep is left on the cluster
        assert not [
            k
            for k in client.run_on_scheduler(lambda dask_scheduler: list(dask_scheduler.tasks))
            if str(k).startswith(KEY_PREFIX)
        ]
        assert all(proc.poll() is None for proc in workers.values())
    table = pq.read_table(out / "results.parquet")
    rows = table.to_pylist()
    assert [r["index"] for r in rows] == [0, 1, 2, 3] and {r["status"] for r in rows} == {"ok"}
    # every point ran in one of the cluster's worker processes, not in the driver
    assert {pid_of(r) for r in rows} <= set(workers)
    expected = serial_table(spec_path, tmp_path / "serial")
    assert {pid_of(r) for r in expected.to_pylist()} == {os.getpid()}
    assert_same_table(table, expected)
    assert table.schema.metadata[b"lubrig_sweep_spec"] == expected.schema.metadata[b"lubrig_sweep_spec"]


def kill_a_busy_worker(client, out, sweep):
    """Once a point is finished, SIGKILL a worker that holds sweep tasks; return its pid, keys and
    how many points were finished by then."""
    address_pid = client.run(os.getpid)
    running = {}

    def a_worker_is_busy():
        if not list((out / "points").glob("*.json")):
            return False
        for addr, keys in client.processing().items():
            keys = [str(k) for k in keys if str(k).startswith(KEY_PREFIX)]
            if keys:  # one thread per worker: one of them runs, the others wait there
                running[addr] = keys
                return True
        return False

    wait_for(a_worker_is_busy, 120, "a point running on a worker", [sweep])
    ((address, keys),) = running.items()
    os.kill(address_pid[address], signal.SIGKILL)
    return address_pid[address], keys, len(list((out / "points").glob("*.json")))


def start_sweep(spec_path, out, address, *options):
    return subprocess.Popen(
        [
            str(LUBRIG),
            "sweep",
            str(spec_path),
            "--out",
            str(out),
            "--scheduler",
            address,
            "--no-figures",
            "--quiet",
            *options,
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def test_worker_killed_mid_sweep_points_rescheduled_each_once(tmp_path):
    spec_path = sweep_spec(tmp_path, "lostworker", 150.0, 12)
    out = tmp_path / "cluster"
    with dask_cluster(tmp_path, 2) as (address, client, workers):
        sweep = start_sweep(spec_path, out, address)
        try:
            victim, victim_keys, done_at_kill = kill_a_busy_worker(client, out, sweep)
            workers[victim].wait(timeout=10)
            stdout, stderr = sweep.communicate(timeout=120)
        finally:
            stop(sweep)
        assert workers[victim].returncode == -signal.SIGKILL
        assert sweep.returncode == 0, stderr
        (survivor,) = set(workers) - {victim}
        assert workers[survivor].poll() is None
    assert done_at_kill < 12, "the sweep ended before the worker was killed"
    # Dask moved the dead worker's tasks to the other one (allowed-failures 3 by default)
    assert "(0 resumed, 12 computed, 0 failed)" in stdout
    rows = pq.read_table(out / "results.parquet").to_pylist()
    assert sorted(r["index"] for r in rows) == list(range(12))
    assert {r["status"] for r in rows} == {"ok"}
    by_id = {r["point_id"]: r for r in rows}
    # the points the dead worker held were computed again by the surviving one
    lost = [by_id[key[len(KEY_PREFIX) :]] for key in victim_keys]
    assert any(pid_of(r) == survivor for r in lost), [r["worker"] for r in lost]
    assert {pid_of(r) for r in rows} <= {victim, survivor}
    journal = [json.loads(line) for line in (out / "journal.jsonl").read_text().splitlines()]
    written = [e["point_id"] for e in journal if e["event"] == "point"]
    assert len(written) == len(set(written)) == 12  # each point written exactly once
    expected = serial_table(spec_path, tmp_path / "serial")
    assert_same_table(pq.read_table(out / "results.parquet"), expected)


def test_killed_worker_error_is_recorded_then_retried(tmp_path):
    # allowed-failures 0: the scheduler gives up on a task at its first lost worker (KilledWorker)
    spec_path = sweep_spec(tmp_path, "killedworker", 150.0, 8)
    out = tmp_path / "cluster"
    env = {"DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES": "0"}
    with dask_cluster(tmp_path, 2, scheduler_env=env) as (address, client, workers):
        sweep = start_sweep(spec_path, out, address)
        try:
            victim, victim_keys, done_at_kill = kill_a_busy_worker(client, out, sweep)
            stdout, stderr = sweep.communicate(timeout=120)
        finally:
            stop(sweep)
        assert sweep.returncode == 0, stderr
        assert done_at_kill < 8
        rows = pq.read_table(out / "results.parquet").to_pylist()
        assert sorted(r["index"] for r in rows) == list(range(8))
        failed = [r for r in rows if r["status"] != "ok"]
        assert failed, "no point failed with the worker"
        assert f"(0 resumed, 8 computed, {len(failed)} failed)" in stdout
        for row in failed:
            assert row["status"] == "error" and row["error"].startswith("KilledWorker: "), row["error"]
            assert row["x_peak_to_peak"] is None
        # the failures are the dead worker's: the point it was running is among them
        assert {r["point_id"] for r in failed} & {k[len(KEY_PREFIX) :] for k in victim_keys}
        retry = subprocess.run(
            [
                str(LUBRIG),
                "sweep",
                str(spec_path),
                "--out",
                str(out),
                "--scheduler",
                address,
                "--no-figures",
                "--quiet",
                "--retry-failed",
            ],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert retry.returncode == 0, retry.stderr
        assert f"({8 - len(failed)} resumed, {len(failed)} computed, 0 failed)" in retry.stdout
        (survivor,) = set(workers) - {victim}
    table = pq.read_table(out / "results.parquet")
    retried = {r["point_id"]: r for r in table.to_pylist()}
    assert all(pid_of(retried[r["point_id"]]) == survivor for r in failed)
    expected = serial_table(spec_path, tmp_path / "serial")
    assert_same_table(table, expected)


def test_scheduler_without_workers_fails_in_one_line(tmp_path):
    spec_path = sweep_spec(tmp_path, "lonely", 1.0, 2)
    with dask_cluster(tmp_path, 0) as (address, _client, _workers):
        run = subprocess.run(
            [
                str(LUBRIG),
                "sweep",
                str(spec_path),
                "--out",
                str(tmp_path / "out"),
                "--scheduler",
                address,
                "--worker-timeout",
                "3",
                "--no-figures",
                "--quiet",
            ],
            capture_output=True,
            text=True,
            timeout=60,
        )
    assert run.returncode == 2
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and f"no Dask worker joined {address} within 3 s" in lines[0], run.stderr
    assert not list((tmp_path / "out").glob("points/*"))  # nothing computed
