"""`lubrig analyze DIR`: wavelet analysis of a `lubrig simulate` output directory.

Reads DIR/timeseries.csv and DIR/summary.json, transforms the displacement minus its mean (from
--start on), writes DIR/wavelet.png and adds a "wavelet" section to DIR/summary.json (other keys
are kept). The policy (scales, memory cap, decimation) is app/analysis/policy.py's, as for sweeps and
reports.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

from lubrig_ros.core.errors import InputError

from ..app import rundir
from ..app.analysis.policy import DEFAULT_POLICY, MAX_POWER_POINTS, WaveletAnalysis, analyze_displacement
from .common import parse_finite

__all__ = ["MAX_POWER_POINTS", "analyze_run", "register"]


#: Ranges of the analysis options: a scale step finer than 1/64 octave or a frequency outside
#: 1e-9 … 1e6 Hz gives more scales than any record can hold (or none), and more than 100
#: listed components is not a list any more.
DJ_RANGE = (1.0 / 64.0, 1.0)
FREQUENCY_RANGE = (1e-9, 1e6)
MAX_COMPONENTS = 100


def _number(
    text: str, option: str, low: float = 0.0, inclusive: bool = True, high: float = math.inf
) -> float:
    sign = ">=" if inclusive else ">"
    what = f"a finite number {sign} {low:g}" + (f" and <= {high:g}" if math.isfinite(high) else "")
    value = parse_finite(option, text, what)
    if not (value >= low if inclusive else value > low) or value > high:
        raise InputError(f"{option} {text!r} is not valid; expected {what}")
    return value


def analyze_run(
    directory: Path,
    start: float = 0.0,
    dj: float = DEFAULT_POLICY.dj,
    fmin: float | None = None,
    fmax: float | None = None,
    n_components: int = DEFAULT_POLICY.n_components,
) -> dict[str, Any]:
    """Analyse DIR, write wavelet.png and the summary section; return that section."""
    from ..figures.wavelet import analysis_figure  # matplotlib only when drawing

    directory = Path(directory)
    summary = rundir.read_summary(directory)
    series = rundir.read_timeseries(directory, ("time_s", "displacement_m"))
    policy = replace(
        DEFAULT_POLICY, start_s=start, dj=dj, fmin_hz=fmin, fmax_hz=fmax, n_components=n_components
    )
    analysis: WaveletAnalysis = analyze_displacement(
        series["time_s"],
        series["displacement_m"],
        summary.get("sample_rate_hz"),  # type: ignore[arg-type]  # checked by the analysis
        summary.get("band_fundamental_hz"),
        policy,
    )
    section = dict(analysis.summary_section(), figure="wavelet.png")
    from ..figures import style

    title = style.run_title(
        str(summary.get("name", directory.name)),
        style.summary_coupling(summary),
        "Displacement and its wavelet power",
    )
    fig = analysis_figure(analysis, title, summary.get("natural_frequency_hz"))
    fig.savefig(directory / "wavelet.png", dpi=120)
    rundir.update_summary(directory, "wavelet", section)
    return section


def _run(args: argparse.Namespace) -> int:
    start = _number(args.start, "--start")
    dj = _number(args.dj, "--dj", *DJ_RANGE[:1], high=DJ_RANGE[1])
    fmin = (
        None
        if args.fmin is None
        else _number(args.fmin, "--fmin", FREQUENCY_RANGE[0], high=FREQUENCY_RANGE[1])
    )
    fmax = (
        None
        if args.fmax is None
        else _number(args.fmax, "--fmax", FREQUENCY_RANGE[0], high=FREQUENCY_RANGE[1])
    )
    components = _number(args.components, "--components", 1.0, high=MAX_COMPONENTS)
    if not components.is_integer():
        raise InputError(f"--components {args.components!r} is not an integer; expected 1..{MAX_COMPONENTS}")
    n = int(components)
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
    parser.add_argument("--start", default="0", help="skip this transient, s (default 0: whole record)")
    parser.add_argument(
        "--dj",
        default=str(DEFAULT_POLICY.dj),
        help=f"scale step, octaves (1/12; {DJ_RANGE[0]:g}..{DJ_RANGE[1]:g})",
    )
    freq = f"{FREQUENCY_RANGE[0]:g}..{FREQUENCY_RANGE[1]:g} Hz"
    parser.add_argument("--fmin", default=None, help=f"lowest frequency, Hz (3 / analysed duration; {freq})")
    parser.add_argument("--fmax", default=None, help=f"highest frequency, Hz (rate / 4; {freq})")
    parser.add_argument(
        "--components",
        default=str(DEFAULT_POLICY.n_components),
        help=f"dominant frequencies listed (5; 1..{MAX_COMPONENTS})",
    )
    parser.set_defaults(func=_run)
