"""The one figure style of lubrig_ros: colormaps, colours of each quantity, titles, text checks.

Every figure module takes its colours, colormaps, sizes and title wording from here, so a change
of style is one edit. Colormaps are perceptually uniform (viridis family, never jet/rainbow);
colours of the quantities are the same in every figure (the band velocity is always black and
dashed, drawn above the relative velocity so it is never hidden).
"""

from __future__ import annotations

import re
from typing import Any

from ..core.params import CONVENTIONS, RigParameters

#: Wavelet power and other magnitude maps.
POWER_CMAP = "viridis"
#: Time along a trajectory (μ–v figure).
TIME_CMAP = "cividis"
#: Continuous maps of sweep results.
MAP_CMAP = "viridis"
#: Two-valued maps (agree / differs, stable / unstable): the ends of cividis (colour-blind safe).
BINARY_COLOURS = ("#00224e", "#fee838")
#: The colormaps this package may use (tests check every figure against it).
UNIFORM_CMAPS = frozenset({"viridis", "magma", "cividis", "inferno", "plasma"})

#: One colour per quantity, the same in every figure.
COLOURS = {
    "displacement": "#1f4e79",
    "velocity": "#d95f02",  # mass velocity ẋ
    "band_velocity": "black",  # v_band: black, dashed, on top
    "relative_velocity": "#1b9e77",  # v_rel
    "friction_coefficient": "#7b3294",
    "curve": "black",
    "transient": "0.65",
    "lateness": "#31688e",  # realtime lateness of a sample (the lag of rig time behind wall time)
    "deadline": "0.25",  # one sample period after a sample's due time
    "max_lag": "#b2182b",  # the plant's bound on the lag before it skips samples
    "skipped": "#e08214",  # samples the plant declared skipped (a declared gap)
}
BAND_STYLE: dict[str, Any] = {"color": "black", "ls": "--", "lw": 1.1, "zorder": 5}

#: Zones of the friction law (model doc §3): light fills, labels in words.
ZONE_COLOURS = {1: "#e5f5e0", 2: "#fde0dd", 3: "#deebf7"}
ZONE_LABELS = {
    1: "zone 1\nrising\n(stable)",
    2: "zone 2\nfalling\n(unstable unless damped)",
    3: "zone 3\nrising, viscous\n(stable)",
}

#: Axis labels used in several figures (SI units stated on every axis).
MU_SIGNED = "friction coefficient μ (–)\nsigned: μ < 0 when v_rel < 0"
V_REL = "relative sliding velocity v_rel = v_band − γ ẋ (m/s)"
TIME = "time t (s)"
FREQUENCY = "frequency (Hz)"

#: Resolution of saved run figures (dpi) and the report's figure size (inches).
DPI = 110
WIDE = (9.0, 6.0)
SQUARE = (6.5, 5.5)
TITLE_SIZE = 10
LEGEND_SIZE = 8
MARK_SIZE = 8

_CASE = re.compile(r"^case0*(\d+)$")


def run_name(name: str) -> str:
    """A run's name as a title says it: 'case07' → 'case 7'; other names unchanged."""
    match = _CASE.match(name)
    return f"case {match.group(1)}" if match else name


def coupling_text(coupling: str | RigParameters) -> str:
    """'paper convention (γ = 0.0159)' from a rig, 'paper convention' from a convention name."""
    if isinstance(coupling, RigParameters):
        return coupling.coupling_label
    return f"{coupling} convention" if coupling in CONVENTIONS else str(coupling)


def summary_coupling(summary: dict[str, Any]) -> str:
    """The coupling text of a summary.json ('paper convention (γ = 0.0159)' or 'γ = 0.05')."""
    gamma = summary.get("velocity_coupling")
    text = f"γ = {gamma:.3g}" if isinstance(gamma, (int, float)) else ""
    convention = summary.get("convention")
    if convention in CONVENTIONS:
        return f"{convention} convention" + (f" ({text})" if text else "")
    return text or "velocity coupling not stated"


def run_title(name: str, coupling: str | RigParameters, what: str = "") -> str:
    """'What — case 7, paper convention (γ = 0.0159), v_rel = v_band − γ ẋ'."""
    head = f"{what} — " if what else ""
    return f"{head}{run_name(name)}, {coupling_text(coupling)}, v_rel = v_band − γ ẋ"
