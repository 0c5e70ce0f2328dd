"""The launch plan of one rig run: which nodes run, with which parameters and remappings (no ROS).

Both launchers turn the same plan into processes, so the wiring of the nodes is written once:
`lubrig rig` (cli/rig.py: `ros_args` gives each node's `--ros-args` command line) and
launch/rig.launch.py (launch_ros `Node` actions from the same `NodeLaunch` fields).

What the plan decides, from the mode and whether the run is recorded:

- every node reads the resolved run from one file (`config_file`), the node settings from
  config/nodes.yaml (`params_file`), and runs in the rig's namespace;
- sim: every node on the rig's ROS clock (`use_sim_time`), the plant publishes /clock unless told
  not to (one owner per ROS domain);
- recorded: the plant and belt_drive hold the run until the recorder has subscribed and its
  subscriptions are matched (`wait_for_subscriber`), and in sim belt_drive paces on the
  recorder's flow_progress (`required_consumers`) when the recorder reports it;
- the plant's declared band source is belt_drive (`band_source`): any other publisher of band
  input is reported by the plant, and the plant starts its run only once a band reader has
  matched belt_drive (sim: it announces itself then; realtime: its loop starts then); so
  belt_drive, which starts on that announcement, waits for no other discovery (`start_delay`
  0): every subscriber that must have the first band block is named;
- sim: the plant holds the run until the analysis has subscribed to state_block
  (`state_subscribers`): it has the first samples however long its start-up takes;
- start order (`after`): the plant starts once belt_drive and the analysis have printed their
  start lines, unless the recorder holds a sim run anyway (then all start at once: their
  CPU-bound start-ups overlap). Wall clock: the plant's deadlines start with it, and the others'
  imports beside its first ticks made those late; sim without a recorder: a short run could be
  over before the analysis is up.
"""

from __future__ import annotations

import signal
from dataclasses import dataclass
from pathlib import Path

from ..interface.contract import DEFAULT_NAMESPACE, RECORDER_PARTICIPANT

#: The rig's nodes (console scripts of the same names); the recorder and the view are apart.
NODES: tuple[str, ...] = ("plant", "belt_drive", "analysis")
#: Node-name prefix of the recorder's nodes (<namespace>/lubrig_recorder, …_w<i> for its workers).
RECORDER_NODE_PREFIX = RECORDER_PARTICIPANT
#: The plant's declared band source in a launched rig.
BAND_SOURCE = "belt_drive"
#: `lubrig rig`'s own node, <namespace>/LAUNCHER_NODE, on the graph from the namespace check until
#: the rig's nodes have stopped: another launcher or a rig node starting meanwhile sees the
#: namespace held (cli/rig_ros.py, nodes/graph.py NamespaceGuard).
LAUNCHER_NODE = "lubrig_rig_launcher"
#: What each process prints once it is set up (its start line).
READY_LINES: dict[str, str] = {
    "recorder": "recorder: recording",
    "view": "view: serving",
    "belt_drive": "belt_drive: mode=",
    "analysis": "analysis: window",
    "plant": "plant: mode=",
    "plant_loop": "subscribed; the loop starts",  # a wall-clock plant waiting for the recorder
}
#: Exit statuses of a node that ended cleanly: 0, or killed by the SIGINT that stops it while it
#: is still importing (nodes/entry.py).
CLEAN_EXITS: tuple[int, ...] = (0, -signal.SIGINT)

ParameterValue = bool | int | float | str | list[str]


@dataclass(frozen=True)
class NodeLaunch:
    """One node of the plan: executable (= node name), parameters, remappings, start condition."""

    name: str
    parameters: dict[str, ParameterValue]
    remappings: tuple[tuple[str, str], ...] = ()
    #: nodes whose start lines this one waits for before it starts
    after: tuple[str, ...] = ()


@dataclass(frozen=True)
class RigPlan:
    """The nodes of one run, in start order, and what they share."""

    mode: str
    namespace: str
    run_config: Path
    params_file: Path
    nodes: tuple[NodeLaunch, ...]
    recorded: bool
    publish_clock: bool

    def node(self, name: str) -> NodeLaunch:
        """The plan's node `name` (KeyError naming the valid ones)."""
        for node in self.nodes:
            if node.name == name:
                return node
        raise KeyError(f"node {name!r} is not in the plan; valid: {[n.name for n in self.nodes]}")

    def ros_args(self, name: str) -> list[str]:
        """The `--ros-args` command line of node `name`: namespace, node settings, parameters."""
        node = self.node(name)
        args = ["--ros-args", "-r", f"__ns:={self.namespace}", "--params-file", str(self.params_file)]
        for source, target in node.remappings:
            args += ["-r", f"{source}:={target}"]
        for key, value in node.parameters.items():
            args += ["-p", f"{key}:={ros_value(value)}"]
        return args


def ros_value(value: ParameterValue) -> str:
    """A parameter value as `-p name:=VALUE` takes it (YAML: true/false, ['a', 'b'])."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, list):
        return "[" + ", ".join(f"'{v}'" for v in value) + "]"
    return str(value)


def rig_plan(
    run_config: Path,
    params_file: Path,
    mode: str,
    namespace: str = DEFAULT_NAMESPACE,
    *,
    recorded: bool = False,
    recorder_reports_progress: bool = True,
    publish_clock: bool = True,
    plant_extra: dict[str, ParameterValue] | None = None,
) -> RigPlan:
    """The plan of a run in `mode` (see module docstring); `plant_extra`: further plant parameters.

    `publish_clock` applies to sim only (the plant publishes /clock in no other mode).
    """
    sim = mode == "sim"
    clock = sim and publish_clock
    shared: dict[str, ParameterValue] = {"config_file": str(run_config), "use_sim_time": sim}
    plant: dict[str, ParameterValue] = {**shared, "mode": mode, "band_source": BAND_SOURCE}
    belt: dict[str, ParameterValue] = {**shared, "mode": mode, "start_delay": 0.0}
    if clock:
        plant["publish_clock"] = True
    if sim:  # the analysis takes every sample from the first: the run waits for its subscription
        plant["state_subscribers"] = ["analysis"]
    if recorded:  # nothing published unrecorded
        plant["wait_for_subscriber"] = belt["wait_for_subscriber"] = RECORDER_NODE_PREFIX
        if sim and recorder_reports_progress:
            belt["required_consumers"] = [RECORDER_PARTICIPANT]
    plant.update(plant_extra or {})
    held_by_recorder = sim and recorded
    plant_after = () if held_by_recorder else ("belt_drive", "analysis")
    nodes = (
        NodeLaunch("belt_drive", belt),
        NodeLaunch("analysis", dict(shared)),
        NodeLaunch("plant", plant, after=plant_after),
    )
    return RigPlan(mode, namespace, run_config, params_file, nodes, recorded, clock)
