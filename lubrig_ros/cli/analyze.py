"""`lubrig analyze DIR`: wavelet analysis of a `lubrig simulate` output directory.

Reads DIR/timeseries.csv and DIR/summary.json, transforms the displacement minus its mean (from
--start on), writes DIR/wavelet.png and adds a "wavelet" section to DIR/summary.json (other keys
are kept).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from scipy.signal import decimate

from ..core.wavelet import DEFAULT_DJ, MIN_SAMPLES, cwt, dominant_components, fourier_factor
from .common import parse_finite, write_json
from .main import CommandError

COLUMNS = (
    "time_s",
    "displacement_m",
    "velocity_m_s",
    "friction_coefficient",
    "band_velocity_m_s",
    "relative_velocity_m_s",
)
#: Largest scales × samples computed; longer records are decimated (anti-aliased) to fit.
MAX_POWER_POINTS = 30_000_000


def _number(text: str, option: str, low: float = 0.0, inclusive: bool = True) -> float:
    sign = ">=" if inclusive else ">"
    what = f"a finite number {sign} {low:g}"
    value = parse_finite(option, text, what)
    if not (value >= low if inclusive else value > low):
        raise ValueError(f"{option} {text!r} is not valid; expected {what}")
    return value


def read_run(directory: Path) -> tuple[dict[str, Any], np.ndarray, np.ndarray]:
    """(summary, time in s, displacement in m) of a simulate output directory."""
    if not directory.is_dir():
        raise CommandError(f"{directory}: no such directory (expected `lubrig simulate` output)")
    summary_path, csv_path = directory / "summary.json", directory / "timeseries.csv"
    for path in (summary_path, csv_path):
        if not path.is_file():
            raise CommandError(f"{path}: missing (expected `lubrig simulate` output)")
    try:
        summary = json.loads(summary_path.read_text())
    except json.JSONDecodeError as exc:
        raise CommandError(f"{summary_path}: not valid JSON ({exc})") from None
    if not isinstance(summary, dict):
        raise CommandError(f"{summary_path}: expected a JSON object")
    with csv_path.open() as handle:
        header = [name.strip() for name in handle.readline().split(",")]
    missing = [name for name in ("time_s", "displacement_m") if name not in header]
    if missing:
        raise CommandError(f"{csv_path}: header lacks {missing}; expected columns {list(COLUMNS)}")
    try:
        data = np.loadtxt(
            csv_path,
            delimiter=",",
            skiprows=1,
            usecols=(header.index("time_s"), header.index("displacement_m")),
            ndmin=2,
        )
    except ValueError as exc:
        raise CommandError(f"{csv_path}: unreadable numbers ({exc})") from None
    return summary, data[:, 0], data[:, 1]


def analyze_run(
    directory: Path,
    start: float = 0.0,
    dj: float = DEFAULT_DJ,
    fmin: float | None = None,
    fmax: float | None = None,
    n_components: int = 5,
) -> dict[str, Any]:
    """Analyse DIR, write wavelet.png and the summary section; return that section."""
    summary, time, displacement = read_run(directory)
    rate = summary.get("sample_rate_hz")
    if not isinstance(rate, (int, float)) or not math.isfinite(rate) or rate <= 0:
        raise CommandError(f"summary.json sample_rate_hz={rate!r} is not a rate > 0 Hz")
    dt = 1.0 / float(rate)
    keep = time >= time[0] + start - 0.5 * dt if time.size else np.zeros(0, bool)
    t, x = time[keep], displacement[keep]
    if x.size < MIN_SAMPLES:
        raise CommandError(f"{x.size} samples after --start {start:g} s; at least {MIN_SAMPLES} are needed")
    default_fmin, default_fmax = fmin is None, fmax is None
    fmax = 0.25 / dt if fmax is None else fmax
    fmin = 3.0 / (x.size * dt) if fmin is None else fmin
    if not 0 < fmin < fmax:
        raise CommandError(f"--fmin {fmin:g} Hz must be below --fmax {fmax:g} Hz")
    n_scales = math.floor(math.log2(fmax / fmin) / dj) + 1
    # decimation by q keeps fmax ≤ 0.8 × the decimated Nyquist frequency 0.5 / (q dt)
    factor = max(1, math.ceil(x.size * n_scales / MAX_POWER_POINTS))
    if default_fmax:  # the cap chooses the decimation, fmax follows it down
        fmax = min(fmax, 0.4 / (dt * factor))
        note = f"scales × samples ≤ {MAX_POWER_POINTS} without decimation"
        if factor > 1:
            note = (
                f"decimated by {factor} to keep scales × samples ≤ {MAX_POWER_POINTS}; "
                f"fmax lowered to {fmax:g} Hz (0.8 × the decimated Nyquist frequency)"
            )
    else:  # an explicit --fmax is honoured: decimate as far as it allows, then shorten
        allowed = max(1, int(0.4 / (dt * fmax)))
        factor = min(factor, allowed)
        note = f"decimated by {factor} (--fmax {fmax:g} Hz allows at most {allowed})"
        limit = (MAX_POWER_POINTS // n_scales) * factor
        if x.size > limit:
            left_out = float(t[x.size - limit] - t[0])
            t, x = t[-limit:], x[-limit:]
            if default_fmin:
                fmin = 3.0 / (x.size * dt)
            note += (
                f"; only the last {x.size * dt:g} s analysed (the first {left_out:g} s after --start "
                f"left out) to keep scales × samples ≤ {MAX_POWER_POINTS}"
            )
        else:
            note += f"; scales × samples ≤ {MAX_POWER_POINTS}"
    if not 0 < fmin < fmax:
        raise CommandError(f"--fmin {fmin:g} Hz must be below fmax {fmax:g} Hz ({note})")
    n_scales = math.floor(math.log2(fmax / fmin) / dj) + 1
    x = x - x.mean()
    if factor > 1:
        x, t = decimate(x, factor, ftype="fir", zero_phase=True), t[::factor]
    s0 = 1.0 / (fmax * fourier_factor())
    result = cwt(x, dt * factor, dj=dj, s0=s0, n_scales=n_scales, t0=float(t[0]))
    fundamental = summary.get("band_fundamental_hz")
    components = dominant_components(result, fundamental, n_components)
    f_peak, p_peak = result.global_peak()
    section = {
        "signal": "displacement_m minus its mean",
        "start_s": start,
        "analysed_from_s": float(t[0] - time[0]),
        "dj": dj,
        "fmin_hz": float(result.frequencies.min()),
        "fmax_hz": float(result.frequencies.max()),
        "decimation": factor,
        "decimation_note": note,
        "lag1": result.lag1,
        "power": "|W|^2 / variance (Torrence & Compo), time mean outside the cone of influence",
        "dominant_frequencies": [
            {
                "frequency_hz": c.frequency_hz,
                "power": c.power,
                "label": c.label,
                "amplitude_m": c.amplitude,
                "significant": c.significant,
            }
            for c in components
        ],
        "global_peak": {"frequency_hz": f_peak, "power": p_peak},
        "figure": "wavelet.png",
    }
    from ..figures.wavelet import wavelet_figure  # matplotlib only when drawing

    marks = {"f0": summary.get("natural_frequency_hz"), "band": fundamental}
    title = f"{directory.name}: displacement and its wavelet power"
    fig = wavelet_figure(result, x, title=title, marks_hz=marks)
    fig.savefig(directory / "wavelet.png", dpi=120)
    summary["wavelet"] = section
    write_json(directory / "summary.json", summary)
    return section


def _run(args: argparse.Namespace) -> int:
    start = _number(args.start, "--start")
    dj = _number(args.dj, "--dj", inclusive=False)
    fmin = None if args.fmin is None else _number(args.fmin, "--fmin", inclusive=False)
    fmax = None if args.fmax is None else _number(args.fmax, "--fmax", inclusive=False)
    n = int(_number(args.components, "--components", 1.0))
    section = analyze_run(Path(args.dir), start, dj, fmin, fmax, n)
    print(f"wrote {Path(args.dir) / 'wavelet.png'}; dominant frequencies:")
    for item in section["dominant_frequencies"]:
        print(f"  {item['frequency_hz']:9.4g} Hz  power {item['power']:9.4g}  {item['label']}")
    return 0


def register(subparsers: Any) -> None:
    """Add the `analyze` subcommand."""
    parser = subparsers.add_parser(
        "analyze",
        help="wavelet analysis of a `lubrig simulate` output directory",
        description=__doc__,
    )
    parser.add_argument("dir", help="directory written by `lubrig simulate`")
    parser.add_argument("--start", default="0", help="skip this transient, s (default 0)")
    parser.add_argument("--dj", default=str(DEFAULT_DJ), help="scale step, octaves (1/12)")
    parser.add_argument("--fmin", default=None, help="lowest frequency, Hz (3 / duration)")
    parser.add_argument("--fmax", default=None, help="highest frequency, Hz (rate / 4)")
    parser.add_argument("--components", default="5", help="dominant frequencies listed (5)")
    parser.set_defaults(func=_run)
