"""Where a rig's DDS traffic may go: this host only (the default) or the network (when asked for).

A ROS 2 domain without DDS security lets every participant that can reach it publish band input
and call reset/pause (docs/security.md). So `lubrig rig`, the launch file and the test suite keep a
rig on this host unless the user asks for the network (`lubrig rig --network`, or the environment
variable LUBRIG_DISCOVERY=network). On this host means both halves:

- ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST: the participants do not look for peers elsewhere;
- the Fast DDS profile config/fastdds_localhost.xml (FASTDDS_DEFAULT_PROFILES_FILE): the UDP
  transport bound to the loopback interface, so a peer elsewhere that knows the host's address
  cannot reach the rig either (the range alone does not stop that; measured, docs/security.md).

A user's own FASTDDS_DEFAULT_PROFILES_FILE is kept (their transport choice wins, and
`isolation` says so).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from ..core.params import ParameterError
from ..core.presets import config_dir

DISCOVERY_VARIABLE = "LUBRIG_DISCOVERY"
DISCOVERY_CHOICES = ("localhost", "network")
RANGE_VARIABLE = "ROS_AUTOMATIC_DISCOVERY_RANGE"
PROFILE_VARIABLE = "FASTDDS_DEFAULT_PROFILES_FILE"
LOCALHOST_PROFILE = "fastdds_localhost.xml"


def localhost_profile() -> Path:
    """The shipped Fast DDS profile that binds UDP to the loopback interface."""
    return config_dir() / LOCALHOST_PROFILE


@dataclass(frozen=True)
class Discovery:
    """The environment for a rig's processes and one line saying what it allows."""

    env: dict[str, str]
    choice: str
    isolation: str


def discovery_environment(env: Mapping[str, str], network: bool = False) -> Discovery:
    """A copy of `env` for rig processes: on this host only, unless `network` or LUBRIG_DISCOVERY=network.

    ParameterError (a ValueError) names a LUBRIG_DISCOVERY value other than localhost or network.
    """
    out = dict(env)
    choice = "network" if network else out.get(DISCOVERY_VARIABLE, "localhost").strip().lower()
    if choice not in DISCOVERY_CHOICES:
        raise ParameterError(
            f"{DISCOVERY_VARIABLE}={out[DISCOVERY_VARIABLE]!r} is not valid; expected one of "
            f"{list(DISCOVERY_CHOICES)}"
        )
    ours = str(localhost_profile())
    if choice == "network":
        out[RANGE_VARIABLE] = "SUBNET"
        if out.get(PROFILE_VARIABLE) == ours:
            del out[PROFILE_VARIABLE]  # inherited from a localhost launcher: not for the network
        return Discovery(out, choice, "discovery on the network: any host on it can reach the rig")
    out[RANGE_VARIABLE] = "LOCALHOST"
    own = out.get(PROFILE_VARIABLE)
    if own and own != ours:
        text = f"discovery on this host; transports from your {PROFILE_VARIABLE}={own}"
    else:
        out[PROFILE_VARIABLE] = ours
        text = "discovery and transports on this host only (--network or LUBRIG_DISCOVERY=network to open)"
    return Discovery(out, choice, text)
