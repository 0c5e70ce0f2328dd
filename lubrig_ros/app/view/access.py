"""What a Foxglove client may do to a rig through `lubrig view`, each an explicit opt-in (no ROS).

Read-only is the default. Three options open a way back from the client to the rig:

- ``services``: the contract's services (``<ns>/plant/reset``, ``<ns>/plant/pause``), forwarded to
  the ROS service and the ROS reply returned;
- ``parameters``: the parameters of the contract's rig nodes (belt_drive, plant, analysis) read
  and set through their ROS parameter services, named ``<node FQN>.<parameter>`` as Foxglove's
  ROS bridge names them (``/lubrig/plant.rtol``); a node refuses a bad value itself;
- ``publish``: band input, std_msgs/Float64 on ``<ns>/band_velocity`` only, and only while the
  plant runs rig_in_loop (what it integrates); every other client channel is refused.

Names, types and the checks that need no ROS live here; nodes/view_control.py does the ROS side.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, fields

from lubrig_ros.core.errors import InputError

from ..interface import cdr
from ..interface.contract import SERVICES, Service, Topic, resolve, topic
from ..interface.node_parameters import MODES, NODE_PARAMETERS

#: Between a node's fully qualified name and a parameter name (Foxglove's ROS 2 bridge convention).
PARAMETER_SEPARATOR = "."
#: The topic a client may publish on (relative name in the contract).
BAND_INPUT = "band_velocity"
#: Message encodings a client may publish band input in: ROS 2 CDR, or JSON ``{"data": V}``.
BAND_ENCODINGS = ("cdr", "json")
#: The plant mode whose band input is a client's to give: the plant takes ``band_velocity`` in
#: every mode, and beside a belt_drive (sim, realtime) a client's values would compete with the
#: drive's samples; lockstep wants one answer per state, which no panel gives.
BAND_INPUT_MODE = "rig_in_loop"
#: The node whose mode decides (a contract node).
PLANT = "plant"
assert BAND_INPUT_MODE in MODES and PLANT in NODE_PARAMETERS


@dataclass(frozen=True)
class Access:
    """The ways back from a Foxglove client to the rig that the command line opened."""

    services: bool = False
    parameters: bool = False
    publish: bool = False

    def opened(self) -> list[str]:
        """Names of the opened ways, for the log (in WAYS order)."""
        return [name for name in WAYS if getattr(self, name)]


#: The ways back a command line can open, each `--allow-<way>` of `lubrig view` (and
#: `--view-allow <way>` of `lubrig rig`): Access's fields.
WAYS: tuple[str, ...] = tuple(f.name for f in fields(Access))


def rig_services(namespace: str) -> tuple[Service, ...]:
    """The contract's services resolved in `namespace` (what ``services`` opens)."""
    return tuple(s.resolved(namespace) for s in SERVICES)


def rig_nodes(namespace: str) -> dict[str, str]:
    """Fully qualified name -> node name of the rig nodes whose parameters ``parameters`` opens."""
    return {resolve(namespace, name): name for name in NODE_PARAMETERS}


def resolve_node(namespace: str, name: str) -> str:
    """The fully qualified name of node `name` in `namespace` (as the ROS graph lists them)."""
    return f"{namespace.rstrip('/')}/{name}"


def parameter_name(node_fqn: str, name: str) -> str:
    """The name a client sees for parameter `name` of node `node_fqn`."""
    return f"{node_fqn}{PARAMETER_SEPARATOR}{name}"


def split_parameter_name(full: str, nodes: dict[str, str]) -> tuple[str, str]:
    """(node FQN, parameter) of a client's parameter name; InputError naming what is valid."""
    node, sep, name = full.partition(PARAMETER_SEPARATOR)
    if not sep or not name or node not in nodes:
        raise InputError(
            f"parameter {full!r} is not a rig node's: expected <node>{PARAMETER_SEPARATOR}<parameter> "
            f"with <node> one of {sorted(nodes)}"
        )
    return node, name


def band_input_topic(namespace: str) -> Topic:
    """The contract's band input topic resolved in `namespace` (what ``publish`` opens)."""
    return topic(BAND_INPUT).resolved(namespace)


def band_channel_problem(namespace: str, topic_name: str, encoding: str, schema_name: str) -> str | None:
    """Why a client channel may not publish into the rig, else None."""
    band = band_input_topic(namespace)
    schemas = (band.msgtype, band.msgtype.replace("/msg/", "/"))
    if topic_name != band.name:
        return f"topic {topic_name!r} may not be published; only {band.name} ({band.msgtype})"
    if schema_name not in schemas:
        return f"{band.name} takes {band.msgtype}, not {schema_name!r}"
    if encoding not in BAND_ENCODINGS:
        return f"{band.name}: encoding {encoding!r} is not one of {list(BAND_ENCODINGS)}"
    return None


def band_mode_problem(namespace: str, mode: object) -> str | None:
    """Why band input may not go to a plant of `mode` (None: no plant answered), else None."""
    plant = resolve_node(namespace, PLANT)
    if mode is None:
        return f"no plant {plant} answered: band input goes only to a {BAND_INPUT_MODE} plant"
    if mode != BAND_INPUT_MODE:
        return f"the plant {plant} runs mode {mode!r}: band input is taken only in {BAND_INPUT_MODE}"
    return None


def band_value(encoding: str, data: bytes) -> float:
    """The band velocity (m/s) of a client's message; InputError if malformed or not finite.

    The plant checks the value's range itself (its ``band_velocity_limit``); a NaN or an infinity
    is never republished.
    """
    if encoding == "json":
        try:
            value = json.loads(data)["data"]
        except (ValueError, KeyError, TypeError):
            raise InputError(f'band input {data[:40]!r} is not JSON {{"data": V}}') from None
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise InputError(f"band input {value!r} is not a number; expected m/s as a finite float")
        value = float(value)
    else:
        value = cdr.float64_value(data)
    if not math.isfinite(value):
        raise InputError(f"band input {value!r} is not valid; expected a finite velocity in m/s")
    return value
