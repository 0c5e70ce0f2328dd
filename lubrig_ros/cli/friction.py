"""`lubrig friction`: landmarks of the friction law, μ and dμ/dv at chosen velocities, curve files.

The friction parameters are those of the selected run (--case N | --config FILE | the default
config/rig.yaml), with --contact-area overriding the area.

Values given on the command line are parsed here rather than by argparse so that every bad value
gives one error line naming it (argparse would add a usage block).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from lubrig_ros.core.errors import InputError

from ..core import schema
from ..core.friction import friction_coefficient, friction_minimum, friction_peak, friction_slope
from ..core.params import FrictionParameters
from .common import add_run_source, allow_negative_numbers, parse_finite, source_from_args


def friction_parameters(base: FrictionParameters, choice: str | None) -> FrictionParameters:
    """The selected run's friction parameters, the contact area replaced by --contact-area if given."""
    if choice is None:
        return base
    try:
        params = base.with_contact_area(choice)
        spec = schema.friction_field(type(base).law, "contact_area")
        if spec is not None:
            spec.check(params.contact_area)
        return params
    except ValueError as exc:
        raise InputError(f"--contact-area {choice!r}: {exc}") from None


#: --at values per call at most (each is one line of output).
MAX_POINTS = 10_000


def parse_velocities(texts: list[str]) -> list[float]:
    """The --at sliding velocities: finite (the law is defined for every double), not too many."""
    if len(texts) > MAX_POINTS:
        raise InputError(f"--at has {len(texts)} velocities; at most {MAX_POINTS}")
    what = "a finite sliding velocity in m/s (negative allowed: μ is odd)"
    return [parse_finite("--at", text, what) for text in texts]


def _json_number(value: float) -> float | None:
    """JSON has no infinity: the unbounded slope at v = 0 is written as null."""
    return float(value) if math.isfinite(value) else None


def friction_report(params: FrictionParameters, velocities: list[float]) -> dict[str, Any]:
    """Landmarks and optional point values as a JSON-ready dictionary."""
    peak, minimum = friction_peak(params), friction_minimum(params)
    report: dict[str, Any] = {
        "contact_area_m2": params.contact_area,
        "peak": {"velocity": peak.velocity, "mu": peak.mu},
        "minimum": {"velocity": minimum.velocity, "mu": minimum.mu},
    }
    if velocities:
        mu = friction_coefficient(velocities, params)
        slope = friction_slope(velocities, params)
        report["points"] = [
            {"velocity": v, "mu": float(m), "dmu_dv": _json_number(float(s))}
            for v, m, s in zip(velocities, mu, slope, strict=True)
        ]
    return report


def _print_table(report: dict[str, Any]) -> None:
    print(f"contact area A = {report['contact_area_m2']:.4g} m²")
    print(f"{'':10s} {'velocity (m/s)':>15s} {'mu':>12s} {'dmu/dv (s/m)':>14s}")
    for name in ("peak", "minimum"):
        point = report[name]
        print(f"{name:10s} {point['velocity']:15.4e} {point['mu']:12.5e} {0.0:14.4e}")
    for point in report.get("points", []):
        slope = point["dmu_dv"]
        slope_text = f"{slope:14.4e}" if slope is not None else f"{'inf':>14s}"
        print(f"{'at':10s} {point['velocity']:15.4e} {point['mu']:12.5e} {slope_text}")


def run(args: argparse.Namespace) -> int:
    """Execute `lubrig friction`."""
    velocities = parse_velocities(args.at or [])
    config = source_from_args(args).base()
    params = friction_parameters(config.rig.friction, args.contact_area)
    report = friction_report(params, velocities)
    if args.out is not None:
        from ..figures.curves import plot_friction_curve, save_figure, write_friction_csv

        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        csv_path = write_friction_csv(out / "friction_curve.csv", params)
        png_path = save_figure(plot_friction_curve(params), out / "friction_curve.png")
        report["files"] = [str(csv_path), str(png_path)]
    if args.json:
        print(json.dumps(report, indent=2, allow_nan=False))
    else:
        _print_table(report)
        for path in report.get("files", []):
            print(f"wrote {path}")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `friction` subcommand."""
    parser = subparsers.add_parser(
        "friction",
        help="friction law landmarks, μ and dμ/dv at given velocities, curve CSV and figure",
        description="Peak and minimum of μ(v); μ and dμ/dv at --at velocities; --out writes "
        "friction_curve.csv (1e-15…1e-2 m/s) and friction_curve.png.",
    )
    allow_negative_numbers(parser)  # let "--at -1e-7" through
    add_run_source(parser)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--at", nargs="+", metavar="V", help="sliding velocities in m/s to evaluate μ and dμ/dv at"
    )
    parser.add_argument(
        "--contact-area",
        default=None,
        metavar="corrected|printed|VALUE",
        help="contact area: 'corrected' 2.83e-10 m² (the default run's, reproduces the study's μ), "
        "'printed' 28.3e-12 m² (as printed in the study, μ 10x smaller) or a value in m² "
        "(default: the selected run's)",
    )
    parser.add_argument("--out", metavar="DIR", help="write friction_curve.csv and .png here")
    parser.set_defaults(func=run)
