"""`lubrig stability`: band-velocity intervals of linear instability per damping ratio, and the map.

The rig is that of the selected run (--case N | --config FILE | the default config/rig.yaml);
--convention, --contact-area and --zeta override it. Numbers are validated here (not by argparse)
so that every bad value gives one error line.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path
from typing import Any

from lubrig_ros.core.errors import InputError

from ..core.friction import friction_minimum, friction_peak
from ..core.params import CONVENTIONS, RigParameters, check_rig_ranges
from ..core.schema import BAND_VELOCITY_LIMIT
from ..core.stability import critical_damping_ratio, unstable_intervals
from .common import add_run_source, allow_negative_numbers, parse_coupling, parse_finite, source_from_args
from .friction import friction_parameters

#: --zeta values per call at most (each is one line of output and one root search).
MAX_ZETAS = 1000


def parse_zeta(text: str) -> float:
    """One damping ratio from the command line: finite and >= 0.

    Any such ζ: the linear analysis explores far beyond a rig's range (core/schema.py).
    """
    value = parse_finite("--zeta", text, "a finite damping ratio >= 0")
    if value < 0.0:
        raise InputError(f"--zeta {text!r} is negative; expected a finite damping ratio >= 0")
    return value


def rig_parameters(
    base: RigParameters,
    convention: str | None,
    contact_area: str | None,
    velocity_coupling: str | None = None,
) -> RigParameters:
    """The selected run's rig with the convention (or an explicit γ) and contact area overridden."""
    if convention is not None and convention not in CONVENTIONS:
        raise InputError(f"--convention {convention!r} is not valid; expected one of {'|'.join(CONVENTIONS)}")
    rig = replace(
        base,
        convention=base.convention if convention is None else convention,
        velocity_coupling=base.velocity_coupling if convention is None else None,
        friction=friction_parameters(base.friction, contact_area),
    )
    if velocity_coupling is not None:
        rig = replace(rig, velocity_coupling=parse_coupling(velocity_coupling))
    check_rig_ranges(rig)  # the run's physical ranges (core/schema.py); --zeta may go beyond
    return rig


def stability_report(rig: RigParameters, zetas: list[float]) -> dict[str, Any]:
    """Unstable band-velocity intervals (m/s) for each ζ, with the zone edges, JSON-ready."""
    peak, minimum = friction_peak(rig.friction), friction_minimum(rig.friction)
    return {
        "convention": rig.coupling_name,
        "velocity_coupling": rig.velocity_factor,
        "coupling_strength": rig.coupling_strength,
        "zone_edges": {"peak_velocity": peak.velocity, "minimum_velocity": minimum.velocity},
        "results": [
            {
                "zeta": zeta,
                "unstable_intervals": [[lo, hi] for lo, hi in unstable_intervals(zeta, rig)],
            }
            for zeta in zetas
        ],
    }


def _print_table(report: dict[str, Any]) -> None:
    edges = report["zone_edges"]
    print(
        f"convention: {report['convention']} (γ = {report['velocity_coupling']:.4g}); zone 2 spans "
        f"{edges['peak_velocity']:.4g} … {edges['minimum_velocity']:.4g} m/s"
    )
    for result in report["results"]:
        intervals = result["unstable_intervals"]
        text = ", ".join(f"[{lo:.4g}, {hi:.4g}]" for lo, hi in intervals) or "none (stable)"
        print(f"zeta = {result['zeta']:<10g} unstable band velocities (m/s): {text}")


def run(args: argparse.Namespace) -> int:
    """Execute `lubrig stability`."""
    config = source_from_args(args).base()
    if args.zeta and len(args.zeta) > MAX_ZETAS:
        raise InputError(f"--zeta has {len(args.zeta)} values; at most {MAX_ZETAS}")
    zetas = [parse_zeta(text) for text in args.zeta] if args.zeta else [config.rig.damping_ratio]
    rig = rig_parameters(config.rig, args.convention, args.contact_area, args.velocity_coupling)
    report = stability_report(rig, zetas)
    if args.at is not None:
        limit = BAND_VELOCITY_LIMIT
        v = parse_finite("--at", args.at, f"a band velocity > 0 and <= {limit:g} m/s")
        if not 0.0 < v <= limit:
            raise InputError(
                f"--at {args.at!r} is not valid; expected a band velocity > 0 and <= {limit:g} m/s"
            )
        report["critical_damping_ratio"] = {
            "velocity": v,
            "zeta_crit": float(critical_damping_ratio(v, rig)),
        }
    if args.out is not None:
        from ..figures.curves import plot_stability_map, save_figure

        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        report["files"] = [str(save_figure(plot_stability_map(rig), out / "stability_map.png"))]
    if args.json:
        print(json.dumps(report, indent=2, allow_nan=False))
    else:
        _print_table(report)
        if "critical_damping_ratio" in report:
            crit = report["critical_damping_ratio"]
            print(f"zeta_crit({crit['velocity']:.4g} m/s) = {crit['zeta_crit']:.6g}")
        for path in report.get("files", []):
            print(f"wrote {path}")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `stability` subcommand."""
    parser = subparsers.add_parser(
        "stability",
        help="linear stability of steady sliding: unstable band velocities per damping ratio",
        description="Routh–Hurwitz on the linearized rig: unstable band-velocity intervals for "
        "each --zeta; --out writes stability_map.png.",
    )
    allow_negative_numbers(parser)  # so "--zeta -0.1" reaches validation
    add_run_source(parser)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--zeta",
        nargs="+",
        default=None,
        metavar="Z",
        help=f"damping ratios >= 0, at most {MAX_ZETAS} (default: the selected run's, 0.01 for the "
        "default rig)",
    )
    parser.add_argument(
        "--convention",
        default=None,
        metavar="physical|paper|hertz",
        help="relative velocity v_band − γ ẋ with γ = 1 (physical, the default run's), 1/ω0 (paper, "
        "the cases') or 1/f0 (hertz); default: the selected run's",
    )
    parser.add_argument(
        "--velocity-coupling",
        metavar="G",
        help="γ in v_rel = v_band − γ ẋ: a convention name or a number > 0 (overrides --convention)",
    )
    parser.add_argument(
        "--contact-area",
        default=None,
        metavar="corrected|printed|VALUE",
        help="contact area: corrected 2.83e-10 m², printed 28.3e-12 m², or m² (default: the "
        "selected run's, corrected for the default rig)",
    )
    parser.add_argument("--at", metavar="V", help="also report ζ_crit at this band velocity (m/s)")
    parser.add_argument("--out", metavar="DIR", help="write stability_map.png here")
    parser.set_defaults(func=run)
