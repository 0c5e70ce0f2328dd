"""The test suite's one process harness as fixtures, and its tiers.

Fixtures (implementation in test/support/lubrig_testkit/harness.py, shared with bench/):

- ``ros_domain``: a ROS_DOMAIN_ID no other test run on this machine holds while the test runs;
  at its end any process still on that domain (whoever started it: procs, the test's own Popen,
  a child that left its process group) is killed and the test errors naming it.
- ``ros_env``: os.environ for processes on that domain (localhost discovery, unbuffered output).
- ``procs``: starts node processes on ``ros_env`` (``procs.node("plant", mode="realtime")``,
  ``procs.module(...)``, ``procs.script(...)``, ``procs.run_module(...)``), logs under tmp_path;
  every process still running at the end of the test gets SIGINT, then SIGKILL of its group.
- ``probe``: an rclpy node on ``ros_domain`` that records what it subscribes to and waits on
  conditions (``probe.wait_for(predicate, timeout)``); the timeouts only guard against a hang.
- ``ros_module_domain``: a domain held for a whole module (for a module-scoped expensive run).
- ``cpu_hogs``: ``cpu_hogs(2)`` starts two busy processes beside the test (killed at its end),
  for tests that assert behaviour on a loaded machine (status, exit code, every sample; never a rate).

A pytest ended by SIGTERM tears its fixtures down as on a Ctrl-C (nothing started is left behind).

Tiers: a test that uses one of these fixtures is marked ``ros`` automatically (a module may also
set ``pytestmark = pytest.mark.ros``); long runs are marked ``slow``. ``make test-fast`` runs
``-m "not ros and not slow"``; ``make test`` runs everything.
"""

from __future__ import annotations

import signal
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

try:
    from lubrig_testkit.harness import DomainLease, Probe, Processes, kill_strays
    from lubrig_testkit.harness import ros_env as _ros_env
except ImportError as exc:  # pragma: no cover - a venv set up before the testkit existed
    raise ImportError(f"{exc}: the test helpers are not installed; run `make setup`") from exc

ROS_FIXTURES = {"ros_domain", "ros_env", "procs", "probe", "ros_module_domain"}


def _leased_domain() -> Iterator[int]:
    """A domain for the fixture's scope; then any process still on it is killed and named."""
    with DomainLease() as domain:
        yield domain
        strays = kill_strays(domain)
    assert not strays, f"processes left behind on ROS_DOMAIN_ID {domain} (killed): {strays}"


@pytest.fixture
def ros_domain() -> Iterator[int]:
    yield from _leased_domain()


@pytest.fixture(scope="module")
def ros_module_domain() -> Iterator[int]:
    yield from _leased_domain()


@pytest.fixture
def ros_env(ros_domain: int) -> dict[str, str]:
    return _ros_env(ros_domain)


@pytest.fixture
def procs(ros_env: dict[str, str], tmp_path: Path) -> Iterator[Processes]:
    processes = Processes(ros_env, tmp_path / "logs")
    try:
        yield processes
    finally:
        processes.stop_all(timeout=10)


@pytest.fixture
def probe(ros_domain: int) -> Iterator[Probe]:
    node = Probe(ros_domain)
    try:
        yield node
    finally:
        node.close()


@pytest.hookimpl(tryfirst=True)  # before -m deselects
@pytest.fixture
def cpu_hogs() -> Iterator[Callable[[int], None]]:
    """cpu_hogs(n): start n busy processes (`python3 -c 'while True: pass'`) for this test."""
    hogs: list[subprocess.Popen] = []

    def start(n: int) -> None:
        hogs.extend(subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n))

    try:
        yield start
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()


def _interrupted(signum: int, _frame: object) -> None:
    raise KeyboardInterrupt(f"signal {signum}")


def pytest_configure(config: pytest.Config) -> None:
    """SIGTERM (e.g. an outer `timeout`) ends pytest as a Ctrl-C does: the fixtures' teardown
    still runs, so the processes the tests started are stopped instead of left behind."""
    signal.signal(signal.SIGTERM, _interrupted)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark every test that uses a ROS fixture `ros`."""
    for item in items:
        if ROS_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.ros)


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """Never end silently with no tests: say so (the exit status stays 5, a failure for make)."""
    if exitstatus == pytest.ExitCode.NO_TESTS_COLLECTED:
        session.config.get_terminal_writer().line(
            "error: no tests were selected (check the -m/-k expression and the test paths)", red=True
        )
