"""The analysis node's rules without ROS: state/band pairing, wavelet analysis, flags, outputs.

`AnalysisSession` takes the plant's states (`state_input`: x, ẋ and the band velocity the sample
was integrated with), band messages (`band_input`) and the plant's run configuration
(`run_config_input`); every `tick` it returns an `AnalysisOutput` with what the node publishes.
Odd input never kills it: non-finite values are counted and skipped, an update that cannot be
analysed is counted and reported in the output, nothing non-finite is ever returned for
publication.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import yaml

from ..core.flags import StabilityFlags
from ..core.online import OnlineUpdate, OnlineWaveletAnalyzer
from ..core.params import ParameterError
from ..core.presets import RunConfig, from_mapping
from ..core.stability import linear_stability
from .diagnostics import Status

HARDWARE_ID = "lubrig_analysis"
#: Flag groups of core.flags.StabilityFlags, one diagnostic status each.
FLAG_GROUPS: dict[str, tuple[str, ...]] = {
    "linear": (
        "band_velocity_m_s",
        "zone",
        "zone_name",
        "linear_stable",
        "effective_damping",
        "critical_damping_ratio",
    ),
    "oscillation": ("oscillation", "growth_rate_per_s", "growth_fit_r2"),
    "stick": ("stick_threshold_m_s", "stick_share", "stick_episodes", "longest_stick_s"),
    "resonance": ("resonance", "resonance_harmonic", "resonance_detail"),
}
#: Colormap anchors (viridis-like), low → high power.
_ANCHORS = np.array([[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]], dtype=float)


def render_power(power: np.ndarray, width: int, decades: float = 4.0) -> np.ndarray:
    """rgb8 image (H = scales, high frequency on top; W = width columns) of log power."""
    power = np.asarray(power, dtype=float)
    columns = np.linspace(0, power.shape[1] - 1, width).round().astype(int)
    p = power[::-1, columns]  # row 0 = smallest scale = highest frequency
    top = float(np.max(p)) if p.size and np.max(p) > 0 else 1.0
    level = np.clip((np.log10(np.maximum(p, top * 10**-decades) / top) + decades) / decades, 0.0, 1.0)
    pos = level * (len(_ANCHORS) - 1)
    i = np.minimum(pos.astype(int), len(_ANCHORS) - 2)
    frac = (pos - i)[..., None]
    rgb = _ANCHORS[i] * (1.0 - frac) + _ANCHORS[i + 1] * frac
    return np.ascontiguousarray(rgb.round().astype(np.uint8))


def flag_statuses(flags: StabilityFlags) -> list[Status]:
    """One status per flag group with its values as text."""
    values = flags.to_dict()
    warn = {
        "linear": values.get("linear_stable") is False,
        "oscillation": values.get("oscillation") == "growing",
        "stick": bool(values.get("stick_share")),
        "resonance": bool(values.get("resonance")),
    }
    message = {
        "linear": f"zone {values.get('zone')}, linearly {'unstable' if warn['linear'] else 'stable'}"
        if values.get("zone") is not None
        else "no band velocity yet",
        "oscillation": f"oscillation {values.get('oscillation')}",
        "stick": f"stick share {values.get('stick_share')}",
        "resonance": str(values.get("resonance_detail") or "n/a"),
    }
    return [
        Status(
            name=f"lubrig/analysis: {group}",
            hardware_id=HARDWARE_ID,
            level="warn" if warn[group] else "ok",
            message=message[group],
            values=tuple((k, str(values.get(k))) for k in keys),
        )
        for group, keys in FLAG_GROUPS.items()
    ]


@dataclass(frozen=True)
class AnalysisSettings:
    """Read-only node settings (contract defaults and ranges: app/contract.ANALYSIS_PARAMETERS)."""

    window: int = 2048
    n_scales: int = 32
    image_width: int = 256
    max_columns: int = 64


@dataclass
class AnalysisOutput:
    """What one update publishes; None (or empty) = nothing on that topic this time."""

    linear_zone: int | None = None
    critical_damping_ratio: float | None = None
    power: np.ndarray | None = None  # (frequency, time), newest ≤ max_columns columns
    dominant_frequency: float | None = None
    image: np.ndarray | None = None  # rgb8 (height, width, 3)
    oscillation_growing: bool | None = None
    statuses: list[Status] = field(default_factory=list)
    skipped: str | None = None  # why the wavelet update was skipped (odd input), else None


class AnalysisSession:
    """Online analysis state (see the module docstring)."""

    def __init__(self, config: RunConfig, settings: AnalysisSettings | None = None) -> None:
        self.settings = settings or AnalysisSettings()
        self.x: list[float] = []
        self.vrel: list[float] = []
        self.band: float | None = None
        self.bad_messages = 0
        self.bad_updates = 0  # analysis updates skipped on input that cannot be analysed
        self.configure(config)

    def configure(self, config: RunConfig) -> None:
        """Analyse runs of `config` from now on (a new analyzer; buffered samples are kept)."""
        s = self.settings
        self.config = config
        self.gamma = config.rig.velocity_factor
        self.analyzer = OnlineWaveletAnalyzer(
            1.0 / config.sample_rate,
            window=s.window,
            n_scales=s.n_scales,
            fundamental_hz=config.band.fundamental_hz,
            analysis_every=max(1, s.window // 8),
            rig=config.rig,
        )

    def run_config_input(self, text: str) -> str | None:
        """The plant's latched run configuration (YAML): reconfigure and drop buffered samples.

        Returns None when applied, else why the text was ignored (the current rig is kept).
        """
        try:
            config = from_mapping(yaml.safe_load(text))
        except (ParameterError, ValueError, TypeError, AttributeError, yaml.YAMLError) as exc:
            return str(exc)
        self.configure(config)
        self.x.clear()
        self.vrel.clear()
        return None

    def band_input(self, value: float) -> bool:
        """A band velocity message; non-finite values are counted and ignored."""
        if math.isfinite(value):
            self.band = value
            return True
        self.bad_messages += 1
        return False

    def state_input(self, position: Sequence[float], velocity: Sequence[float]) -> bool:
        """A plant state (JointState position/velocity); False when it is skipped as malformed.

        The state carries the band velocity of its own sample (joint "band", velocity[1]); the
        sample is paired with it, not with the latest band message, which in sim mode runs up to
        flow_window samples ahead. v_rel = v_band − γ ẋ with the rig's velocity factor γ.
        """
        if not (len(position) and len(velocity)):
            self.bad_messages += 1
            return False
        x, v = position[0], velocity[0]
        if not (math.isfinite(x) and math.isfinite(v)):
            self.bad_messages += 1
            return False
        band = velocity[1] if len(velocity) > 1 and math.isfinite(velocity[1]) else None
        if band is not None:
            self.band = band
        self.x.append(x)
        self.vrel.append((self.band or 0.0) - self.gamma * v)
        return True

    def tick(self) -> AnalysisOutput:
        """One update: linear zone and ζ_crit at the current band, then the wavelet analysis."""
        out = AnalysisOutput()
        try:
            self._analyse(out)
        except (ParameterError, ValueError, ArithmeticError) as exc:  # never die on odd input
            self.bad_updates += 1
            out.skipped = str(exc)
        return out

    def _analyse(self, out: AnalysisOutput) -> None:
        if self.band:  # a band at rest has no sliding equilibrium, hence no zone or ζ_crit
            verdict = linear_stability(abs(self.band), self.config.rig)
            out.linear_zone = None if verdict.zone is None else int(verdict.zone)  # None: law without a peak
            if math.isfinite(verdict.critical_damping_ratio):
                out.critical_damping_ratio = float(verdict.critical_damping_ratio)
        if not self.x:
            return
        x, vrel = self.x, self.vrel
        self.x, self.vrel = [], []
        update = self.analyzer.push(x, vrel, band_velocity=self.band)
        if update.ready:
            self._outputs(update, out)

    def _outputs(self, update: OnlineUpdate, out: AnalysisOutput) -> None:
        power = update.power[:, -self.settings.max_columns :]
        if power.size and np.isfinite(power).all():
            out.power = power
        if update.components:
            f = update.components[0].frequency_hz
            if math.isfinite(f):
                out.dominant_frequency = float(f)
        if update.window is not None and np.isfinite(update.window.power).all():
            out.image = render_power(update.window.power, self.settings.image_width)
        if update.flags is not None:
            out.oscillation_growing = update.flags.oscillation == "growing"
            out.statuses = flag_statuses(update.flags)
