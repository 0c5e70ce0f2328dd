"""`lubrig rig`: start the node processes for one run, wait for it, stop them, report.

Resolves the run once (case | config file | default, plus --duration / --convention) and writes
it to DIR/run_config.yaml; every node gets that file as its `config_file` parameter (nothing is
rebuilt from a case number). Starts the recorder (`recorder -o DIR/bag --config
DIR/run_config.yaml [--use-sim-time]`, sim mode logs rig time) and waits until it is subscribed,
then belt_drive, plant and analysis on the current ROS_DOMAIN_ID, all in the rig namespace
(`--namespace NS`, default /lubrig: the nodes get `-r __ns:=NS`, the recorder `--namespace
NS`); waits until the plant reports
the run complete (sim) or the wall duration has passed (realtime), stops the nodes and then the
recorder with SIGINT (SIGTERM after a grace period) so that the bag is finalized, and finally
writes the report of the bag into DIR/report (`--no-report` skips it) and prints its location.

Sim mode: belt_drive streams band blocks paced on <ns>/flow_progress (app/flow.py); when recording,
the recorder's participant (`<ns>/lubrig_recorder`, contract.RECORDER_PARTICIPANT) is one of
belt_drive's `required_consumers`, so a slow recorder slows the run instead of losing samples.
The plant publishes the global /clock (`publish_clock`) unless `--no-clock` is given: /clock has
one owner per ROS domain, so a second rig on the same domain runs with `--no-clock`. Every node
of a sim rig runs with `use_sim_time` true (belt_drive, plant, analysis, and the recorder's
nodes with `--use-sim-time`); their stamps are rig time from the rig's own samples, with or
without /clock, and nothing paces on /clock (docs/nodes.md, "Sim time").
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

from ..app.contract import (
    DEFAULT_NAMESPACE,
    EXIT_INTEGRATION_FAILED,
    EXIT_REAL_TIME_NOT_HELD,
    RECORDER_PARTICIPANT,
    parameter,
    recorded_topics,
    validate_namespace,
)
from ..app.discovery import discovery_environment
from ..app.lifetime import die_with_parent
from ..app.rundir import prepare_output_dir
from ..app.selection import RunSelection
from ..core.params import CONVENTIONS, ParameterError
from ..core.presets import RunConfig, config_dir
from .main import CommandError
from .progress import Progress

NODES = ("plant", "belt_drive", "analysis")
GRACE_S = 10.0
#: The recorder, stopped last, may take the plant's announced tail (5 s), drain its workers and
#: finalize the bag: on a loaded machine that took longer than GRACE_S (seen: SIGTERM just after
#: it had written every sample). A guard against a hang, not an expected duration.
RECORDER_GRACE_S = 40.0
#: Recorder worker processes in sim mode (recorder_command).
SIM_RECORDER_WORKERS = 1
#: Sim: end the run (non-zero) once the plant has reported it stalled this long without a break
#: (a run that cannot progress; a loaded machine's pauses of a few seconds are not one).
STALL_GIVE_UP_S = 15.0
RECORDER_READY_S = 60.0
#: Exit statuses of a node that ended cleanly: 0, or killed by the SIGINT that stops it while it is
#: still importing (nodes/entry.py); launch/rig.launch.py uses the same rule.
CLEAN_EXITS = (0, -signal.SIGINT)


def _die_with_launcher() -> None:
    """In a node process before exec: SIGTERM when the launcher ends, however it ends.

    SIGTERM, not SIGKILL: the node stops as on `lubrig rig`'s own stop (the recorder finalizes
    the bag); the recorder's helpers are killed with the recorder (nodes/recorder_forkserver.py).
    """
    die_with_parent(signal.SIGTERM)


def _executable(name: str) -> str:
    """Console script `name` next to this interpreter, else on PATH."""
    here = Path(sys.executable).parent / name
    if here.is_file():
        return str(here)
    found = shutil.which(name)
    if found is None:
        raise CommandError(f"executable {name!r} not found (is lubrig_ros installed?)")
    return found


RECORDER_NODE_PREFIX = "lubrig_recorder"  # the recorder's worker nodes: <namespace>/lubrig_recorder_w<i>


def recorder_reports_progress() -> bool:
    """True when the installed recorder publishes flow_progress as RECORDER_PARTICIPANT.

    The recorder side of issue 12 (nodes/recorder.py) declares it with a module constant
    FLOW_PARTICIPANT; a recorder without it never reports, and pacing on it would never start.
    """
    from ..nodes import recorder

    return getattr(recorder, "FLOW_PARTICIPANT", None) == RECORDER_PARTICIPANT



RUN_CONFIG_FILE = "run_config.yaml"


def resolve_run(
    case: int | None = None,
    config_file: str | Path | None = None,
    duration: float | None = None,
    convention: str | None = None,
) -> RunConfig:
    """The run: case 1..10, else a configuration file, else the default; then the overrides.

    The launchers' (`lubrig rig`, launch/rig.launch.py) use of app/selection.py: 0 / "" / None
    mean "not given". ParameterError naming the bad value.
    """
    selection = RunSelection(
        case=case or None,
        config_file=Path(config_file).resolve() if config_file else None,
        convention=convention or None,
        duration=duration,
    )
    return selection.resolve()


def write_run_config(config: RunConfig, directory: Path) -> Path:
    """Write the resolved run to DIRECTORY/run_config.yaml; the path the nodes get as config_file."""
    path = directory / RUN_CONFIG_FILE
    path.write_text(config.to_yaml())
    return path.resolve()


def select_config(args: argparse.Namespace) -> RunConfig:
    """The resolved run of the command line (CommandError on a bad value)."""
    try:
        return resolve_run(args.case, args.config, args.duration, args.convention)
    except ParameterError as exc:
        raise CommandError(str(exc)) from None


def _ros_args(params: dict[str, object], params_file: Path, namespace: str = DEFAULT_NAMESPACE) -> list[str]:
    args = ["--ros-args", "-r", f"__ns:={namespace}", "--params-file", str(params_file)]
    for key, value in params.items():
        args += ["-p", f"{key}:={value}"]
    return args


def _wait_complete(
    deadline: float,
    procs: dict[str, subprocess.Popen],
    namespace: str = DEFAULT_NAMESPACE,
    progress: Progress | None = None,
    stall: list[str] | None = None,
) -> bool:
    """Sim: wait for <ns>/run_complete = true (latched) from the plant (rig time from /clock).

    Gives up early when the plant has reported its run stalled (timing status ERROR) for
    STALL_GIVE_UP_S without a break; the plant's line is appended to `stall`.
    """
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node
    from std_msgs.msg import Bool

    from ..app import contract
    from ..nodes.interfaces import qos_profile

    spec = contract.topic("run_complete").resolved(namespace)
    context = Context()
    rclpy.init(context=context)
    node = Node("lubrig_rig_launcher", context=context)
    done = []
    node.create_subscription(
        Bool, spec.name, lambda m: done.append(True) if m.data else None, qos_profile(spec.qos)
    )
    if progress is not None and progress.enabled:  # rig time on a terminal: the plant's /clock
        from rosgraph_msgs.msg import Clock

        node.create_subscription(
            Clock, "/clock", lambda m: progress.update(m.clock.sec + 1e-9 * m.clock.nanosec),
            qos_profile(contract.topic("/clock").qos),
        )
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus

    timing = f"{contract.resolve(namespace, 'plant')}: timing"
    stalled_since: list[float] = []
    stall_text: list[str] = []

    def on_diagnostics(array: DiagnosticArray) -> None:
        for status in array.status:
            if status.name != timing:
                continue
            if status.level == DiagnosticStatus.ERROR and status.message.startswith("stalled"):
                stalled_since[:] = stalled_since or [time.monotonic()]
                stall_text[:] = [status.message]
            else:
                stalled_since.clear()

    node.create_subscription(
        DiagnosticArray, "/diagnostics", on_diagnostics, qos_profile(contract.topic("/diagnostics").qos)
    )
    from rclpy.executors import SingleThreadedExecutor

    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        while not done and time.monotonic() < deadline:
            if any(p.poll() is not None for p in procs.values()):
                break
            if stalled_since and time.monotonic() - stalled_since[0] >= STALL_GIVE_UP_S:
                if stall is not None:
                    stall.append(f"{timing}: {stall_text[0]}")
                break
            try:
                executor.spin_once(timeout_sec=0.1)
            except RuntimeError:
                # a Ctrl-C: rclpy's signal handling shut the context down under a take ("Unable
                # to convert call argument"), which is the interrupt, not a failure; the
                # shutdown may still be in flight for a moment
                end = time.monotonic() + 0.5
                while context.ok() and time.monotonic() < end:
                    time.sleep(0.01)
                if context.ok():
                    raise
                raise KeyboardInterrupt from None
    finally:
        executor.shutdown(timeout_sec=1.0)  # before the context: no Executor.__del__ traceback
        node.destroy_node()
        context.try_shutdown()
    return bool(done)


def _dump_stacks(name: str, proc: subprocess.Popen, grace: float) -> None:
    """A node that ignored SIGINT: SIGUSR1 makes it write its threads' stacks to its log."""
    print(
        f"lubrig rig: {name} did not stop within {grace:g} s of SIGINT; its Python stacks go to "
        "its log (SIGUSR1), then SIGTERM",
        file=sys.stderr,
    )
    try:
        proc.send_signal(signal.SIGUSR1)  # nodes.entry registers faulthandler for it
        proc.wait(timeout=0.5)
    except (subprocess.TimeoutExpired, ProcessLookupError):
        pass


def stop_all(procs: dict[str, subprocess.Popen], grace: float = GRACE_S) -> dict[str, int]:
    """SIGINT every running process, wait, then SIGTERM (and SIGKILL) what is left."""
    for proc in procs.values():
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
    codes: dict[str, int] = {}
    end = time.monotonic() + grace
    for name, proc in procs.items():
        try:
            codes[name] = proc.wait(timeout=max(0.1, end - time.monotonic()))
        except subprocess.TimeoutExpired:
            _dump_stacks(name, proc, grace)
            proc.terminate()
            try:
                codes[name] = proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                proc.kill()
                codes[name] = proc.wait()
    return codes


def recorder_command(
    bag_dir: Path, run_config: Path, mode: str, namespace: str = DEFAULT_NAMESPACE
) -> list[str]:
    """The recorder's command line: the rig's namespace; sim mode: rig time as log time, one worker.

    A sim run streams blocks, a few hundred messages per second, which one worker takes; each
    worker is a DDS participant whose start-up costs CPU on the run's critical path.
    """
    argv = [_executable("recorder"), "-o", str(bag_dir), "--config", str(run_config)]
    argv += ["--namespace", namespace]
    if mode == "sim":
        return [*argv, "--use-sim-time", "--workers", str(SIM_RECORDER_WORKERS)]
    # wall clock: state_block holds every sample; the per-sample streams would be written twice
    return [*argv, "--progress-heartbeat-only", "--topics", *recorded_topics(mode)]


def _set_aside(bag_dir: Path) -> None:
    """Keep the previous recording of this DIR as bag.previous (the recorder needs a new path)."""
    if not bag_dir.exists():
        return
    previous = bag_dir.with_name(bag_dir.name + ".previous")
    if previous.exists():
        shutil.rmtree(previous)
    bag_dir.rename(previous)
    print(f"lubrig rig: previous bag moved to {previous}")


#: What each process prints once it is set up (its start line), for `_wait_ready`.
READY_LINES = {
    "recorder": "recorder: recording",
    "view": "view: serving",
    "belt_drive": "belt_drive: mode=",
    "analysis": "analysis: window",
    "plant": "plant: mode=",
    "plant_loop": "subscribed; the loop starts",  # a realtime plant waiting for the recorder
}


def _wait_ready(name: str, proc: subprocess.Popen, log: Path, limit: float = RECORDER_READY_S) -> None:
    """Wait until process `name` prints its READY_LINES line; CommandError naming it if it exits."""
    end = time.monotonic() + limit
    while READY_LINES[name] not in log.read_text(errors="replace"):
        if proc.poll() is not None:
            lines = log.read_text(errors="replace").strip().splitlines()
            errors = [line for line in lines if "ERROR" in line or "FATAL" in line or "error" in line]
            why = (errors or lines or ["no output"])[0]
            raise CommandError(f"{name} exited with status {proc.returncode} during start-up: {why}")
        if time.monotonic() > end:
            raise CommandError(f"{name} not ready after {limit:g} s; see {log}")
        time.sleep(0.05)


def run(args: argparse.Namespace) -> int:
    """Start, wait, stop, report."""
    config = select_config(args)
    namespace = getattr(args, "namespace", DEFAULT_NAMESPACE)
    try:
        validate_namespace(namespace, "--namespace")
    except ParameterError as exc:
        raise CommandError(str(exc)) from None
    mode = args.mode
    bag = prepare_output_dir(Path(args.run_dir), args.force, "--run-dir").resolve()
    bag.mkdir(parents=True, exist_ok=True)
    logs = bag / "logs"
    logs.mkdir(exist_ok=True)
    run_config = write_run_config(config, bag)
    params_file = config_dir() / "nodes.yaml"
    # every node reads the resolved run (duration, convention, rig, band) from the one file
    selection: dict[str, object] = {"config_file": str(run_config)}
    per_node: dict[str, dict[str, object]] = {
        "plant": dict(selection, mode=mode),
        "belt_drive": dict(selection, mode=mode),
        "analysis": dict(selection),
    }
    for option, name in (("max_lag", "max_lag"), ("lag_policy", "lag_policy")):
        value = getattr(args, option, None)
        if value is not None:
            if mode == "sim":
                raise CommandError(f"--{option.replace('_', '-')} applies to --mode realtime only")
            per_node["plant"][name] = value
    clock = mode == "sim" and not getattr(args, "no_clock", False)
    if clock:
        per_node["plant"]["publish_clock"] = True
    if mode == "sim":  # every node on the rig's ROS clock (/clock; stamps from the rig's own time)
        for params in per_node.values():
            params["use_sim_time"] = True
    procs: dict[str, subprocess.Popen] = {}
    discovery = discovery_environment(os.environ, args.network)  # this host only unless asked
    env = discovery.env
    env.setdefault("RCUTILS_LOGGING_BUFFERED_STREAM", "0")  # node logs complete even on SIGINT
    # the launcher's own participant (it waits for run_complete) with the nodes' transports and
    # discovery range: with rclpy's defaults it found the latched run_complete seconds late
    os.environ.update({k: v for k, v in env.items() if os.environ.get(k) != v})
    with_recorder = not args.no_recorder
    if with_recorder:
        # sim: nothing flows before the recorder has subscribed to every output (no lost sample),
        # and belt_drive paces on the recorder's flow_progress as well as the plant's
        per_node["plant"]["wait_for_subscriber"] = RECORDER_NODE_PREFIX  # nothing unrecorded
        if mode == "sim":
            per_node["belt_drive"]["wait_for_subscriber"] = RECORDER_NODE_PREFIX
            if recorder_reports_progress():
                per_node["belt_drive"]["required_consumers"] = f"['{RECORDER_PARTICIPANT}']"
        _set_aside(bag / "bag")
    try:
        if with_recorder:
            with open(logs / "recorder.log", "w") as log:
                procs["recorder"] = subprocess.Popen(
                    recorder_command(bag / "bag", run_config, mode, namespace),
                    env=env,
                    stdout=log,
                    stderr=subprocess.STDOUT,
                    preexec_fn=_die_with_launcher,  # a launcher killed by SIGKILL takes its nodes with it
                )
            if mode != "sim":  # realtime: nothing paces the nodes on the recorder, so it comes first
                _wait_ready("recorder", procs["recorder"], logs / "recorder.log")
        if args.view is not None:  # live view for Foxglove (lubrig view), up before the nodes publish
            with open(logs / "view.log", "w") as log:
                procs["view"] = subprocess.Popen(
                    [_executable("view"), "--namespace", namespace, "--port", str(args.view)], env=env,
                    stdout=log, stderr=subprocess.STDOUT, preexec_fn=_die_with_launcher,
                )
            _wait_ready("view", procs["view"], logs / "view.log")
            print(f"lubrig rig: live view on ws://127.0.0.1:{args.view} (Foxglove; log {logs / 'view.log'})")
        # wall clock: the plant's deadlines start with it, so it starts last, once the others have
        # done their CPU-bound start-up (imports of several processes on 2 cores would make its
        # first ticks late); sim: all at once (nothing flows before every participant reports)
        order = NODES if mode == "sim" else ("belt_drive", "analysis", "plant")
        for name in order:
            if name == "plant" and mode != "sim":
                for other in ("belt_drive", "analysis"):
                    _wait_ready(other, procs[other], logs / f"{other}.log")
            with open(logs / f"{name}.log", "w") as log:
                procs[name] = subprocess.Popen(
                    [_executable(name), *_ros_args(per_node[name], params_file, namespace)],
                    env=env,
                    stdout=log,
                    stderr=subprocess.STDOUT,
                    preexec_fn=_die_with_launcher,
                )
        if with_recorder and mode == "sim":
            # sim: plant and belt_drive wait for the recorder's subscriptions and flow_progress, so
            # it starts beside them (start-up is CPU-bound: imports of four processes on 2 cores)
            _wait_ready("recorder", procs["recorder"], logs / "recorder.log")
        if mode != "sim":  # the run's wall duration counts from the plant's first sample
            _wait_ready("plant", procs["plant"], logs / "plant.log")
            if with_recorder:
                _wait_ready("plant_loop", procs["plant"], logs / "plant.log")
        domain = env.get("ROS_DOMAIN_ID", "0")
        print(
            f"lubrig rig: {config.name} ({mode}, {config.duration:g} s) on ROS_DOMAIN_ID {domain}, "
            f"namespace {namespace}; {discovery.isolation}"
            + (", publishing /clock (one owner per domain: --no-clock for a second rig)" if clock else "")
        )
        start = time.monotonic()
        if mode == "sim":
            limit = args.timeout if args.timeout else max(60.0, 10.0 * config.duration)
            bar = Progress("lubrig rig", config.duration)
            stall: list[str] = []
            complete = _wait_complete(start + limit, procs, namespace, bar, stall)
            bar.finish()
            if not complete and stall:
                raise CommandError(f"sim run stalled for {STALL_GIVE_UP_S:g} s: {stall[0]}; see {logs}")
            failed = not complete and procs["plant"].poll() == EXIT_INTEGRATION_FAILED
            if not complete and not failed:
                dead = [n for n, p in procs.items() if p.poll() is not None]
                why = f"process(es) {dead} exited" if dead else f"timeout after {limit:g} s"
                raise CommandError(f"sim run did not complete ({why}); see {logs}")
        else:
            end = start + config.duration
            bar = Progress("lubrig rig", config.duration)
            while time.monotonic() < end and all(p.poll() is None for p in procs.values()):
                time.sleep(0.1)
                bar.update(time.monotonic() - start)
            bar.finish()
        wall = time.monotonic() - start
    except KeyboardInterrupt:
        print("lubrig rig: interrupted, stopping the nodes", file=sys.stderr)
        wall = math.nan  # interrupted: no run time to report, exit status 130
    finally:
        # nodes first, the recorder last so that it has everything before it closes the bag
        ordered = {n: p for n, p in procs.items() if n != "recorder"}
        codes = stop_all(ordered)
        if "recorder" in procs:
            codes |= stop_all({"recorder": procs["recorder"]}, RECORDER_GRACE_S)
    bad = {n: c for n, c in codes.items() if c not in CLEAN_EXITS}
    late = bad.get("plant") == EXIT_REAL_TIME_NOT_HELD and mode != "sim"
    failed = bad.get("plant") == EXIT_INTEGRATION_FAILED and mode == "sim"
    if late or failed:
        del bad["plant"]
    if math.isnan(wall):
        print(f"lubrig rig: interrupted before the run ended; what was recorded is in {bag}")
    else:
        print(f"lubrig rig: run finished in {wall:.1f} s wall; results in {bag}")
    print(f"  run configuration: {run_config}")
    print(f"  node logs:         {logs}")
    if with_recorder:
        print(f"  bag:               {bag / 'bag'}")
    else:
        print("  (--no-recorder: nothing recorded)")
    if bad:
        raise CommandError(f"node(s) exited with errors {bad}; see {logs}")
    if failed:  # what was published before the failed sample is recorded; no report of a broken run
        print(f"lubrig rig: error: {_plant_verdict(logs / 'plant.log', 'the run ends')}", file=sys.stderr)
        return EXIT_INTEGRATION_FAILED
    if with_recorder and not args.no_report and not math.isnan(wall):
        from ..report import write_report

        page = write_report(bag / "bag", bag / "report", force=True)  # inside the checked run folder
        print(f"report: {page}")
    if late:  # the run is recorded and reported; its timing is what failed
        print(f"lubrig rig: error: {_real_time_verdict(logs / 'plant.log')}", file=sys.stderr)
    if math.isnan(wall):
        return 130  # 128 + SIGINT: interrupted, as a shell reports it
    return EXIT_REAL_TIME_NOT_HELD if late else 0


def _plant_verdict(log: Path, marker: str) -> str:
    """The plant's last log line holding `marker`, from the marker on (the whole line if none)."""
    lines = log.read_text(errors="replace").splitlines() if log.is_file() else []
    said = [line for line in lines if marker in line]
    if not said:
        return f"the plant ended without saying why; see {log}"
    return said[-1][said[-1].index(marker) :]


def _real_time_verdict(log: Path) -> str:
    """The plant's own line on why the rig did not hold real time (its last such line)."""
    lines = log.read_text(errors="replace").splitlines() if log.is_file() else []
    said = [line for line in lines if "hold real time" in line]
    if not said:
        return f"the rig did not hold real time (plant exit status {EXIT_REAL_TIME_NOT_HELD}); see {log}"
    text = said[-1]
    return "the rig " + text[text.index("did not hold") :] if "did not hold" in text else text


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"{text!r} is not valid; expected a finite number > 0 s")
    return value


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `rig` subcommand."""
    parser = subparsers.add_parser(
        "rig",
        help="run the rig as ROS 2 nodes (belt_drive, plant, analysis, recorder)",
        description="Start the node processes on the current ROS_DOMAIN_ID, wait for the run, "
        "stop them cleanly and report where the results are.",
    )
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--case", type=int, metavar="N", help="study case 1..10")
    group.add_argument("--config", metavar="FILE", help="run configuration YAML")
    parser.add_argument("--mode", choices=("sim", "realtime"), default="sim")
    lag = parameter("plant", "max_lag")
    parser.add_argument(
        "--max-lag", type=_positive, metavar="S",
        help=f"realtime: {lag.description} (default {lag.default:g} s; valid {lag.expected()})",
    )
    policy = parameter("plant", "lag_policy")
    parser.add_argument(
        "--lag-policy", choices=policy.choices,
        help=f"realtime: what the plant does beyond --max-lag (default {policy.default}); either way "
        f"lubrig rig ends with status {EXIT_REAL_TIME_NOT_HELD} naming the cause",
    )
    parser.add_argument(
        "--namespace", default=DEFAULT_NAMESPACE, metavar="NS",
        help=f"ROS namespace of the rig's nodes, topics and services (default {DEFAULT_NAMESPACE})",
    )
    parser.add_argument("--convention", choices=CONVENTIONS, help="override the convention")
    parser.add_argument("--duration", type=_positive, metavar="S", help="run length in s")
    parser.add_argument(
        "--run-dir", "--bag", dest="run_dir", required=True, metavar="DIR",
        help="run folder: run_config.yaml, logs/, the bag in DIR/bag, the report in DIR/report "
        "(--bag is the old name); an existing non-empty DIR is refused unless --force",
    )
    parser.add_argument("--force", action="store_true", help="reuse a non-empty run folder")
    parser.add_argument("--timeout", type=_positive, metavar="S", help="sim: wall-time limit")
    parser.add_argument(
        "--network",
        action="store_true",
        help="let hosts on the network discover the rig (default: this host only; also "
        "LUBRIG_DISCOVERY=network); an unsecured domain lets them drive it (docs/security.md)",
    )
    parser.add_argument("--no-recorder", action="store_true", help="do not start the recorder")
    parser.add_argument(
        "--no-clock", action="store_true",
        help="sim: the plant does not publish /clock (one owner per ROS domain: use it for a "
        "second rig on the same domain)",
    )
    parser.add_argument("--no-report", action="store_true", help="do not write DIR/report")
    parser.add_argument("--view", nargs="?", type=int, const=8765, metavar="PORT",
                        help="also serve the run to Foxglove on ws://127.0.0.1:PORT (default 8765; "
                        "lubrig view)")
    parser.set_defaults(func=run)
