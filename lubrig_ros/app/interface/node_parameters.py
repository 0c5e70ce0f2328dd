"""The nodes' ROS parameters as data: name, type, default, unit, range, meaning (no ROS import).

Part of the rig's interface contract (app/interface/contract.py re-exports every name here). The parameters
that set a run configuration's fields take their unit and physical range from core/schema.py, so
the descriptors (`ros2 param describe`), the docs (docs/nodes.md, generated) and the run
configuration's own checks agree; the others carry their ranges here.
"""

from __future__ import annotations

from dataclasses import fields
from functools import cache

from ...core import schema
from ...core.friction_laws import DEFAULT_LAW, law_parameters
from ...core.params import CONVENTION_CHOICES, CONVENTIONS
from ...core.presets import CASE_NUMBERS
from ..processes.discovery import GRAPH_SETTLE_S
from .parameter_types import NodeParameter as NodeParameter
from .parameter_types import ParameterType as ParameterType
from .parameter_types import field_parameter as _field
from .parameter_types import param as _p
from .profile_parameters import PROFILE_PARAMETERS as PROFILE_PARAMETERS
from .profile_parameters import profile_parameter as profile_parameter

MODES: tuple[str, ...] = ("sim", "lockstep", "realtime", "rig_in_loop")
#: What a wall-clock plant does once it is more than max_lag behind real time (app/plant/session.py).
LAG_POLICIES: tuple[str, ...] = ("skip", "stop")
DEFAULT_LAG_POLICY = "skip"
#: s: lateness a wall-clock plant catches up on before it has not held real time.
DEFAULT_MAX_LAG = 0.02
#: Samples per state_block in the wall-clock modes (1 kHz: 50 blocks per second).
DEFAULT_OUTPUT_BLOCK_LENGTH = 20
#: Band samples belt_drive sends ahead of the realtime plant (its flow_progress).
DEFAULT_LOOKAHEAD = 200
_RIG = schema.RIG_FIELDS
_SIM = schema.SIMULATION_FIELDS

#: Run selection, shared by the three rig nodes (the launcher passes config_file).
RUN_SELECTION: tuple[NodeParameter, ...] = (
    _p(
        "case",
        "integer",
        0,
        "study case 1..10 (0: use config_file or the default)",
        low=0,
        high=CASE_NUMBERS.stop - 1,
    ),
    _p(
        "config_file",
        "string",
        "",
        "run configuration YAML (the launcher passes the resolved run's file; empty: default)",
    ),
    _p(
        "topic_namespace",
        "string",
        "",
        "deprecated, must stay empty: topics and services follow the node namespace "
        "(--ros-args -r __ns:=/rig2, launch namespace=); a value other than the node's namespace "
        "is refused at start",
    ),
)
WAIT_FOR_SUBSCRIBER = _p(
    "wait_for_subscriber",
    "string",
    "",
    "hold the run until a node whose name starts with this (e.g. the recorder, 'lubrig_recorder') "
    "subscribes to every output topic, matched (plant: sim, lockstep; belt_drive: the band blocks "
    "in every mode), or to the block outputs (plant: realtime, rig_in_loop: the loop starts then); "
    "empty = do not wait",
)
DEFAULT_REALTIME_PRIORITY = 50
REALTIME_PRIORITY = _p(
    "realtime_priority",
    "integer",
    DEFAULT_REALTIME_PRIORITY,
    "realtime, rig_in_loop: SCHED_FIFO priority 1..99 of the plant's loop thread, and one below "
    "it for the node's executor thread, whose callbacks hold the GIL the loop needs (where the "
    "process may; otherwise a warning and normal scheduling), and a CPU wake-up latency "
    "request of 0 (/dev/cpu_dma_latency, where writable); 0 keeps normal scheduling",
    low=0,
    high=99,
)
#: Band samples per BandVelocityBlock (sim); measured: docs/nodes.md "Block length".
DEFAULT_BLOCK_LENGTH = 1000
MAX_BLOCK_LENGTH = 10_000
#: Band samples belt_drive may send beyond the slowest participant (sim): four blocks in flight,
#: so the plant integrates the next block while a consumer's flow_progress is on its way.
DEFAULT_FLOW_WINDOW = 4 * DEFAULT_BLOCK_LENGTH
#: Samples a lossless replay sends beyond its slowest subscriber by default: within the block
#: topics' QoS history for bags of blocks down to 11 samples (realtime bags hold blocks of
#: DEFAULT_OUTPUT_BLOCK_LENGTH), one block at a time for a sim bag's.
DEFAULT_REPLAY_FLOW_WINDOW = 1000
MAX_FLOW_WINDOW = 1_000_000
#: Node name of the recorder's flow-progress participant, in the rig's namespace (`lubrig rig`
#: adds it to belt_drive's required_consumers when it records).
RECORDER_PARTICIPANT = "lubrig_recorder"


#: Largest |band velocity| the plant accepts from the band topic by default, m/s (the schema's).
BAND_VELOCITY_LIMIT = schema.BAND_VELOCITY_LIMIT
#: The rig fields the plant exposes as rig.<name> (core/schema.py RIG_FIELDS with `node`;
#: normal_force, the friction law's, and velocity_coupling, beside convention, are declared below).
RIG_FIELDS: tuple[str, ...] = tuple(schema.rig_fields(on_rig=True, node=True))
#: Longest a parameter period or timeout may be, s (a value beyond is a typo: minutes).
MAX_PERIOD_S = 60.0


def friction_fields(law: str = DEFAULT_LAW) -> tuple[str, ...]:
    """The fields of friction law `law`'s parameter dataclass (core.friction_laws registry), in order.

    ParameterError naming the valid laws for an unknown one.
    """
    return tuple(f.name for f in fields(law_parameters(law)))


#: The default (junction-kinetics) law's fields.
FRICTION_FIELDS: tuple[str, ...] = friction_fields(DEFAULT_LAW)

FRICTION_LAW = _p(
    "friction.law",
    "string",
    None,
    "friction law of the run (core.friction_laws: junction_kinetics, stribeck or a registered "
    "one); the plant's friction.<field> parameters are this law's fields",
    from_config="rig.friction.law",
)


def _friction_parameter(law: str, name: str) -> NodeParameter:
    spec = schema.friction_field(law, name)
    text = f"friction law {name}; applied at the next reset"
    if spec is None:  # a registered law without `ranges`: checked by its dataclass
        return _p(
            f"friction.{name}",
            "double",
            None,
            text,
            unit="SI",
            read_only=False,
            from_config=f"rig.friction.{name}",
        )
    text = f"{spec.symbol}, {spec.description}; applied at the next reset"
    return _field(f"friction.{name}", spec, text, read_only=False, from_config=f"rig.friction.{name}")


def friction_parameters(law: str = DEFAULT_LAW) -> tuple[NodeParameter, ...]:
    """The plant's `friction.<field>` parameters of law `law` (normal_force is rig.normal_force)."""
    return tuple(_friction_parameter(law, n) for n in friction_fields(law) if n != "normal_force")


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
        _field("sample_rate", _SIM["sample_rate"], "output rate", from_config="simulation.sample_rate"),
        _field(
            "duration",
            _SIM["duration"],
            "run length in rig time (sim mode; wall-clock modes: with exit_when_complete)",
            from_config="simulation.duration",
        ),
        _field(
            "rtol",
            _SIM["rtol"],
            "integrator relative tolerance; applied at the next reset",
            read_only=False,
            from_config="simulation.rtol",
        ),
        _field(
            "initial_perturbation",
            _SIM["initial_perturbation"],
            "x(0) = (1 + this) x0; applied at the next reset",
            read_only=False,
            from_config="simulation.initial_perturbation",
        ),
        _p(
            "convention",
            "string",
            None,
            f"{CONVENTION_CHOICES}; empty: the run configuration's; applied at the next reset",
            choices=("", *CONVENTIONS),
            read_only=False,
            from_config="rig.convention",
        ),
        _p(
            "velocity_coupling",
            "double",
            None,
            "explicit γ in v_rel = v_band − γ ẋ, overriding the convention; 0: the convention's γ; "
            "applied at the next reset",
            unit=_RIG["velocity_coupling"].unit,
            low=0.0,
            high=_RIG["velocity_coupling"].high,
            read_only=False,
            from_config="rig.velocity_coupling",
            zero_means=_RIG["velocity_coupling"].unset,
            nonzero_low=_RIG["velocity_coupling"].low,
        ),
        *(
            _field(
                f"rig.{n}",
                _RIG[n],
                f"rig {n} {_RIG[n].symbol}, {_RIG[n].description}; applied at the next reset",
                read_only=False,
                from_config=f"rig.{n}",
            )
            for n in RIG_FIELDS
        ),
        _field(
            "rig.normal_force",
            _RIG["normal_force"],
            "normal force N; applied at the next reset",
            read_only=False,
            from_config="rig.friction.normal_force",
        ),
        FRICTION_LAW,
        *friction_parameters(law),
        _p(
            "band_velocity_limit",
            "double",
            BAND_VELOCITY_LIMIT,
            "largest accepted |v_band|; NaN/inf and larger values are rejected",
            unit="m/s",
            low=0.0,
            low_open=True,
            high=BAND_VELOCITY_LIMIT,
        ),
        _p(
            "stale_timeout",
            "double",
            0.05,
            "time without good band input before the input is stale",
            unit="s",
            low=0.0,
            low_open=True,
            high=MAX_PERIOD_S,
        ),
        _p(
            "tick_step_attempts",
            "integer",
            DEFAULT_TICK_STEP_ATTEMPTS,
            "realtime: integrator step attempts per call of the tick; a sample that needs more is "
            "an overrun, finished by further calls (the loop stays responsive, stop/pause/reset "
            "and diagnostics run between them) instead of blocking it",
            unit="attempts",
            low=1,
            high=1_000_000,
        ),
        _p(
            "lag_policy",
            "string",
            DEFAULT_LAG_POLICY,
            "realtime, rig_in_loop: once more than max_lag behind real time, skip (keep real time: "
            "integrate the overdue samples with the band values known for them, publish none of "
            "them, declare the gap in the next state_block) or stop (no more output); ERROR either "
            "way, and the node exits with status 3 (app/plant/session.py)",
            choices=LAG_POLICIES,
        ),
        _p(
            "max_lag",
            "double",
            DEFAULT_MAX_LAG,
            "realtime, rig_in_loop: lateness of a sample the plant catches up on; beyond it the rig "
            "has not held real time (lag_policy)",
            unit="s",
            low=0.0,
            low_open=True,
            high=10.0,
        ),
        _p(
            "output_block_length",
            "integer",
            DEFAULT_OUTPUT_BLOCK_LENGTH,
            "realtime, rig_in_loop: samples per state_block (the recorder, analysis and live view "
            "take these; state stays one message per sample)",
            unit="samples",
            low=1,
            high=10_000,
        ),
        _p(
            "state_per_sample",
            "bool",
            True,
            "realtime, rig_in_loop, lockstep: also publish one state (RigState) per sample, for rig "
            "software in the loop; wall-clock modes: only while the topic has a subscriber (each "
            "costs the plant's loop CPU time: docs/benchmarks.md)",
        ),
        WAIT_FOR_SUBSCRIBER,
        _p(
            "state_subscribers",
            "string_array",
            (),
            "sim, lockstep: nodes (names starting with each) that must have subscribed to "
            "state_block before the run starts, besides wait_for_subscriber (the launchers: the "
            "analysis, so that it has the run's first samples); empty = none",
        ),
        _p(
            "band_source",
            "string",
            "",
            "the declared band source: node name (in the plant's namespace) or fully qualified name "
            "of the one publisher of band input (the launchers: belt_drive); any other publisher "
            "is reported (band sources WARN, naming it); set, the run starts (sim: the plant "
            "announces itself; wall clock: its loop starts) once a band reader has matched it; "
            "empty: any one publisher",
        ),
        _p(
            "namespace_settle",
            "double",
            GRAPH_SETTLE_S,
            "discovery time the start-up check watches the graph for another rig in the "
            "namespace before the run may start; 0: no check (`lubrig rig` gives 0: it has "
            "watched the graph itself and holds the namespace until the rig's nodes stop)",
            unit="s",
            low=0.0,
            high=MAX_PERIOD_S,
        ),
        REALTIME_PRIORITY,
        _p(
            "diagnostics_period",
            "double",
            1.0,
            "time between /diagnostics",
            unit="s",
            low=0.0,
            low_open=True,
            high=MAX_PERIOD_S,
        ),
        _p(
            "publish_clock",
            "bool",
            False,
            "sim: publish rig time on the global /clock (one per block + 5 Hz heartbeat); one "
            "owner per ROS domain: the launcher turns it on for a single rig only",
        ),
        _p(
            "exit_when_complete",
            "bool",
            False,
            "end the node once its run is over, exit status 0 (3 if a wall-clock run did not hold "
            "real time): sim, lockstep once run_complete is true; realtime, rig_in_loop once the "
            "sample at `duration` (counted from the first sample) is published; launch/rig.launch.py "
            "sets it, `lubrig rig` stops the nodes itself",
        ),
        _p(
            "scalar_topics",
            "bool",
            False,
            "also publish displacement, velocity and friction_coefficient as std_msgs/Float64, one "
            "message per sample (about 3 x 37 us per sample for the plant, and the same per "
            "subscriber: sim mode falls from block to sample speed)",
        ),
        _p(
            "shadow",
            "bool",
            False,
            "rig_in_loop: also take the real rig's measured displacement (measured_displacement) "
            "and publish shadow_block, its residual against the model per sample and their running "
            "RMS (pairing: docs/fitting.md); ignored, with a warning, in the other modes",
        ),
    )


#: The plant's parameters with the default (junction-kinetics) law (plant_parameters(law) for another).
PLANT_PARAMETERS: tuple[NodeParameter, ...] = plant_parameters(DEFAULT_LAW)


BELT_DRIVE_PARAMETERS: tuple[NodeParameter, ...] = (
    *RUN_SELECTION,
    _p("mode", "string", "sim", "sim | realtime", choices=("sim", "realtime")),
    _field("sample_rate", _SIM["sample_rate"], "output rate", from_config="simulation.sample_rate"),
    _field("duration", _SIM["duration"], "run length (sim mode)", from_config="simulation.duration"),
    _p(
        "block_length",
        "integer",
        DEFAULT_BLOCK_LENGTH,
        "sim: band samples per band_velocity_block message (the plant answers with one state_block "
        "per block); results do not depend on it",
        unit="samples",
        low=1,
        high=MAX_BLOCK_LENGTH,
    ),
    _p(
        "flow_window",
        "integer",
        DEFAULT_FLOW_WINDOW,
        "sim: band samples the drive may send beyond the slowest of the plant and the required "
        "consumers (flow_progress); at most (BLOCK_QOS depth - 2) x block_length",
        unit="samples",
        low=1,
        high=MAX_FLOW_WINDOW,
    ),
    _p(
        "required_consumers",
        "string_array",
        (),
        "sim: nodes (fully qualified, or relative to the drive's namespace) whose flow_progress "
        "paces the drive besides the plant's; it starts once each has reported (e.g. "
        "['lubrig_recorder'], set by `lubrig rig` when recording)",
    ),
    _p(
        "plant_node",
        "string",
        "plant",
        "sim: the plant's node name (relative to the drive's namespace, or absolute) whose "
        "flow_progress sets the segment and paces the drive",
    ),
    _p(
        "start_delay",
        "double",
        0.5,
        "sim: wall time to wait once the plant's subscription to the band blocks is discovered, "
        "for the discovery of the other subscribers",
        unit="s",
        low=0.0,
        high=60.0,
    ),
    _p(
        "lookahead",
        "integer",
        DEFAULT_LOOKAHEAD,
        "realtime: band samples sent ahead of the plant's flow_progress, each with its sample index",
        unit="samples",
        low=1,
        high=MAX_BLOCK_LENGTH,
    ),
    _p(
        "band_velocity_limit",
        "double",
        BAND_VELOCITY_LIMIT,
        "the plant's band_velocity_limit: a profile whose |v_band| exceeds it over the run (the plant "
        "would reject those samples and the run stall) is refused, at start and at run time",
        unit="m/s",
        low=0.0,
        low_open=True,
        high=BAND_VELOCITY_LIMIT,
    ),
    WAIT_FOR_SUBSCRIBER,
    *PROFILE_PARAMETERS,
)

ANALYSIS_PARAMETERS: tuple[NodeParameter, ...] = (
    *RUN_SELECTION,
    _p(
        "convention",
        "string",
        "",
        f"{CONVENTION_CHOICES}; empty: the run configuration's",
        choices=("", *CONVENTIONS),
    ),
    _p("window", "integer", 2048, "samples in the sliding wavelet window", low=64, high=65_536),
    _p("n_scales", "integer", 32, "wavelet scales", low=2, high=256),
    _p("publish_period", "double", 0.2, "wall time between analysis updates", unit="s", low=0.01, high=60.0),
    _p("image_width", "integer", 256, "pixels of wavelet_image", low=8, high=4096),
    _p("max_columns", "integer", 64, "newest power columns per wavelet_power message", low=1, high=4096),
    _p(
        "per_sample_input",
        "bool",
        False,
        "also take <ns>/state (RigState, one message per sample) for a plant that publishes no "
        "state_block; the lubrig plant publishes state_block in every mode (1 kHz of RigState "
        "costs this node about a fifth of a core)",
    ),
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
