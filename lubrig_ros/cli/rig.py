"""`lubrig rig`: start the node processes for one run, wait for it, stop them, report.

Resolves the run once (case | config file | default, plus --duration / --convention) and writes
it to DIR/run_config.yaml; every node gets that file as its `config_file` parameter (nothing is
rebuilt from a case number). The nodes, their parameters and their start order are the launch
plan (app/processes/rig_plan.py), which launch/rig.launch.py turns into launch_ros actions as well.

Before anything starts, the launcher looks at the ROS graph (cli/rig_ros.py): a namespace that
another rig holds on this ROS_DOMAIN_ID is refused (exit 2, one line naming that rig's nodes).
Then it starts the recorder (`recorder -o DIR/bag --config DIR/run_config.yaml
[--use-sim-time]`, sim mode logs rig time) and belt_drive, plant and analysis in the rig
namespace (`--namespace NS`, default /lubrig: the nodes get `-r __ns:=NS`, the recorder
`--namespace NS`); waits until the plant reports the run complete (sim) or the wall duration has
passed (realtime), stops the nodes and then the recorder with SIGINT (SIGTERM, then SIGKILL after
bounded grace periods, each said) so that the bag is finalized, and finally writes the report of
the bag into DIR/report (`--no-report` skips it) and prints its location.

A process that fails — in start-up, the run or shutdown — is named with how it ended and the
first error line of its log (cli/rig_supervisor.py); `lubrig rig` then exits 1 (EXIT_FAILED).

Sim mode: belt_drive streams band blocks paced on <ns>/flow_progress (app/flow.py); when recording,
the recorder's participant (`<ns>/lubrig_recorder`, contract.RECORDER_PARTICIPANT) is one of
belt_drive's `required_consumers`, so a slow recorder slows the run instead of losing samples.
After run_complete the nodes are stopped once the recorder reports every sample the plant
reported (its count holds only samples it has of band and state; RECORDER_HOLD_S at most):
a writer stopped earlier would take a copy lost on the way with it.
The plant publishes the global /clock (`publish_clock`) unless `--no-clock` is given: /clock has
one owner per ROS domain, so a second rig on the same domain runs with `--no-clock`. Every node
of a sim rig runs with `use_sim_time` true (belt_drive, plant, analysis, and the recorder's
nodes with `--use-sim-time`); their stamps are rig time from the rig's own samples, with or
without /clock, and nothing paces on /clock (docs/nodes.md, "Sim time").
"""

from __future__ import annotations

import argparse
import contextlib
import faulthandler
import functools
import math
import os
import shutil
import signal
import sys
import time
from collections.abc import Callable
from pathlib import Path

from ..app.interface.contract import (
    DEFAULT_NAMESPACE,
    EXIT_INTEGRATION_FAILED,
    EXIT_REAL_TIME_NOT_HELD,
    RECORDER_PARTICIPANT,
    RIG_SAMPLE_STREAMS,
    parameter,
    recorded_topics,
    resolve,
    validate_namespace,
)
from ..app.processes.discovery import discovery_environment
from ..app.processes.rig_plan import CLEAN_EXITS, READY_LINES, ParameterValue, RigPlan, rig_plan
from ..app.processes.startup_trace import mark
from ..app.rundir import prepare_output_dir
from ..app.selection import RunSelection
from ..app.view.access import WAYS
from ..core.params import CONVENTIONS, ParameterError
from ..core.presets import RunConfig, config_dir
from ..nodes.view import DEFAULT_PORT, HIGHEST_PORT, tcp_port
from .main import CommandError
from .progress import Progress
from .rig_gate import StagedRunDir, StartGate, admit_run
from .rig_ros import STALL_GIVE_UP_S, LauncherPresence, wait_complete
from .rig_supervisor import CTRL_C, GRACE_S, Exit, RigProcessError, Supervisor, catch_ctrl_c, stop_all

__all__ = [  # what tests and launch/rig.launch.py take from here
    "CLEAN_EXITS",
    "READY_LINES",
    "STALL_GIVE_UP_S",
    "resolve_run",
    "select_config",
    "stop_all",
    "write_run_config",
]

#: The recorder, stopped last, may take the plant's announced tail (5 s), drain its workers and
#: finalize the bag: on a loaded machine that took longer than GRACE_S (seen: SIGTERM just after
#: it had written every sample). A guard against a hang, not an expected duration.
RECORDER_GRACE_S = 40.0
#: Recorder worker processes in sim mode (recorder_command).
SIM_RECORDER_WORKERS = 1
#: Exit status of `lubrig rig` when a process of the rig failed (as ros2 launch's for a node).
EXIT_FAILED = 1
RUN_CONFIG_FILE = "run_config.yaml"


def _executable(name: str) -> str:
    """Console script `name` next to this interpreter, else on PATH."""
    here = Path(sys.executable).parent / name
    if here.is_file():
        return str(here)
    found = shutil.which(name)
    if found is None:
        raise CommandError(f"executable {name!r} not found (is lubrig_ros installed?)")
    return found


def recorder_reports_progress() -> bool:
    """True when the installed recorder publishes flow_progress as RECORDER_PARTICIPANT.

    The recorder declares it with a module constant FLOW_PARTICIPANT; a recorder without it
    never reports, and pacing on it would never start.
    """
    from ..nodes import recorder

    return getattr(recorder, "FLOW_PARTICIPANT", None) == RECORDER_PARTICIPANT


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


def recorder_command(
    bag_dir: Path, run_config: Path, mode: str, namespace: str = DEFAULT_NAMESPACE
) -> list[str]:
    """The recorder's command line: the rig's namespace; sim mode: rig time as log time, one worker.

    A sim run streams blocks, a few hundred messages per second, which one worker takes; each
    worker is a DDS participant whose start-up costs CPU on the run's critical path.
    """
    argv = [_executable("recorder"), "-o", str(bag_dir), "--config", str(run_config)]
    argv += ["--namespace", namespace, "--require-samples", *RIG_SAMPLE_STREAMS]
    if mode == "sim":
        return [*argv, "--use-sim-time", "--workers", str(SIM_RECORDER_WORKERS)]
    # wall clock: state_block holds every sample; the per-sample streams would be written twice
    return [*argv, "--progress-heartbeat-only", "--topics", *recorded_topics(mode)]


def _plant_options(args: argparse.Namespace, mode: str) -> dict[str, ParameterValue]:
    """--max-lag / --lag-policy as plant parameters (realtime only: CommandError in sim)."""
    extra: dict[str, ParameterValue] = {}
    for option in ("max_lag", "lag_policy"):
        value = getattr(args, option, None)
        if value is not None:
            if mode == "sim":
                raise CommandError(f"--{option.replace('_', '-')} applies to --mode realtime only")
            extra[option] = parameter("plant", option).check(value)  # the plant's own range
    return extra


def _start(sup: Supervisor, plan: RigPlan, args: argparse.Namespace, bag: Path) -> None:
    """Start-up: the recorder, the view, the plan's nodes in order; every start line awaited."""
    sim = plan.mode == "sim"
    if plan.recorded:
        sup.start("recorder", recorder_command(bag / "bag", plan.run_config, plan.mode, plan.namespace))
        if not sim:  # wall clock: nothing paces the nodes on the recorder, so it comes first
            sup.wait_ready("recorder")
    if args.view is not None:  # live view for Foxglove (lubrig view), up before the nodes publish
        allow = [f"--allow-{way}" for way in dict.fromkeys(args.view_allow)]
        view = [_executable("view"), "--namespace", plan.namespace, "--port", str(args.view)]
        sup.start("view", [*view, *allow])
        sup.wait_ready("view")
        print(f"lubrig rig: live view on ws://127.0.0.1:{args.view} (Foxglove; log {sup.log('view')})")
    for node in plan.nodes:
        for other in node.after:
            sup.wait_ready(other)
        sup.start(node.name, [_executable(node.name), *plan.ros_args(node.name)])
    if plan.recorded and sim:
        # sim: plant and belt_drive wait for the recorder's subscriptions and flow_progress, so
        # it starts beside them (start-up is CPU-bound: imports of four processes on 2 cores)
        sup.wait_ready("recorder")
    sup.wait_ready("plant")  # wall clock: the run's duration counts from the plant's start line
    if plan.recorded and not sim:
        sup.wait_ready("plant_loop")


def _allowed(mode: str) -> Callable[[Exit], bool]:
    """Which ends of the plant are the run's verdict, not a failure of a process."""

    def allowed(gone: Exit) -> bool:
        if gone.name != "plant":
            return False
        if mode == "sim":
            return gone.status == EXIT_INTEGRATION_FAILED
        return gone.status == EXIT_REAL_TIME_NOT_HELD

    return allowed


def _run_phase(
    sup: Supervisor, plan: RigPlan, config: RunConfig, timeout: float | None, presence: LauncherPresence
) -> None:
    """Wait for the end of the run (sim: run_complete; realtime: the wall duration)."""
    allowed = _allowed(plan.mode)
    bar = Progress("lubrig rig", config.duration)
    start = time.monotonic()
    if plan.mode == "sim":
        limit = timeout if timeout else max(60.0, 10.0 * config.duration)
        stall: list[str] = []
        recorder = resolve(plan.namespace, RECORDER_PARTICIPANT) if plan.recorded else ""
        complete = wait_complete(presence, start + limit, sup.procs, bar, stall, CTRL_C.is_set, recorder)
        bar.finish()
        if CTRL_C.is_set():
            raise KeyboardInterrupt
        if complete:
            return
        if stall:
            raise CommandError(f"sim run stalled for {STALL_GIVE_UP_S:g} s: {stall[0]}; see {sup.logs}")
        sup.check(allowed)
        if not sup.ended():
            raise RigProcessError(f"sim run did not complete within {limit:g} s (--timeout); see {sup.logs}")
        return
    end = start + config.duration
    while time.monotonic() < end and not sup.ended() and not CTRL_C.is_set():
        time.sleep(0.1)
        bar.update(time.monotonic() - start)
    bar.finish()
    if CTRL_C.is_set():
        raise KeyboardInterrupt
    sup.check(allowed)


def _stop(sup: Supervisor) -> None:
    """Shutdown: nodes first, the recorder last (it has everything before it closes the bag).

    A second Ctrl-C (a terminal's reaches the whole group) does not cut the stop short.
    """
    sup.phase = "shutdown"
    previous = None
    with contextlib.suppress(ValueError):  # not the main thread (in-process callers): no change
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        sup.stop([n for n in sup.procs if n != "recorder"], GRACE_S)
        sup.stop(["recorder"], RECORDER_GRACE_S)
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


def run(args: argparse.Namespace) -> int:
    """Check the namespace, start, wait, stop, report."""
    config = select_config(args)
    namespace = getattr(args, "namespace", DEFAULT_NAMESPACE)
    try:
        validate_namespace(namespace, "--namespace")
        discovery = discovery_environment(os.environ, args.network)  # this host only unless asked
    except ParameterError as exc:
        raise CommandError(str(exc)) from None
    if args.view_allow and args.view is None:
        raise CommandError(f"--view-allow {args.view_allow[0]} applies with --view only")
    mode = args.mode
    plant_extra = _plant_options(args, mode)
    # no start-up check of its own: the launcher watches the graph for GRAPH_SETTLE_S itself
    # (cli/rig_gate.py), and its node holds the namespace until the rig's nodes stop
    plant_extra["namespace_settle"] = 0.0
    env = discovery.env
    env.setdefault("RCUTILS_LOGGING_BUFFERED_STREAM", "0")  # node logs complete even on SIGINT
    # the launcher's own participant (graph check, run_complete) with the nodes' transports and
    # discovery range: with rclpy's defaults it found the latched run_complete seconds late
    os.environ.update({k: v for k, v in env.items() if os.environ.get(k) != v})
    # run_config.yaml and the logs are staged until the namespace check, which runs while the
    # first processes import (cli/rig_gate.py), has passed
    bag = prepare_output_dir(Path(args.run_dir), args.force, "--run-dir").resolve()
    staged = StagedRunDir(bag)
    try:
        write_run_config(config, staged.path)
        with_recorder = not args.no_recorder
        plan = rig_plan(
            bag / RUN_CONFIG_FILE,
            config_dir() / "nodes.yaml",
            mode,
            namespace,
            recorded=with_recorder,
            recorder_reports_progress=not with_recorder or recorder_reports_progress(),
            publish_clock=not getattr(args, "no_clock", False),
            plant_extra=plant_extra,
        )
    except BaseException:
        staged.discard()
        raise
    gate = StartGate()
    presence = LauncherPresence(namespace)
    admit = functools.partial(admit_run, presence, gate, staged, with_recorder)
    sup = Supervisor(staged.path / "logs", env, gate, admit)
    catch_ctrl_c()
    with contextlib.suppress(ValueError, RuntimeError):  # stacks on SIGUSR1, as the nodes do
        faulthandler.register(signal.SIGUSR1, all_threads=True)
    failure = ""
    wall = math.nan  # interrupted: no run time to report, exit status 130
    try:
        # the namespace check's node first: made beside four importing processes it came 0.2-0.35 s
        # after them, and the check's wait counts from it (cli/rig_ros.py namespace_taken)
        presence.make()
        mark("launcher", "node made")
        _start(sup, plan, args, bag)
        mark("launcher", "start lines seen")
        domain = env.get("ROS_DOMAIN_ID", "0")
        print(
            f"lubrig rig: {config.name} ({mode}, {config.duration:g} s) on ROS_DOMAIN_ID {domain}, "
            f"namespace {namespace}; {discovery.isolation}"
            + (
                ", publishing /clock (one owner per domain: --no-clock for a second rig)"
                if plan.publish_clock
                else ""
            )
        )
        sup.phase = "the run"
        start = time.monotonic()
        _run_phase(sup, plan, config, args.timeout, presence)
        wall = time.monotonic() - start
    except RigProcessError as exc:
        failure = "" if CTRL_C.is_set() else str(exc)  # else: nodes ended on the same Ctrl-C
    except KeyboardInterrupt:
        CTRL_C.set()
    finally:
        if CTRL_C.is_set():
            print("lubrig rig: interrupted, stopping the nodes", file=sys.stderr)
        _stop(sup)
        presence.close()  # the namespace is free once the rig's nodes have stopped
        if not staged.placed:  # ended before the gate opened: nothing of the run is left
            gate.shut()
            staged.discard()
    if not staged.placed:  # interrupted during the namespace check: nothing was started
        return 130
    return _finish(sup, plan, args, bag, wall, failure)


def _finish(
    sup: Supervisor, plan: RigPlan, args: argparse.Namespace, bag: Path, wall: float, failure: str
) -> int:
    """Say where the results are and how the run ended; the exit status."""
    logs = sup.logs
    plant = sup.exits.get("plant")
    late = plant is not None and plant.status == EXIT_REAL_TIME_NOT_HELD and plan.mode != "sim"
    failed = plant is not None and plant.status == EXIT_INTEGRATION_FAILED and plan.mode == "sim"
    failures = [failure] if failure else sup.failures_at_shutdown(_allowed(plan.mode))
    if failures or math.isnan(wall):
        ended = "failed" if failures else "interrupted"
        print(f"lubrig rig: {ended} before the run ended; what was recorded is in {bag}")
    else:
        print(f"lubrig rig: run finished in {wall:.1f} s wall; results in {bag}")
    print(f"  run configuration: {plan.run_config}")
    print(f"  node logs:         {logs}")
    print(f"  bag:               {bag / 'bag'}" if plan.recorded else "  (--no-recorder: nothing recorded)")
    if failures:
        print(f"lubrig rig: error: {'; '.join(failures)}", file=sys.stderr)
        return EXIT_FAILED
    if failed:  # what was published before the failed sample is recorded; no report of a broken run
        print(f"lubrig rig: error: {_plant_verdict(logs / 'plant.log', 'the run ends')}", file=sys.stderr)
        return EXIT_INTEGRATION_FAILED
    if plan.recorded and not args.no_report and not math.isnan(wall):
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
        "--max-lag",
        type=_positive,
        metavar="S",
        help=f"realtime: {lag.description} (default {lag.default:g} s; valid {lag.expected()})",
    )
    policy = parameter("plant", "lag_policy")
    parser.add_argument(
        "--lag-policy",
        choices=policy.choices,
        help=f"realtime: what the plant does beyond --max-lag (default {policy.default}); either way "
        f"lubrig rig ends with status {EXIT_REAL_TIME_NOT_HELD} naming the cause",
    )
    parser.add_argument(
        "--namespace",
        default=DEFAULT_NAMESPACE,
        metavar="NS",
        help=f"ROS namespace of the rig's nodes, topics and services (default {DEFAULT_NAMESPACE})",
    )
    parser.add_argument("--convention", choices=CONVENTIONS, help="override the convention")
    parser.add_argument("--duration", type=_positive, metavar="S", help="run length in s")
    parser.add_argument(
        "--run-dir",
        "--bag",
        dest="run_dir",
        required=True,
        metavar="DIR",
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
        "--no-clock",
        action="store_true",
        help="sim: the plant does not publish /clock (one owner per ROS domain: use it for a "
        "second rig on the same domain)",
    )
    parser.add_argument("--no-report", action="store_true", help="do not write DIR/report")
    parser.add_argument(
        "--view",
        nargs="?",
        type=functools.partial(tcp_port, lowest=1),  # the URL printed must be the one served
        const=DEFAULT_PORT,
        metavar="PORT",
        help=f"also serve the run to Foxglove on ws://127.0.0.1:PORT (default {DEFAULT_PORT}, "
        f"valid 1..{HIGHEST_PORT}; lubrig view)",
    )
    parser.add_argument(
        "--view-allow",
        action="append",
        choices=WAYS,
        default=[],
        metavar="WAY",
        help=f"with --view: let Foxglove clients act on the rig that way ({', '.join(WAYS)}; "
        "repeatable): lubrig view's --allow-WAY, without authentication",
    )
    parser.set_defaults(func=run)
