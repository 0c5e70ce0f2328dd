"""The analysis node's rules without ROS: state/band pairing, wavelet analysis, flags, outputs.

`AnalysisSession` takes the plant's samples (`samples_input`: arrays of x, ẋ, the band velocity
each sample was integrated with and v_rel, from a RigStateBlock or one RigState, with the rig time
of the last one) and the plant's run configuration (`run_config_input`); every `tick` it returns
an `AnalysisOutput` with what the node publishes (also the wavelet power's frequency and time
axes and the full stability flags for the typed outputs wavelet_frame and stability).
Odd input never kills it: non-finite values are counted and skipped, an update that cannot be
analysed is counted and reported in the output, nothing non-finite is ever returned for
publication.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import yaml

from ...core.flags import StabilityFlags, evaluate_flags
from ...core.online import OnlineUpdate, OnlineWaveletAnalyzer
from ...core.params import ParameterError
from ...core.presets import RunConfig, from_mapping
from ...core.stability import linear_stability
from ..interface.diagnostics import Status

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
            name=group,  # the node prefixes its fully qualified name
            hardware_id=HARDWARE_ID,
            level="warn" if warn[group] else "ok",
            message=message[group],
            values=tuple((k, str(values.get(k))) for k in keys),
        )
        for group, keys in FLAG_GROUPS.items()
    ]


@dataclass(frozen=True)
class AnalysisSettings:
    """Read-only node settings (contract defaults and ranges: app/interface/contract.ANALYSIS_PARAMETERS)."""

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
    frequencies: np.ndarray | None = None  # (rows,) Hz of the rows of `power`
    power_start: float | None = None  # s, rig time of the first column of `power`
    power_end: float | None = None  # s, rig time of the last column
    flags: StabilityFlags | None = None  # every flag: the linear group at the current band,
    # the signal groups from the latest full-window analysis
    newest_time: float | None = None  # s, rig time of the newest sample analysed


class AnalysisSession:
    """Online analysis state (see the module docstring)."""

    def __init__(self, config: RunConfig, settings: AnalysisSettings | None = None) -> None:
        self.settings = settings or AnalysisSettings()
        self.x: list[float] = []
        self.vrel: list[float] = []
        self.band: float | None = None
        self.newest_time: float | None = None  # rig time of the newest sample taken
        self.window_flags: StabilityFlags | None = None
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
        self.warm_up(config)

    @staticmethod
    def warm_up(config: RunConfig) -> None:
        """Load here what the first update needs: the friction law's compiled module and scipy.optimize.

        Otherwise they are imported inside the node's first update (a timer callback), where a
        SIGINT interrupting the import killed the node with exit 1 (numpy turns the
        KeyboardInterrupt raised inside its import into an ImportError).
        """
        band = abs(float(config.band(0.0)))
        with contextlib.suppress(ParameterError, ValueError, ArithmeticError):
            evaluate_flags(config.rig, band_velocity=band)
            if band:
                linear_stability(band, config.rig)

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
        self.window_flags = None
        return None

    def samples_input(
        self,
        displacement: Sequence[float] | np.ndarray,
        velocity: Sequence[float] | np.ndarray,
        band_velocity: Sequence[float] | np.ndarray,
        relative_velocity: Sequence[float] | np.ndarray,
        newest_time: float | None = None,
    ) -> int:
        """Consecutive plant samples (a RigStateBlock's arrays, or one RigState); how many were taken.

        Arrays of unequal length are a malformed message (counted, nothing taken); samples with a
        non-finite x, ẋ or v_rel are counted and skipped. `newest_time`: rig time of the last
        sample (s), the time axis of the wavelet output.
        """
        try:
            x, v, band, vrel = (
                np.asarray(a, dtype=float).reshape(-1)
                for a in (displacement, velocity, band_velocity, relative_velocity)
            )
        except (TypeError, ValueError):
            self.bad_messages += 1
            return 0
        if not (x.size == v.size == band.size == vrel.size) or x.size == 0:
            self.bad_messages += 1
            return 0
        good = np.isfinite(x) & np.isfinite(v) & np.isfinite(vrel)
        if not good.all():
            self.bad_messages += int((~good).sum())
            x, band, vrel = x[good], band[good], vrel[good]
        finite_band = band[np.isfinite(band)]
        if finite_band.size:
            self.band = float(finite_band[-1])
        self.x.extend(x.tolist())
        self.vrel.extend(vrel.tolist())
        if newest_time is not None and math.isfinite(newest_time):
            self.newest_time = float(newest_time)
        return int(x.size)

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
        out.newest_time = self.newest_time
        if self.band:  # a band at rest has no sliding equilibrium, hence no zone or ζ_crit
            verdict = linear_stability(abs(self.band), self.config.rig)
            out.linear_zone = None if verdict.zone is None else int(verdict.zone)  # None: law without a peak
            if math.isfinite(verdict.critical_damping_ratio):
                out.critical_damping_ratio = float(verdict.critical_damping_ratio)
        if self.x:
            x, vrel = self.x, self.vrel
            self.x, self.vrel = [], []
            update = self.analyzer.push(x, vrel, band_velocity=self.band)
            if update.ready:
                self._outputs(update, out)
        out.flags = self._flags()

    def _flags(self) -> StabilityFlags:
        """The linear group at the current band velocity with the latest window's signal groups."""
        linear = evaluate_flags(self.config.rig, band_velocity=self.band)
        base = self.window_flags or StabilityFlags()
        return replace(base, **{name: getattr(linear, name) for name in FLAG_GROUPS["linear"]})

    def _outputs(self, update: OnlineUpdate, out: AnalysisOutput) -> None:
        power = update.power[:, -self.settings.max_columns :]
        if power.size and np.isfinite(power).all() and np.isfinite(update.frequencies).all():
            out.power = power
            out.frequencies = np.asarray(update.frequencies, dtype=float)
            if self.newest_time is not None:  # the columns are the newest samples, dt apart
                out.power_end = self.newest_time
                out.power_start = self.newest_time - (power.shape[1] - 1) * self.analyzer.dt
        if update.components:
            f = update.components[0].frequency_hz
            if math.isfinite(f):
                out.dominant_frequency = float(f)
        if update.window is not None and np.isfinite(update.window.power).all():
            out.image = render_power(update.window.power, self.settings.image_width)
        if update.flags is not None:
            self.window_flags = update.flags
            out.oscillation_growing = update.flags.oscillation == "growing"
            out.statuses = flag_statuses(update.flags)
