"""The rig's ROS interface as data: topics, services, QoS and node parameters (no ROS import).

Every other place derives from this module: the nodes create their publishers, subscriptions,
services and parameters from it, the recorder and replay take their topic list and QoS from it,
and the tables in README.md, docs/topics.md and docs/nodes.md are generated from it
(lubrig_ros/app/contract_docs.py; test/test_contract.py keeps them in sync).

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

import math
import re
from dataclasses import dataclass, fields, replace
from functools import cache
from typing import Any, Literal

from ..core.friction_laws import DEFAULT_LAW, law_parameters
from ..core.params import CONVENTIONS, RIG_RANGES, ParameterError

DEFAULT_NAMESPACE = "/lubrig"
#: Longest namespace ROS 2 accepts (rmw: RMW_NAMESPACE_MAX_NAME_LENGTH; measured with rclpy: 245).
NAMESPACE_MAX_LENGTH = 245
MODES: tuple[str, ...] = ("sim", "lockstep", "realtime", "rig_in_loop")
#: Modes whose rig time is the plant's own (advanced by band input), not the wall clock.
STEPPED_MODES: tuple[str, ...] = ("sim", "lockstep")
#: What a wall-clock plant does once it is more than max_lag behind real time (app/plant_session.py).
LAG_POLICIES: tuple[str, ...] = ("skip", "stop")
DEFAULT_LAG_POLICY = "skip"
#: s: lateness a wall-clock plant catches up on before it has not held real time.
DEFAULT_MAX_LAG = 0.02
#: Samples per state_block in the wall-clock modes (1 kHz: 50 blocks per second).
DEFAULT_OUTPUT_BLOCK_LENGTH = 20
#: Exit status of a wall-clock plant (and `lubrig rig`) whose run did not hold real time.
EXIT_REAL_TIME_NOT_HELD = 3
#: Exit status of a stepped-mode plant (sim, lockstep) whose run ended on a sample that could
#: not be integrated (app/plant_session.py, "Integration failure"); `lubrig rig` ends with it.
EXIT_INTEGRATION_FAILED = 4
#: Band samples belt_drive sends ahead of the realtime plant (its flow_progress).
DEFAULT_LOOKAHEAD = 200

# ----------------------------------------------------------------------------------- names

_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


def _name_problem(name: str, *, namespace: bool) -> str | None:
    """Why `name` breaks ROS 2's rules for a namespace (or a topic/service name), else None."""
    kind = "namespace" if namespace else "name"
    if not name:
        return f"a {kind} must not be empty"
    if namespace and not name.startswith("/"):
        return "a namespace must be absolute (start with '/')"
    bad = sorted({c for c in name if not (c.isascii() and (c.isalnum() or c in "_/"))})
    if bad:
        return f"a {kind} may hold only letters, digits, '_' and '/' (not {''.join(bad)!r})"
    if "//" in name:
        return f"a {kind} must not contain '//'"
    if name.endswith("/") and name != "/":
        return f"a {kind} must not end with '/' (unless it is just '/')"
    if not namespace and name == "/":
        return "a name must not be just '/'"
    tokens = [t for t in name.split("/") if t]
    if any(not _TOKEN.match(t) for t in tokens):
        return f"no token of a {kind} may start with a digit"
    if namespace and len(name) > NAMESPACE_MAX_LENGTH:
        return f"a namespace may have at most {NAMESPACE_MAX_LENGTH} characters (has {len(name)})"
    return None


def validate_namespace(namespace: str, what: str = "namespace") -> str:
    """Return `namespace` if it is a valid ROS 2 namespace, else ParameterError (a ValueError).

    ROS 2's rules (rmw_validate_namespace; test/test_contract.py checks against rclpy's own
    validator): absolute, only letters, digits, '_' and '/', no '//', no trailing '/' (except
    the root namespace '/'), no token starting with a digit, at most 245 characters. So
    '/lubrig', '/rig_2' and '/' are valid; '/rig-2', 'lubrig', '/lubrig/' and '/2rig' are not.
    """
    if not isinstance(namespace, str):
        raise ParameterError(f"{what}={namespace!r} is not valid; expected a string such as '/lubrig'")
    problem = _name_problem(namespace, namespace=True)
    if problem:
        raise ParameterError(
            f"{what}={namespace!r} is not valid: {problem}; expected an absolute ROS name such as "
            "'/lubrig' or '/rig_2'"
        )
    return namespace


def validate_name(name: str, what: str = "name") -> str:
    """Return a topic or service name (relative or absolute) if ROS 2 accepts it, else ParameterError."""
    problem = _name_problem(name, namespace=False) if isinstance(name, str) else "not a string"
    if problem:
        raise ParameterError(f"{what}={name!r} is not valid: {problem}")
    return name


def resolve(namespace: str, name: str) -> str:
    """Absolute name of `name` in `namespace` (absolute names are kept), as rcl resolves it."""
    validate_name(name)
    if name.startswith("/"):
        return name
    namespace = validate_namespace(namespace)
    return f"{'' if namespace == '/' else namespace}/{name}"


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
    _t("band_velocity", "std_msgs/msg/Float64", STREAM_QOS, "external rig software (rig_in_loop, lockstep)",
       OUTPUT_RATE, "m/s", "band velocity v_band, one sample per message"),
    _t("band_velocity_block", "lubrig_interfaces/msg/BandVelocityBlock", BLOCK_QOS,
       "belt_drive or external rig software",
       "sim: output rate / block_length; realtime: one per flow_progress of the plant", "m/s",
       "consecutive band velocity samples v_band with the sample index of the first (belt_drive: "
       "sim paced by flow_progress, realtime sent lookahead samples ahead)"),
    _t("state", "lubrig_interfaces/msg/RigState", STREAM_QOS,
       "plant (lockstep, realtime, rig_in_loop; state_per_sample)",
       OUTPUT_RATE, "SI", "one output sample of the rig: x, ẋ, μ, friction force, v_band, v_rel, "
       "belt travel, sample_index, segment"),
    _t("state_block", "lubrig_interfaces/msg/RigStateBlock", BLOCK_QOS, "plant (every mode)",
       "sim, lockstep: one per band block; realtime, rig_in_loop: output rate / output_block_length",
       "SI", "consecutive output samples of the rig (fields of state); realtime: each sample's "
       "lateness and the samples skipped behind real time"),
    _t("flow_progress", "lubrig_interfaces/msg/FlowProgress", BLOCK_QOS,
       "plant (every mode), recorder, required consumers", "one per block taken", "1",
       "samples of the current segment a participant has taken; belt_drive paces on the slowest"),
    _t("displacement", "std_msgs/msg/Float64", STREAM_QOS, "plant (scalar_topics true)", OUTPUT_RATE,
       "m", "displacement x of the mass (optional, for simple tools)"),
    _t("velocity", "std_msgs/msg/Float64", STREAM_QOS, "plant (scalar_topics true)", OUTPUT_RATE,
       "m/s", "velocity ẋ of the mass (optional, for simple tools)"),
    _t("friction_coefficient", "std_msgs/msg/Float64", STREAM_QOS, "plant (scalar_topics true)",
       OUTPUT_RATE, "1", "friction coefficient μ(v_rel) (optional, for simple tools)"),
    _t("/clock", "rosgraph_msgs/msg/Clock", STREAM_QOS, "plant (sim mode, publish_clock true: one owner)",
       "one per block + 5 Hz heartbeat", "s", "rig time"),
    _t("run_config", "std_msgs/msg/String", LATCHED_QOS, "plant", "once, latched", "YAML",
       "the full run configuration (in a bag: the launcher's run_config.yaml)"),
    _t("run_complete", "std_msgs/msg/Bool", LATCHED_QOS, "plant", "on change, latched", "1",
       "false at start and after a reset, true once a sim run reaches its duration"),
    _t("dominant_frequency", "std_msgs/msg/Float64", ANALYSIS_QOS, "analysis",
       "1 / publish_period (5 Hz)", "Hz", "strongest wavelet component"),
    _t("wavelet_power", "std_msgs/msg/Float64MultiArray", ANALYSIS_QOS, "analysis",
       "1 / publish_period", "1",
       'newest ≤ max_columns columns of normalized power |W|²/σ², dims ["frequency", "time"] '
       "(row-major)"),
    _t("wavelet_image", "sensor_msgs/msg/Image", ANALYSIS_QOS, "analysis", "1 / publish_period",
       "rgb8", "n_scales × image_width, log power over 4 decades, high frequency on top"),
    _t("wavelet_frame", "lubrig_interfaces/msg/WaveletFrame", ANALYSIS_QOS, "analysis",
       "1 / publish_period", "1", "wavelet_power with its frequency and time axes"),
    _t("stability", "lubrig_interfaces/msg/StabilityFlags", ANALYSIS_QOS, "analysis",
       "1 / publish_period", "SI", "every stability flag with the values it derives from"),
    _t("linear_zone", "std_msgs/msg/UInt8", ANALYSIS_QOS, "analysis", "1 / publish_period", "1",
       "friction zone 1, 2 or 3 at the current band velocity"),
    _t("critical_damping_ratio", "std_msgs/msg/Float64", ANALYSIS_QOS, "analysis",
       "1 / publish_period", "1", "ζ_crit at the current band velocity"),
    _t("oscillation_growing", "std_msgs/msg/Bool", ANALYSIS_QOS, "analysis",
       "1 / publish_period (once the window is full)", "1", "envelope growth flag"),
    _t("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray", ANALYSIS_QOS, "plant, analysis",
       "plant 1 / diagnostics_period (1 Hz), analysis 1 / publish_period", "key/values",
       "statuses named `<node FQN>: <group>`: plant `/lubrig/plant: timing`, `… band input`; "
       "analysis `/lubrig/analysis: linear`, `… oscillation`, `… stick`, `… resonance` "
       "(values = core.flags fields)"),
)

SERVICES: tuple[Service, ...] = (
    Service("plant/reset", "std_srvs/srv/Trigger", "plant",
            "rig time back to 0 and the initial state in a new segment; pending rig-parameter "
            "updates applied (sim: /clock and the stamps go on from the old segment's end, never back)"),
    Service("plant/pause", "std_srvs/srv/SetBool", "plant",
            "true pauses, false resumes (sim: band samples queue up while paused and are "
            "integrated on resume)"),
)

#: The rig's sample streams: the plant's outputs (per sample or per block, scalar topics optional),
#: its band input (per sample or per block), flow progress and /clock.
PLANT_TOPICS: tuple[str, ...] = (
    "state", "state_block", "displacement", "velocity", "friction_coefficient",
    "band_velocity", "band_velocity_block", "flow_progress", "/clock",
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


def plant_topics(namespace: str = DEFAULT_NAMESPACE) -> dict[str, Topic]:
    """The plant's high-rate topics (PLANT_TOPICS) resolved in `namespace`, keyed by absolute name."""
    resolved = (topic(n).resolved(namespace) for n in PLANT_TOPICS)
    return {t.name: t for t in resolved}


#: One message per sample, beside state_block (which carries the same samples): not recorded
#: from a wall-clock rig by default (`recorded_topics`); `recorder --topics` can add them.
PER_SAMPLE_TOPICS: tuple[str, ...] = (
    "state", "band_velocity", "displacement", "velocity", "friction_coefficient",
)


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
            raise ValueError(f"topic {name!r} is not in the topic contract; valid: {', '.join(sorted(docs))}")
        selected.append(docs[full])
    return selected


# ------------------------------------------------------------------------------ parameters

ParameterType = Literal["double", "integer", "string", "bool", "string_array"]


@dataclass(frozen=True)
class NodeParameter:
    """One ROS parameter of a node.

    `default` None means "from the selected run configuration" (`from_config` names the field);
    `low`/`high` bound numbers (`low_open`: strictly greater than low); `choices` lists the
    valid strings; `read_only` parameters are fixed at start-up, the others may be set at run time.
    """

    name: str
    type: ParameterType
    default: Any
    description: str
    unit: str = ""
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    choices: tuple[str, ...] = ()
    read_only: bool = True
    from_config: str = ""

    def expected(self) -> str:
        """What is valid, in words (used in error messages and the docs)."""
        unit = f" {self.unit}" if self.unit and self.unit not in ("1", "SI") else ""
        if self.choices:
            return f"one of {list(self.choices)}"
        if self.type == "string":
            return "a string"
        if self.type == "string_array":
            return "a list of strings"
        if self.type == "bool":
            return "true or false"
        number = "an integer" if self.type == "integer" else "a finite number"
        if self.low is not None and self.high is not None:
            return f"{_num(self.low)}..{_num(self.high)}{unit}"
        if self.low is not None:
            return f"{number} {'>' if self.low_open else '>='} {_num(self.low)}{unit}"
        if self.high is not None:
            return f"{number} <= {_num(self.high)}{unit}"
        return number

    def check(self, value: Any) -> Any:
        """Return `value` if valid for this parameter, else ParameterError naming value and range."""
        bad = ParameterError(f"{self.name}={value!r} is not valid; expected {self.expected()}")
        if self.type in ("double", "integer"):
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise bad
            if self.type == "integer" and not isinstance(value, int):
                raise bad
            if not math.isfinite(value):
                raise bad
            if self.low is not None and (value < self.low or (self.low_open and value <= self.low)):
                raise bad
            if self.high is not None and value > self.high:
                raise bad
        elif self.type == "string":
            if not isinstance(value, str) or (self.choices and value not in self.choices):
                raise bad
        elif self.type == "string_array":
            if isinstance(value, str) or not isinstance(value, list | tuple):
                raise bad
            if not all(isinstance(v, str) for v in value):
                raise bad
        elif not isinstance(value, bool):
            raise bad
        return value


def _num(x: float) -> str:
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e6 else f"{x:g}"


def _p(name: str, type_: ParameterType, default: Any, text: str, **kw: Any) -> NodeParameter:
    return NodeParameter(name, type_, default, text, **kw)


#: Run selection, shared by the three rig nodes (the launcher passes config_file).
RUN_SELECTION: tuple[NodeParameter, ...] = (
    _p("case", "integer", 0, "study case 1..10 (0: use config_file or the default)"),
    _p("config_file", "string", "",
       "run configuration YAML (the launcher passes the resolved run's file; empty: default)"),
    _p("topic_namespace", "string", "",
       "deprecated, must stay empty: topics and services follow the node namespace "
       "(--ros-args -r __ns:=/rig2, launch namespace=); a value other than the node's namespace "
       "is refused at start"),
)
WAIT_FOR_SUBSCRIBER = _p(
    "wait_for_subscriber", "string", "",
    "hold the run until a node whose name starts with this (e.g. the recorder, 'lubrig_recorder') "
    "subscribes to every output topic (sim, lockstep) or to state_block (realtime, rig_in_loop: "
    "the loop starts then); empty = do not wait",
)
DEFAULT_REALTIME_PRIORITY = 50
REALTIME_PRIORITY = _p(
    "realtime_priority", "integer", DEFAULT_REALTIME_PRIORITY,
    "realtime, rig_in_loop: SCHED_FIFO priority 1..99 of the plant's loop thread alone (where "
    "the process may; otherwise a warning and normal scheduling), and a CPU wake-up latency "
    "request of 0 (/dev/cpu_dma_latency, where writable); 0 keeps normal scheduling",
    low=0, high=99,
)
#: Band samples per BandVelocityBlock (sim); measured: docs/nodes.md "Block length".
DEFAULT_BLOCK_LENGTH = 250
MAX_BLOCK_LENGTH = 10_000
#: Band samples belt_drive may send beyond the slowest participant (sim).
DEFAULT_FLOW_WINDOW = 1000
MAX_FLOW_WINDOW = 1_000_000
#: Node name of the recorder's flow-progress participant, in the rig's namespace (`lubrig rig`
#: adds it to belt_drive's required_consumers when it records).
RECORDER_PARTICIPANT = "lubrig_recorder"


def flow_window_problem(flow_window: int, block_length: int) -> str | None:
    """Why this window could lose blocks with this block length, or None.

    Reliable keep_last QoS keeps BLOCK_QOS.depth unacknowledged messages per reader: a window
    of w samples puts at most ceil(w / block_length) + 1 blocks in flight towards the slowest
    participant (plus its progress message); keep that below the depth with a margin of 2.
    """
    most = (BLOCK_QOS.depth - 2) * block_length
    if flow_window > most:
        return (
            f"flow_window={flow_window} is too large for block_length={block_length}: at most "
            f"{most} samples ({BLOCK_QOS.depth - 2} blocks, the block topics' QoS depth "
            f"{BLOCK_QOS.depth} minus 2) may be in flight without a risk of losing a block"
        )
    return None


#: Largest |band velocity| the plant accepts from the band topic, m/s.
BAND_VELOCITY_LIMIT = 1e-2

RIG_FIELDS: tuple[str, ...] = ("mass", "natural_frequency", "damping_ratio")
RIG_UNITS = {"mass": "kg", "natural_frequency": "Hz", "damping_ratio": "1", "normal_force": "N"}
#: Units of the friction laws' fields (a field not listed here is documented as "SI").
FRICTION_UNITS = {
    # junction kinetics (core/params.py FrictionParameters)
    "shear_modulus": "Pa", "interface_thickness": "m", "interpenetration_thickness": "m",
    "yield_distance": "m", "thermal_break_time": "s", "reference_activation_time": "s",
    "reference_velocity": "m/s", "activation_exponent": "1", "reference_viscosity": "Pa·s",
    "shear_thinning_exponent": "1", "contact_area": "m²", "normal_force": "N",
    # Stribeck (core/stribeck.py StribeckParameters)
    "static_coefficient": "1", "kinetic_coefficient": "1", "stribeck_velocity": "m/s",
    "stribeck_exponent": "1", "viscous_coefficient": "s/m", "regularization_velocity": "m/s",
}


def friction_fields(law: str = DEFAULT_LAW) -> tuple[str, ...]:
    """The fields of friction law `law`'s parameter dataclass (core.friction_laws registry), in order.

    ParameterError naming the valid laws for an unknown one.
    """
    return tuple(f.name for f in fields(law_parameters(law)))


#: The default (junction-kinetics) law's fields.
FRICTION_FIELDS: tuple[str, ...] = friction_fields(DEFAULT_LAW)

FRICTION_LAW = _p(
    "friction.law", "string", None,
    "friction law of the run (core.friction_laws: junction_kinetics, stribeck or a registered "
    "one); the plant's friction.<field> parameters are this law's fields",
    from_config="rig.friction.law",
)


def friction_parameters(law: str = DEFAULT_LAW) -> tuple[NodeParameter, ...]:
    """The plant's `friction.<field>` parameters of law `law` (normal_force is rig.normal_force)."""
    return tuple(
        _p(f"friction.{n}", "double", None, f"friction law {n}; applied at the next reset",
           unit=FRICTION_UNITS.get(n, "SI"), read_only=False, from_config=f"rig.friction.{n}")
        for n in friction_fields(law)
        if n != "normal_force"
    )


#: Realtime plant: step attempts per tick. One sample of physical-convention
#: stick-slip at rtol 1e-12 needs up to about 610 (accepted and rejected, 30 s of case 1 and of
#: the default rig); 2000 leaves room for those and bounds a tick at about 4 ms (about 2 µs an
#: attempt on a quiet machine: 61 substeps took 0.13 ms), more under load.
DEFAULT_TICK_STEP_ATTEMPTS = 2000


@cache
def plant_parameters(law: str = DEFAULT_LAW) -> tuple[NodeParameter, ...]:
    """Every parameter of a plant whose run uses friction law `law`.

    The friction parameters derive from the law's parameter dataclass, so a run configuration
    with `friction: {law: stribeck, ...}` gets `friction.static_coefficient` etc.
    """
    return (
        *RUN_SELECTION,
        _p("mode", "string", "sim", " | ".join(MODES), choices=MODES),
        _p("sample_rate", "double", None, "output rate", unit="Hz", low=0.0, low_open=True,
           from_config="simulation.sample_rate"),
        _p("duration", "double", None,
           "run length in rig time (sim mode; wall-clock modes: with exit_when_complete)", unit="s",
           low=0.0, low_open=True, from_config="simulation.duration"),
        _p("rtol", "double", None, "integrator relative tolerance; applied at the next reset",
           low=1e-13, high=1e-2, read_only=False, from_config="simulation.rtol"),
        _p("initial_perturbation", "double", None, "x(0) = (1 + this) x0; applied at the next reset",
           read_only=False, from_config="simulation.initial_perturbation"),
        _p("convention", "string", None,
           "physical | paper | hertz (γ = 1, 1/ω0, 1/f0); empty: the run configuration's; applied "
           "at the next reset", choices=("", *CONVENTIONS), read_only=False,
           from_config="rig.convention"),
        _p("velocity_coupling", "double", None,
           "explicit γ in v_rel = v_band − γ ẋ, overriding the convention; 0: the convention's γ; "
           "applied at the next reset", low=0.0, read_only=False, from_config="rig.velocity_coupling"),
        *(
            _p(f"rig.{n}", "double", None, f"rig {n}; applied at the next reset", unit=RIG_UNITS[n],
               read_only=False, from_config=f"rig.{n}", low=RIG_RANGES[n][0], high=RIG_RANGES[n][1])
            for n in RIG_FIELDS
        ),
        _p("rig.normal_force", "double", None, "normal force N; applied at the next reset", unit="N",
           read_only=False, from_config="rig.friction.normal_force",
           low=RIG_RANGES["normal_force"][0], high=RIG_RANGES["normal_force"][1]),
        FRICTION_LAW,
        *friction_parameters(law),
        _p("band_velocity_limit", "double", BAND_VELOCITY_LIMIT,
           "largest accepted |v_band|; NaN/inf and larger values are rejected", unit="m/s", low=0.0,
           low_open=True),
        _p("stale_timeout", "double", 0.05, "time without good band input before the input is stale",
           unit="s", low=0.0, low_open=True),
        _p("tick_step_attempts", "integer", DEFAULT_TICK_STEP_ATTEMPTS,
           "realtime: integrator step attempts per call of the tick; a sample that needs more is "
           "an overrun, finished by further calls (the loop stays responsive, stop/pause/reset "
           "and diagnostics run between them) instead of blocking it", unit="attempts", low=1,
           high=1_000_000),
        _p("lag_policy", "string", DEFAULT_LAG_POLICY,
           "realtime, rig_in_loop: once more than max_lag behind real time, skip (keep real time: "
           "integrate the overdue samples with the band values known for them, publish none of "
           "them, declare the gap in the next state_block) or stop (no more output); ERROR either "
           "way, and the node exits with status 3 (app/plant_session.py)", choices=LAG_POLICIES),
        _p("max_lag", "double", DEFAULT_MAX_LAG,
           "realtime, rig_in_loop: lateness of a sample the plant catches up on; beyond it the rig "
           "has not held real time (lag_policy)", unit="s", low=0.0, low_open=True, high=10.0),
        _p("output_block_length", "integer", DEFAULT_OUTPUT_BLOCK_LENGTH,
           "realtime, rig_in_loop: samples per state_block (the recorder, analysis and live view "
           "take these; state stays one message per sample)", unit="samples", low=1, high=10_000),
        _p("state_per_sample", "bool", True,
           "realtime, rig_in_loop, lockstep: also publish one state (RigState) per sample, for rig "
           "software in the loop; wall-clock modes: only while the topic has a subscriber (about "
           "80 us per sample for the plant's loop)"),
        WAIT_FOR_SUBSCRIBER,
        _p("band_source", "string", "",
           "the declared band source: node name (in the plant's namespace) or fully qualified name "
           "of the one publisher of band input (the launchers: belt_drive); any other publisher "
           "is reported (band sources WARN, naming it); empty: any one publisher"),
        REALTIME_PRIORITY,
        _p("diagnostics_period", "double", 1.0, "time between /diagnostics", unit="s", low=0.0,
           low_open=True),
        _p("publish_clock", "bool", False,
           "sim: publish rig time on the global /clock (one per block + 5 Hz heartbeat); one "
           "owner per ROS domain: the launcher turns it on for a single rig only"),
        _p("exit_when_complete", "bool", False,
           "end the node once its run is over, exit status 0 (3 if a wall-clock run did not hold "
           "real time): sim, lockstep once run_complete is true; realtime, rig_in_loop once the "
           "sample at `duration` (counted from the first sample) is published; launch/rig.launch.py "
           "sets it, `lubrig rig` stops the nodes itself"),
        _p("scalar_topics", "bool", False,
           "also publish displacement, velocity and friction_coefficient as std_msgs/Float64, one "
           "message per sample (about 3 x 37 us per sample for the plant, and the same per "
           "subscriber: sim mode falls from block to sample speed)"),
    )


#: The plant's parameters with the default (junction-kinetics) law (plant_parameters(law) for another).
PLANT_PARAMETERS: tuple[NodeParameter, ...] = plant_parameters(DEFAULT_LAW)

BELT_DRIVE_PARAMETERS: tuple[NodeParameter, ...] = (
    *RUN_SELECTION,
    _p("mode", "string", "sim", "sim | realtime", choices=("sim", "realtime")),
    _p("sample_rate", "double", None, "output rate", unit="Hz", low=0.0, low_open=True,
       from_config="simulation.sample_rate"),
    _p("duration", "double", None, "run length (sim mode)", unit="s", low=0.0, low_open=True,
       from_config="simulation.duration"),
    _p("block_length", "integer", DEFAULT_BLOCK_LENGTH,
       "sim: band samples per band_velocity_block message (the plant answers with one state_block "
       "per block); results do not depend on it", unit="samples", low=1, high=MAX_BLOCK_LENGTH),
    _p("flow_window", "integer", DEFAULT_FLOW_WINDOW,
       "sim: band samples the drive may send beyond the slowest of the plant and the required "
       "consumers (flow_progress); at most (BLOCK_QOS depth - 2) x block_length",
       unit="samples", low=1, high=MAX_FLOW_WINDOW),
    _p("required_consumers", "string_array", (),
       "sim: nodes (fully qualified, or relative to the drive's namespace) whose flow_progress "
       "paces the drive besides the plant's; it starts once each has reported (e.g. "
       "['lubrig_recorder'], set by `lubrig rig` when recording)"),
    _p("plant_node", "string", "plant",
       "sim: the plant's node name (relative to the drive's namespace, or absolute) whose "
       "flow_progress sets the segment and paces the drive"),
    _p("start_delay", "double", 0.5, "wall time to wait once the plant is seen (discovery)", unit="s",
       low=0.0, high=60.0),
    _p("lookahead", "integer", DEFAULT_LOOKAHEAD,
       "realtime: band samples sent ahead of the plant's flow_progress, each with its sample index",
       unit="samples", low=1, high=MAX_BLOCK_LENGTH),
    _p("band_velocity_limit", "double", BAND_VELOCITY_LIMIT,
       "the plant's band_velocity_limit: a profile whose |v_band| exceeds it over the run (the plant "
       "would reject those samples and the run stall) is refused, at start and at run time",
       unit="m/s", low=0.0, low_open=True),
    WAIT_FOR_SUBSCRIBER,
    _p("profile.kind", "string", None, "band profile kind (constant | cycle | sine | table); run time",
       read_only=False, from_config="band.kind"),
    _p("profile.<field>", "double", None,
       "the fields of the profile kinds (core.profiles: velocity; low_velocity, high_velocity, "
       "plateau_time, ramp_time; mean_velocity, amplitude, frequency, phase) and profile.path "
       "(string, table CSV); run time, validated by the core profile classes",
       read_only=False, from_config="band.<field>"),
)

ANALYSIS_PARAMETERS: tuple[NodeParameter, ...] = (
    *RUN_SELECTION,
    _p("convention", "string", "", "physical | paper | hertz (empty: from the configuration)",
       choices=("", *CONVENTIONS)),
    _p("window", "integer", 2048, "samples in the sliding wavelet window", low=64),
    _p("n_scales", "integer", 32, "wavelet scales", low=2, high=256),
    _p("publish_period", "double", 0.2, "wall time between analysis updates", unit="s", low=0.01,
       high=60.0),
    _p("image_width", "integer", 256, "pixels of wavelet_image", low=8, high=4096),
    _p("max_columns", "integer", 64, "newest power columns per wavelet_power message", low=1),
    _p("per_sample_input", "bool", False,
       "also take <ns>/state (RigState, one message per sample) for a plant that publishes no "
       "state_block; the lubrig plant publishes state_block in every mode (1 kHz of RigState "
       "costs this node about a fifth of a core)"),
)

NODE_PARAMETERS: dict[str, tuple[NodeParameter, ...]] = {
    "belt_drive": BELT_DRIVE_PARAMETERS,
    "plant": PLANT_PARAMETERS,
    "analysis": ANALYSIS_PARAMETERS,
}


def parameter(node: str, name: str) -> NodeParameter:
    """The contract's parameter `name` of `node`; KeyError naming the valid ones."""
    for p in NODE_PARAMETERS[node]:
        if p.name == name:
            return p
    raise KeyError(f"{node} has no parameter {name!r}; valid: {[p.name for p in NODE_PARAMETERS[node]]}")
