"""The one process harness of the tests and benchmarks: ROS domains, node processes, a probe node.

test/conftest.py wraps these in fixtures (``ros_domain``, ``ros_env``, ``procs``, ``probe``);
bench/ scripts use them directly. Nothing here sleeps for a fixed time to let something happen:
every wait is on a condition, with a generous timeout that only guards against a hang.

- ``DomainLease()`` — a ROS_DOMAIN_ID no other test run on this machine holds: an exclusive
  ``flock`` on ``$TMPDIR/lubrig_ros_domains/<id>.lock`` for as long as the lease is open (the
  kernel drops it when the holder dies, so a crashed run never leaks an id). An id that a live
  process still runs on (a stray of a run killed before its teardown) is passed over.
- ``ros_env(domain)`` — os.environ with that domain, discovery on localhost, unbuffered output.
- ``Processes(env, log_dir)`` — starts node processes (``node(name, **params)``, ``module(...)``,
  ``script(...)``, ``command(argv)``), each in its own session with stdout/stderr in log files;
  ``stop_all()`` sends SIGINT, waits, then SIGKILLs the process group of anything left.
- ``kill_strays(domain)`` — at the end of a lease: names (and kills) any process still on the
  domain, wherever it came from.
- ``Probe(domain)`` — an rclpy node in its own context on the domain, spun in a thread, that
  records what it subscribes to and waits on conditions (``wait_for``, ``wait_for_count``).
- ``wait_until(condition, timeout, what)`` — poll a condition; AssertionError naming it otherwise.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from lubrig_ros.app.processes.discovery import discovery_environment
from lubrig_ros.app.processes.lifetime import die_with_parent

PYTHON = sys.executable


def child_setup(then: Callable[[], None] | None = None) -> Callable[[], None] | None:
    """A preexec_fn for a process started from this thread: `then`, and SIGTERM at the parent's death.

    The kernel sends the signal when the *thread* that started the child ends, so it is asked
    for only from the main thread (a helper thread's children are stopped by the teardown).
    """
    if threading.current_thread() is not threading.main_thread():
        return then

    def setup() -> None:
        die_with_parent(signal.SIGTERM)  # its own SIGTERM handling stops what it started
        if then is not None:
            then()

    return setup


BIN = Path(PYTHON).parent
# 10..99: clear of the default domain 0 and of ids whose DDS ports fall in Linux's ephemeral range
DOMAIN_IDS = range(10, 100)
LOCK_DIR = Path(tempfile.gettempdir()) / "lubrig_ros_domains"
#: s after its state_block subscription matched that a probe's consumer waits for its other
#: subscriptions to match the publishers the graph shows (then it reports ready all the same)
LAG_WAIT_S = 5.0


def wait_until(
    condition: Callable[[], object],
    timeout: float,
    what: str = "condition",
    alive: tuple[NodeProcess, ...] = (),
    every: float = 0.02,
) -> None:
    """Poll condition every `every` s until true; AssertionError after timeout s or if a process dies."""
    end = time.monotonic() + timeout
    while not condition():
        for proc in alive:
            if proc.popen.poll() is not None:
                raise AssertionError(
                    f"{what}: {proc.name} exited with {proc.popen.returncode}:\n{proc.log()}"
                )
        if time.monotonic() > end:
            raise AssertionError(f"{what}: not within {timeout} s")
        time.sleep(every)


def domain_users(domain: int) -> list[str]:
    """Processes other than this one with ROS_DOMAIN_ID=domain in their environment ("pid argv").

    Read from /proc (this user's processes); a process that ends while it is read is left out.
    """
    wanted, users = f"ROS_DOMAIN_ID={domain}".encode(), []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            if wanted not in (entry / "environ").read_bytes().split(b"\0"):
                continue
            argv = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        users.append(f"{entry.name} {argv.strip()}")
    return users


def kill_strays(domain: int, grace: float = 5.0) -> list[str]:
    """At the end of a lease: processes still on `domain` after `grace` s, each SIGKILLed.

    Whatever started them (procs, a Popen of the test, a child that left its process group or
    was forked by a node): on a leased domain nothing may outlive the test. Empty when
    everything ended as it should.
    """
    end = time.monotonic() + grace
    while (left := domain_users(domain)) and time.monotonic() < end:
        time.sleep(0.1)
    for user in left:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.kill(int(user.split(" ", 1)[0]), signal.SIGKILL)
    return left


class DomainLease:
    """An exclusive ROS_DOMAIN_ID for this machine while open (flock on a file per id)."""

    def __init__(self) -> None:
        LOCK_DIR.mkdir(parents=True, exist_ok=True)
        ids = list(DOMAIN_IDS)
        start = os.getpid() % len(ids)  # concurrent runs start their search at different ids
        self._file: IO[bytes] | None = None
        for k in range(len(ids)):
            domain = ids[(start + k) % len(ids)]
            f = open(LOCK_DIR / f"{domain}.lock", "ab")  # noqa: SIM115 (held for the lease)
            try:
                fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                f.close()
                continue
            if domain_users(domain):  # strays of a run that ended without its teardown
                f.close()
                continue
            self._file, self.domain = f, domain
            return
        raise RuntimeError(f"all ROS domain ids {ids[0]}..{ids[-1]} are in use on this machine")

    def close(self) -> None:
        """Release the id."""
        if self._file is not None:
            self._file.close()  # closing drops the flock
            self._file = None

    def __enter__(self) -> int:
        return self.domain

    def __exit__(self, *exc: object) -> None:
        self.close()


def ros_env(domain: int) -> dict[str, str]:
    """os.environ for processes on domain: localhost discovery, unbuffered output and logging."""
    env = discovery_environment(os.environ).env  # this host only, as lubrig rig does
    env["ROS_DOMAIN_ID"] = str(domain)
    env["PYTHONUNBUFFERED"] = "1"
    env["RCUTILS_LOGGING_BUFFERED_STREAM"] = "0"
    return env


class NodeProcess:
    """A started process in its own session; stdout and stderr in files under log_dir."""

    def __init__(
        self,
        name: str,
        argv: list[str],
        env: dict[str, str],
        log_dir: Path,
        cwd: str | Path | None = None,
        preexec_fn: Callable[[], None] | None = None,
    ) -> None:
        self.name, self.argv = name, argv
        log_dir.mkdir(parents=True, exist_ok=True)
        stem = name
        k = 1
        while (log_dir / f"{stem}.out").exists():
            k += 1
            stem = f"{name}-{k}"
        self.stdout_path, self.stderr_path = log_dir / f"{stem}.out", log_dir / f"{stem}.err"
        with open(self.stdout_path, "wb") as out, open(self.stderr_path, "wb") as err:
            self.popen = subprocess.Popen(
                argv,
                env=env,
                cwd=cwd,
                stdout=out,
                stderr=err,
                start_new_session=True,
                preexec_fn=child_setup(preexec_fn),
            )

    @property
    def pid(self) -> int:
        """Process id (also the id of its process group)."""
        return self.popen.pid

    def running(self) -> bool:
        """True while the process has not exited."""
        return self.popen.poll() is None

    def output(self) -> str:
        """stdout so far."""
        return self.stdout_path.read_text(errors="replace")

    def errors(self) -> str:
        """stderr so far."""
        return self.stderr_path.read_text(errors="replace")

    def log(self) -> str:
        """stdout and stderr so far, labelled (for failure messages)."""
        return f"--- {self.name} stdout:\n{self.output()}\n--- {self.name} stderr:\n{self.errors()}"

    def wait_for_output(self, text: str, timeout: float = 30.0) -> None:
        """Wait until text appears in stdout; AssertionError with the logs on timeout or exit."""
        end = time.monotonic() + timeout
        while text not in self.output():
            if self.popen.poll() is not None and text not in self.output():
                raise AssertionError(
                    f"{text!r} not printed by {self.argv} (exit {self.popen.returncode}):\n{self.log()}"
                )
            if time.monotonic() > end:
                raise AssertionError(f"{text!r} not printed by {self.argv} within {timeout} s:\n{self.log()}")
            time.sleep(0.02)

    def wait(self, timeout: float = 60.0) -> int:
        """Wait for exit and return the status; kills the group and raises on timeout."""
        try:
            return self.popen.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.kill()
            raise AssertionError(f"{self.argv} did not exit within {timeout} s:\n{self.log()}") from None

    def stop(self, sig: int = signal.SIGINT, timeout: float = 20.0) -> int:
        """Send sig, wait up to timeout for the exit status; SIGKILL the group and raise otherwise."""
        if self.popen.poll() is None:
            self.popen.send_signal(sig)
        try:
            status = self.popen.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            state = self._signal_state()
            self.kill()
            raise AssertionError(
                f"{self.argv} did not stop within {timeout} s ({state}):\n{self.log()}"
            ) from None
        self._kill_group()  # children left behind by the leader (e.g. recorder workers)
        return status

    def _signal_state(self) -> str:
        """How a process that ignores a stop handles signals: /proc's Sig* lines, then its stacks.

        SIGUSR1 makes a process that registered faulthandler for it (the nodes, `lubrig rig`)
        print every thread's Python stack to its stderr, which the log shows.
        """
        try:
            lines = Path(f"/proc/{self.pid}/status").read_text().splitlines()
        except OSError:
            return "no /proc status"
        state = "; ".join(line.replace("\t", " ") for line in lines if line.startswith(("Sig", "Shd")))
        with contextlib.suppress(ProcessLookupError):
            os.kill(self.pid, signal.SIGUSR1)
            time.sleep(1.0)
        return state

    def kill(self) -> None:
        """SIGKILL the whole process group (the process and its children) and reap the leader."""
        self._kill_group()
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.popen.wait(timeout=10)

    def _kill_group(self) -> None:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(self.popen.pid, signal.SIGKILL)

    def __enter__(self) -> NodeProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.kill()


class Processes:
    """The processes of one test (or bench run) on one environment; all stopped by stop_all()."""

    def __init__(self, env: dict[str, str], log_dir: Path) -> None:
        self.env, self.log_dir = env, Path(log_dir)
        self.started: dict[str, NodeProcess] = {}

    def command(
        self,
        name: str,
        argv: list[str],
        env: dict[str, str] | None = None,
        cwd: str | Path | None = None,
        preexec_fn: Callable[[], None] | None = None,
    ) -> NodeProcess:
        """Start argv under a name (for logs and stop_all's status map)."""
        proc = NodeProcess(name, argv, self.env if env is None else env, self.log_dir, cwd, preexec_fn)
        key, k = name, 1
        while key in self.started:
            k += 1
            key = f"{name}-{k}"
        self.started[key] = proc
        return proc

    def node(self, name: str, *args: str, **params: Any) -> NodeProcess:
        """Start the console script `name --ros-args -p key:=value ...` (a lubrig_ros node)."""
        argv = [str(BIN / name), *args]
        if params:
            argv.append("--ros-args")
            for key, value in params.items():
                argv += ["-p", f"{key}:={value}"]
        return self.command(name, argv)

    def script(self, script: str, *args: str, **kwargs: Any) -> NodeProcess:
        """Start a console script of the venv with plain arguments."""
        return self.command(script, [str(BIN / script), *args], **kwargs)

    def module(self, module: str, *args: str, **kwargs: Any) -> NodeProcess:
        """Start `python -m module args`."""
        return self.command(module.rsplit(".", 1)[-1], [PYTHON, "-m", module, *args], **kwargs)

    def run_module(
        self, module: str, *args: str, timeout: float = 120.0, env: dict[str, str] | None = None
    ) -> subprocess.CompletedProcess[str]:
        """Run `python -m module args` to completion; output captured."""
        return run([PYTHON, "-m", module, *args], self.env if env is None else env, timeout)

    def run_script(
        self, script: str, *args: str, timeout: float = 120.0, env: dict[str, str] | None = None
    ) -> subprocess.CompletedProcess[str]:
        """Run a console script of the venv to completion; output captured."""
        return run([str(BIN / script), *args], self.env if env is None else env, timeout)

    def __getitem__(self, name: str) -> NodeProcess:
        return self.started[name]

    def log(self, name: str) -> str:
        """The labelled logs of a started process."""
        return self.started[name].log()

    def logs(self) -> str:
        """Every started process's logs (for failure messages)."""
        return "\n".join(p.log() for p in self.started.values())

    def stop_all(self, timeout: float = 20.0) -> dict[str, int]:
        """SIGINT to every running process, wait up to timeout, SIGKILL leftovers; exit statuses.

        A process that had to be killed shows as its negative signal number (-9); before the kill
        its signal state and Python stacks are taken (`_signal_state`) and its whole log goes to
        stderr, which pytest shows in full for a failed test (an assertion message is cut).
        """
        for proc in self.started.values():
            if proc.running():
                with contextlib.suppress(ProcessLookupError):
                    proc.popen.send_signal(signal.SIGINT)
        end = time.monotonic() + timeout
        codes = {}
        for name, proc in self.started.items():
            try:
                codes[name] = proc.popen.wait(timeout=max(0.1, end - time.monotonic()))
            except subprocess.TimeoutExpired:
                state = proc._signal_state()
                proc.kill()
                codes[name] = proc.popen.returncode
                stuck = f"{name} did not stop within {timeout:g} s of SIGINT ({state})"
                print(f"{stuck}:\n{proc.log()}", file=sys.stderr)
            proc._kill_group()
        return codes

    def kill_all(self) -> None:
        """SIGKILL every process group (teardown after a failure)."""
        for proc in self.started.values():
            proc.kill()


def run(
    argv: list[str], env: dict[str, str] | None, timeout: float = 120.0
) -> subprocess.CompletedProcess[str]:
    """Run argv to completion in its own session; output captured; the group is killed on timeout."""
    with subprocess.Popen(
        argv,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=child_setup(),
    ) as popen:
        try:
            out, err = popen.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(popen.pid, signal.SIGKILL)
            out, err = popen.communicate()
            raise AssertionError(f"{argv} did not finish within {timeout} s:\n{out}\n{err}") from None
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(popen.pid, signal.SIGKILL)  # nothing of it outlives the call
    return subprocess.CompletedProcess(argv, popen.returncode, out, err)


class Probe:
    """A node in its own rclpy context on the test's domain, spun in a background thread.

    ``subscribe(topic, type, qos)`` records every message in ``messages[topic]`` (receive times in
    ``times[topic]``, for benchmarks only: tests assert what arrives, not when).
    """

    def __init__(self, domain: int, name: str = "probe") -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        # read by rmw at init: discovery and transports stay on this machine
        os.environ.update(discovery_environment(os.environ).env)
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = Node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.messages: dict[str, list[Any]] = defaultdict(list)
        self.times: dict[str, list[float]] = defaultdict(list)
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        with contextlib.suppress(Exception):
            self.executor.spin()

    def subscribe(self, topic: str, msg_type: type, qos: Any = None) -> Any:
        """Record every message on topic (default QoS: reliable, volatile, depth 1000)."""
        if qos is None:
            from rclpy.qos import QoSProfile, ReliabilityPolicy

            qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        messages, times = self.messages[topic], self.times[topic]

        def callback(msg: Any) -> None:
            messages.append(msg)
            times.append(time.monotonic())

        return self.node.create_subscription(msg_type, topic, callback, qos)

    def consume_blocks(self, namespace: str, delay: float = 0.0, topic: str = "state_block") -> str:
        """Take <namespace>/state_block as a required consumer of the sim flow control.

        Records every RigStateBlock in ``messages[<namespace>/<topic>]`` and reports on
        <namespace>/flow_progress (participant: this node's fully qualified name, returned; give
        it to belt_drive's ``required_consumers``): samples 0 once the subscription has matched
        the plant's publisher and no subscription of the probe lags (`lagging`; LAG_WAIT_S at
        most), then after every
        block taken, and every 0.2 s as a heartbeat.
        `delay`: seconds slept in every block callback (a deliberately slow consumer).
        """
        from lubrig_interfaces.msg import FlowProgress, RigStateBlock
        from lubrig_ros.app.interface import contract
        from lubrig_ros.nodes.interfaces import qos_profile

        block_name = contract.resolve(namespace, topic)
        qos = qos_profile(contract.BLOCK_QOS)
        progress = self.node.create_publisher(FlowProgress, contract.resolve(namespace, "flow_progress"), qos)
        participant = self.node.get_fully_qualified_name()
        state = {"ready": False, "segment": 0, "samples": 0}
        lock = threading.Lock()
        messages, times = self.messages[block_name], self.times[block_name]

        def report() -> None:
            msg = FlowProgress(participant=participant)
            msg.segment, msg.samples = state["segment"], state["samples"]
            progress.publish(msg)

        def on_block(msg: Any) -> None:
            if delay:
                time.sleep(delay)
            messages.append(msg)
            times.append(time.monotonic())
            with lock:
                if msg.segment >= state["segment"]:
                    state["segment"] = msg.segment
                    state["samples"] = msg.first_sample_index + len(msg.displacement)
                if state["ready"]:
                    report()

        sub = self.node.create_subscription(RigStateBlock, block_name, on_block, qos)

        matched_at: list[float] = []

        def heartbeat() -> None:
            with lock:
                if not state["ready"] and sub.get_publisher_count() > 0:
                    matched_at[:] = matched_at or [time.monotonic()]
                    # a subscription that can never match (another QoS) is not waited for for ever
                    state["ready"] = not self.lagging() or time.monotonic() - matched_at[0] > LAG_WAIT_S
                if state["ready"]:
                    report()

        self.node.create_timer(0.2, heartbeat)
        return participant

    def lagging(self) -> list[str]:
        """The probe's subscriptions that have matched fewer publishers than the graph shows.

        A reader drops what a writer sends before the reader has matched it (its half of the
        match; volatile: it is not sent again), so a consumer reports ready only once none lags
        (the recorder's rule, docs/recording.md).
        """
        return [
            s.topic_name
            for s in self.node.subscriptions
            if s.get_publisher_count() < self.node.count_publishers(s.topic_name)
        ]

    def publisher(self, topic: str, msg_type: type, qos: Any) -> Any:
        """A publisher of the probe node."""
        return self.node.create_publisher(msg_type, topic, qos)

    def wait_for(self, predicate: Callable[[], object], timeout: float) -> bool:
        """Poll predicate until true or timeout s; returns its last value as a bool."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if predicate():
                return True
            time.sleep(0.02)
        return bool(predicate())

    def samples(self, topic: str, field: str) -> int:
        """Samples received on a block topic: the lengths of every message's `field`, summed."""
        return sum(len(getattr(m, field)) for m in self.messages[topic])

    def wait_for_count(self, topic: str, count: int, timeout: float) -> bool:
        """Wait until at least count messages arrived on topic."""
        return self.wait_for(lambda: len(self.messages[topic]) >= count, timeout)

    def wait_for_more(self, topic: str, more: int, timeout: float) -> bool:
        """Wait until `more` messages arrive on topic after this call."""
        start = len(self.messages[topic])
        return self.wait_for_count(topic, start + more, timeout)

    def topics(self) -> dict[str, list[str]]:
        """Topic name -> type names in the ROS graph."""
        return dict(self.node.get_topic_names_and_types())

    def call(
        self, srv_type: type, name: str, request: Any, timeout: float = 20.0, resend: float = 0.0
    ) -> Any:
        """Call a service and wait for its answer.

        `resend` (s, idempotent requests only): send the request again while none is answered.
        Fast DDS drops a response when the server has not yet matched this new client's
        response reader (it waits 100 ms for that, then warns "failed to send response
        (timeout)"), and the request is never answered; a start-up on a loaded machine can take
        longer than that to match. The first answer to any of the copies is taken.
        """
        client = self.node.create_client(srv_type, name)
        assert client.wait_for_service(timeout_sec=timeout), f"service {name} not available"
        futures = [client.call_async(request)]
        end = time.monotonic() + timeout
        while not self.wait_for(lambda: any(f.done() for f in futures), min(resend or timeout, timeout)):
            assert resend and time.monotonic() < end, f"service {name} did not answer"
            futures.append(client.call_async(request))
        return next(f for f in futures if f.done()).result()

    def set_parameter(self, node: str, name: str, value: Any) -> Any:
        """SetParameters on /<node>; returns the SetParametersResult (idempotent: resent, see call)."""
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter

        request = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
        return self.call(SetParameters, f"/{node}/set_parameters", request, resend=5.0).results[0]

    def close(self) -> None:
        """Shut the context down and stop the spin thread."""
        self.context.try_shutdown()
        self._thread.join(timeout=5)
        with contextlib.suppress(Exception):
            self.node.destroy_node()
