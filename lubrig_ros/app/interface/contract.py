"""The rig's ROS interface as data: topics, services, QoS and node parameters (no ROS import).

The node parameters live in app/interface/node_parameters.py and are re-exported here. Every other place
derives from this module: the nodes create their publishers, subscriptions,
services and parameters from it, the recorder and replay take their topic list and QoS from it,
and the tables in README.md, docs/topics.md and docs/nodes.md are generated from it
(lubrig_ros/app/interface/contract_docs.py; test/test_contract.py keeps them in sync).

Names are stored RELATIVE (``band_velocity``, ``plant/reset``); only the ROS-wide standard topics
``/clock`` and ``/diagnostics`` are absolute. The nodes hand rclpy the relative names
(nodes/interfaces.py), so rcl resolves them against the node's namespace and applies remap rules
(``-r __ns:=/rig2``, ``-r band_velocity:=/my/band``, launch namespaces and remappings). The
default namespace ``/lubrig`` (DEFAULT_NAMESPACE) is where the launchers put the nodes, and the
nodes' own default when started without ``__ns``. `resolve` computes the absolute name for
processes that are not in the rig's namespace (recorder, replay, launcher, tests). Message and
service types are strings ("std_msgs/msg/Float64"), QoS is plain data (`QoS`); the ROS adapters
turn them into rclpy objects (nodes/interfaces.py).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

from lubrig_ros.core.errors import InputError

from .names import NAMESPACE_MAX_LENGTH as NAMESPACE_MAX_LENGTH
from .names import resolve as resolve
from .names import validate_name as validate_name
from .names import validate_namespace as validate_namespace
from .node_parameters import ANALYSIS_PARAMETERS as ANALYSIS_PARAMETERS
from .node_parameters import BAND_VELOCITY_LIMIT as BAND_VELOCITY_LIMIT
from .node_parameters import BELT_DRIVE_PARAMETERS as BELT_DRIVE_PARAMETERS
from .node_parameters import DEFAULT_BLOCK_LENGTH as DEFAULT_BLOCK_LENGTH
from .node_parameters import DEFAULT_FLOW_WINDOW as DEFAULT_FLOW_WINDOW
from .node_parameters import DEFAULT_LAG_POLICY as DEFAULT_LAG_POLICY
from .node_parameters import DEFAULT_LOOKAHEAD as DEFAULT_LOOKAHEAD
from .node_parameters import DEFAULT_MAX_LAG as DEFAULT_MAX_LAG
from .node_parameters import DEFAULT_OUTPUT_BLOCK_LENGTH as DEFAULT_OUTPUT_BLOCK_LENGTH
from .node_parameters import DEFAULT_REALTIME_PRIORITY as DEFAULT_REALTIME_PRIORITY
from .node_parameters import DEFAULT_TICK_STEP_ATTEMPTS as DEFAULT_TICK_STEP_ATTEMPTS
from .node_parameters import FRICTION_FIELDS as FRICTION_FIELDS
from .node_parameters import FRICTION_LAW as FRICTION_LAW
from .node_parameters import LAG_POLICIES as LAG_POLICIES
from .node_parameters import MAX_BLOCK_LENGTH as MAX_BLOCK_LENGTH
from .node_parameters import MAX_FLOW_WINDOW as MAX_FLOW_WINDOW
from .node_parameters import MODES as MODES
from .node_parameters import NODE_PARAMETERS as NODE_PARAMETERS
from .node_parameters import PLANT_PARAMETERS as PLANT_PARAMETERS
from .node_parameters import PROFILE_PARAMETERS as PROFILE_PARAMETERS
from .node_parameters import REALTIME_PRIORITY as REALTIME_PRIORITY
from .node_parameters import RECORDER_PARTICIPANT as RECORDER_PARTICIPANT
from .node_parameters import RIG_FIELDS as RIG_FIELDS
from .node_parameters import RUN_SELECTION as RUN_SELECTION
from .node_parameters import WAIT_FOR_SUBSCRIBER as WAIT_FOR_SUBSCRIBER
from .node_parameters import NodeParameter as NodeParameter
from .node_parameters import ParameterType as ParameterType
from .node_parameters import friction_fields as friction_fields
from .node_parameters import friction_parameters as friction_parameters
from .node_parameters import parameter as parameter
from .node_parameters import plant_parameters as plant_parameters
from .node_parameters import profile_parameter as profile_parameter

DEFAULT_NAMESPACE = "/lubrig"
#: Modes whose rig time is the plant's own (advanced by band input), not the wall clock.
STEPPED_MODES: tuple[str, ...] = ("sim", "lockstep")
#: Exit status of a wall-clock plant (and `lubrig rig`) whose run did not hold real time.
EXIT_REAL_TIME_NOT_HELD = 3
#: Exit status of a stepped-mode plant (sim, lockstep) whose run ended on a sample that could
#: not be integrated (app/plant/session.py, "Integration failure"); `lubrig rig` ends with it.
EXIT_INTEGRATION_FAILED = 4

# ------------------------------------------------------------------------------------- QoS

Reliability = Literal["reliable", "best_effort"]
Durability = Literal["volatile", "transient_local"]
History = Literal["keep_last", "keep_all"]


@dataclass(frozen=True)
class QoS:
    """A QoS profile as plain data (the names of the rclpy/rmw policies, lower case)."""

    reliability: Reliability = "reliable"
    durability: Durability = "volatile"
    history: History = "keep_last"
    depth: int = 1000

    @property
    def latched(self) -> bool:
        """True for transient_local durability: late subscribers get the last message(s)."""
        return self.durability == "transient_local"

    def describe(self) -> str:
        """Short text for the documentation tables, e.g. 'reliable, volatile, keep_last 1000'."""
        history = f"keep_last {self.depth}" if self.history == "keep_last" else "keep_all"
        return f"{self.reliability}, {self.durability}, {history}"


#: Sample streams (band, plant outputs, /clock): reliable, deep queue, volatile.
STREAM_QOS = QoS(depth=1000)
#: Blocks of samples and flow-control progress: reliable, volatile (a block is up to block_length samples).
BLOCK_QOS = QoS(depth=100)
#: Analysis outputs and diagnostics.
ANALYSIS_QOS = QoS(depth=10)
#: Once-per-run messages (run configuration, run complete), latched.
LATCHED_QOS = QoS(durability="transient_local", depth=1)

# ---------------------------------------------------------------------------------- topics

OUTPUT_RATE = "output rate"  # = sample_rate: per wall second (realtime), per rig second (sim)


@dataclass(frozen=True)
class Topic:
    """One topic: name (relative unless ROS-wide), type, QoS, who publishes, rate, unit, meaning."""

    name: str
    msgtype: str
    qos: QoS
    publisher: str
    rate: str
    unit: str
    description: str

    @property
    def depth(self) -> int:
        """QoS history depth."""
        return self.qos.depth

    @property
    def latched(self) -> bool:
        """QoS durability transient_local."""
        return self.qos.latched

    def resolved(self, namespace: str = DEFAULT_NAMESPACE) -> Topic:
        """The topic with its name resolved in `namespace`."""
        return replace(self, name=resolve(namespace, self.name))


@dataclass(frozen=True)
class Service:
    """One service: relative name, type, server node, meaning."""

    name: str
    srvtype: str
    server: str
    description: str

    def resolved(self, namespace: str = DEFAULT_NAMESPACE) -> Service:
        """The service with its name resolved in `namespace`."""
        return replace(self, name=resolve(namespace, self.name))


def _t(name: str, msgtype: str, qos: QoS, publisher: str, rate: str, unit: str, text: str) -> Topic:
    return Topic(name, msgtype, qos, publisher, rate, unit, text)


TOPICS: tuple[Topic, ...] = (
    _t(
        "band_velocity",
        "std_msgs/msg/Float64",
        STREAM_QOS,
        "external rig software (rig_in_loop, lockstep)",
        OUTPUT_RATE,
        "m/s",
        "band velocity v_band, one sample per message",
    ),
    _t(
        "band_velocity_block",
        "lubrig_interfaces/msg/BandVelocityBlock",
        BLOCK_QOS,
        "belt_drive or external rig software",
        "sim: output rate / block_length; realtime: one per flow_progress of the plant",
        "m/s",
        "consecutive band velocity samples v_band with the sample index of the first (belt_drive: "
        "sim paced by flow_progress, realtime sent lookahead samples ahead)",
    ),
    _t(
        "state",
        "lubrig_interfaces/msg/RigState",
        STREAM_QOS,
        "plant (lockstep, realtime, rig_in_loop; state_per_sample)",
        OUTPUT_RATE,
        "SI",
        "one output sample of the rig: x, ẋ, μ, friction force, v_band, v_rel, "
        "belt travel, sample_index, segment",
    ),
    _t(
        "state_block",
        "lubrig_interfaces/msg/RigStateBlock",
        BLOCK_QOS,
        "plant (every mode)",
        "sim, lockstep: one per band block; realtime, rig_in_loop: output rate / output_block_length",
        "SI",
        "consecutive output samples of the rig (fields of state); realtime: each sample's "
        "lateness and the samples skipped behind real time",
    ),
    _t(
        "flow_progress",
        "lubrig_interfaces/msg/FlowProgress",
        BLOCK_QOS,
        "plant (every mode), recorder, required consumers",
        "one per block taken",
        "1",
        "samples of the current segment a participant has taken; belt_drive paces on the slowest",
    ),
    _t(
        "displacement",
        "std_msgs/msg/Float64",
        STREAM_QOS,
        "plant (scalar_topics true)",
        OUTPUT_RATE,
        "m",
        "displacement x of the mass (optional, for simple tools)",
    ),
    _t(
        "velocity",
        "std_msgs/msg/Float64",
        STREAM_QOS,
        "plant (scalar_topics true)",
        OUTPUT_RATE,
        "m/s",
        "velocity ẋ of the mass (optional, for simple tools)",
    ),
    _t(
        "friction_coefficient",
        "std_msgs/msg/Float64",
        STREAM_QOS,
        "plant (scalar_topics true)",
        OUTPUT_RATE,
        "1",
        "friction coefficient μ(v_rel) (optional, for simple tools)",
    ),
    _t(
        "measured_displacement",
        "std_msgs/msg/Float64",
        STREAM_QOS,
        "external rig software (rig_in_loop, plant shadow true)",
        OUTPUT_RATE,
        "m",
        "the real rig's measured displacement x, one sample per message, each after the band "
        "value it answers (pairing: docs/fitting.md)",
    ),
    _t(
        "shadow_block",
        "lubrig_interfaces/msg/ShadowBlock",
        BLOCK_QOS,
        "plant (rig_in_loop, shadow true)",
        "one per state_block with new pairs",
        "m",
        "measured and simulated displacement per paired sample (sample_index), residual measured − "
        "simulated and its running RMS over the segment",
    ),
    _t(
        "/clock",
        "rosgraph_msgs/msg/Clock",
        STREAM_QOS,
        "plant (sim mode, publish_clock true: one owner)",
        "one per block + 5 Hz heartbeat",
        "s",
        "rig time",
    ),
    _t(
        "run_config",
        "std_msgs/msg/String",
        LATCHED_QOS,
        "plant",
        "once, latched",
        "YAML",
        "the full run configuration (in a bag: the launcher's run_config.yaml)",
    ),
    _t(
        "run_complete",
        "std_msgs/msg/Bool",
        LATCHED_QOS,
        "plant",
        "on change, latched",
        "1",
        "false at start and after a reset, true once a sim run reaches its duration",
    ),
    _t(
        "dominant_frequency",
        "std_msgs/msg/Float64",
        ANALYSIS_QOS,
        "analysis",
        "1 / publish_period (5 Hz)",
        "Hz",
        "strongest wavelet component",
    ),
    _t(
        "wavelet_power",
        "std_msgs/msg/Float64MultiArray",
        ANALYSIS_QOS,
        "analysis",
        "1 / publish_period",
        "1",
        'newest ≤ max_columns columns of normalized power |W|²/σ², dims ["frequency", "time"] (row-major)',
    ),
    _t(
        "wavelet_image",
        "sensor_msgs/msg/Image",
        ANALYSIS_QOS,
        "analysis",
        "1 / publish_period",
        "rgb8",
        "n_scales × image_width, log power over 4 decades, high frequency on top",
    ),
    _t(
        "wavelet_frame",
        "lubrig_interfaces/msg/WaveletFrame",
        ANALYSIS_QOS,
        "analysis",
        "1 / publish_period",
        "1",
        "wavelet_power with its frequency and time axes",
    ),
    _t(
        "stability",
        "lubrig_interfaces/msg/StabilityFlags",
        ANALYSIS_QOS,
        "analysis",
        "1 / publish_period",
        "SI",
        "every stability flag with the values it derives from",
    ),
    _t(
        "linear_zone",
        "std_msgs/msg/UInt8",
        ANALYSIS_QOS,
        "analysis",
        "1 / publish_period",
        "1",
        "friction zone 1, 2 or 3 at the current band velocity",
    ),
    _t(
        "critical_damping_ratio",
        "std_msgs/msg/Float64",
        ANALYSIS_QOS,
        "analysis",
        "1 / publish_period",
        "1",
        "ζ_crit at the current band velocity",
    ),
    _t(
        "oscillation_growing",
        "std_msgs/msg/Bool",
        ANALYSIS_QOS,
        "analysis",
        "1 / publish_period (once the window is full)",
        "1",
        "envelope growth flag",
    ),
    _t(
        "measured/dominant_frequency",
        "std_msgs/msg/Float64",
        ANALYSIS_QOS,
        "analysis (shadow_block arriving)",
        "1 / publish_period",
        "Hz",
        "dominant_frequency of the real rig's measured displacement",
    ),
    _t(
        "measured/wavelet_frame",
        "lubrig_interfaces/msg/WaveletFrame",
        ANALYSIS_QOS,
        "analysis (shadow_block arriving)",
        "1 / publish_period",
        "1",
        "wavelet_frame of the real rig's measured displacement",
    ),
    _t(
        "measured/stability",
        "lubrig_interfaces/msg/StabilityFlags",
        ANALYSIS_QOS,
        "analysis (shadow_block arriving)",
        "1 / publish_period",
        "SI",
        "stability flags of the measured displacement (stick: v_rel from its backward differences)",
    ),
    _t(
        "/diagnostics",
        "diagnostic_msgs/msg/DiagnosticArray",
        ANALYSIS_QOS,
        "plant, analysis",
        "plant 1 / diagnostics_period (1 Hz), analysis 1 / publish_period",
        "key/values",
        "statuses named `<node FQN>: <group>`: plant `/lubrig/plant: timing`, `… band input` (shadow "
        "mode: `… shadow`); "
        "analysis `/lubrig/analysis: linear`, `… oscillation`, `… stick`, `… resonance` "
        "(values = core.flags fields)",
    ),
)

SERVICES: tuple[Service, ...] = (
    Service(
        "plant/reset",
        "std_srvs/srv/Trigger",
        "plant",
        "rig time back to 0 and the initial state in a new segment; pending rig-parameter "
        "updates applied (sim: /clock and the stamps go on from the old segment's end, never back)",
    ),
    Service(
        "plant/pause",
        "std_srvs/srv/SetBool",
        "plant",
        "true pauses, false resumes (sim: band samples queue up while paused and are integrated on resume)",
    ),
)

_BY_NAME: dict[str, Topic] = {t.name: t for t in TOPICS}
_SERVICES_BY_NAME: dict[str, Service] = {s.name: s for s in SERVICES}


def topic(name: str) -> Topic:
    """The contract's topic by its (relative) name; KeyError naming the valid ones."""
    try:
        return _BY_NAME[name]
    except KeyError:
        raise KeyError(f"topic {name!r} is not in the contract; valid: {sorted(_BY_NAME)}") from None


def service(name: str) -> Service:
    """The contract's service by its (relative) name."""
    try:
        return _SERVICES_BY_NAME[name]
    except KeyError:
        valid = sorted(_SERVICES_BY_NAME)
        raise KeyError(f"service {name!r} is not in the contract; valid: {valid}") from None


def documented_topics(namespace: str = DEFAULT_NAMESPACE) -> dict[str, Topic]:
    """Every topic of the contract resolved in `namespace`, keyed by absolute name."""
    resolved = (t.resolved(namespace) for t in TOPICS)
    return {t.name: t for t in resolved}


#: One message per sample, beside state_block (which carries the same samples): not recorded
#: from a wall-clock rig by default (`recorded_topics`); `recorder --topics` can add them.
PER_SAMPLE_TOPICS: tuple[str, ...] = (
    "state",
    "band_velocity",
    "displacement",
    "velocity",
    "friction_coefficient",
    "measured_displacement",
)


#: Topics that exist only beside a rig_in_loop plant with `shadow` true (its input, its pairs and
#: the analysis of the measured signal, which starts with the first pairs); no node has them else.
SHADOW_TOPICS: tuple[str, ...] = (
    "measured_displacement",
    "shadow_block",
    "measured/dominant_frequency",
    "measured/wavelet_frame",
    "measured/stability",
)


#: The sample streams every `lubrig rig` run publishes (the plant's blocks; belt_drive's band
#: blocks, sent ahead in every mode): its recording must hold samples of each.
RIG_SAMPLE_STREAMS: tuple[str, ...] = ("state_block", "band_velocity_block")


def recorded_topics(mode: str) -> tuple[str, ...]:
    """Relative names of the topics `lubrig rig` records in `mode` (every documented one in sim)."""
    names = tuple(t.name for t in TOPICS)
    if mode in STEPPED_MODES:
        return names
    return tuple(n for n in names if n not in PER_SAMPLE_TOPICS)


def select_topics(namespace: str, names: list[str] | tuple[str, ...] | None) -> list[Topic]:
    """The named topics (relative or absolute, all of them if none) resolved in `namespace`.

    ValueError naming a name that is not in the contract and the valid ones.
    """
    docs = documented_topics(namespace)
    if not names:
        return list(docs.values())
    selected = []
    for name in names:
        full = resolve(namespace, name)
        if full not in docs:
            raise InputError(f"topic {name!r} is not in the topic contract; valid: {', '.join(sorted(docs))}")
        selected.append(docs[full])
    return selected
