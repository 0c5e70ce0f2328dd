"""`lubrig fit DATA --free NAME ... --out DIR`: identify rig and friction parameters from a record.

DATA is a CSV (header time, band_velocity, displacement[, friction_coefficient]; SI units: s,
m/s, m, 1; timeseries.csv's unit-suffixed names work too) or a bag recorded by `lubrig rig`.
The fit starts from --case | --config (default config/rig.yaml) and frees the named parameters
within their physical ranges (core/schema.py); method and outputs: docs/fitting.md, lubrig_ros/fit.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from lubrig_ros.core.errors import InputError

from ..app import rundir
from ..core.presets import default_config
from ..core.schema import friction_fields, rig_fields
from ..fit.defaults import MAX_EVALUATIONS, SEGMENT_SECONDS
from .common import (
    MAX_LOCAL_WORKERS,
    add_force,
    add_run_source,
    parse_finite,
    parse_workers,
    source_from_args,
)


def _source_text(args: argparse.Namespace) -> str:
    if args.case is not None:
        return f"case {args.case}"
    return f"config {args.config}" if args.config is not None else "defaults (config/rig.yaml)"


def _free_help() -> str:
    """Every fittable name of the default law and the rig with its unit and range (from the schema)."""
    law = type(default_config().rig.friction).law
    specs = [*rig_fields(fit=True).values(), *friction_fields(law).values()]
    listed = "; ".join(f"{s.name} {s.range_text()}" for s in specs)
    return (
        f"a parameter to estimate (repeat or list several): rig fields and the friction law's fields "
        f"({law}: another law's fields when --config names it), within their physical ranges: {listed}"
    )


def run(args: argparse.Namespace) -> int:
    """Entry of `lubrig fit`."""
    segment = parse_finite("--segment", args.segment, "a segment length in s > 0")
    if segment <= 0.0:
        raise InputError(f"--segment {args.segment!r} must be > 0; expected a segment length in s")
    workers = parse_workers(args.workers)
    evaluations = int(parse_finite("--max-evaluations", args.max_evaluations, "an integer >= 1"))
    if evaluations < 1:
        raise InputError(f"--max-evaluations {args.max_evaluations!r} must be >= 1")
    config = source_from_args(args).resolve()
    from ..fit.data import load_data
    from ..fit.parameters import free_parameters

    names = [name for group in args.free for name in group.replace(",", " ").split()]
    free_parameters(names, config)  # bad names refused before the data is read
    data = load_data(args.data)
    if segment * data.sample_rate < 2:
        raise InputError(f"--segment {args.segment} s holds fewer than 2 samples at {data.sample_rate:g} Hz")
    config = config.with_overrides(sample_rate=round(data.sample_rate, 6), duration=float(data.time[-1]))
    from ..fit.page import FIT_FILES, write_outputs
    from ..fit.solve import bound_warning, fit, unconverged

    out = rundir.prepare_output_dir(Path(args.out), args.force, "--out", FIT_FILES)
    result = fit(data, config, names, segment_seconds=segment, workers=workers, max_evaluations=evaluations)
    write_outputs(out, data, result, _source_text(args))
    for name, value, error, p in zip(
        result.names, result.values, result.errors, result.parameters, strict=True
    ):
        print(f"{name} = {value:.6g} ± {error:.3g}{p.spec.unit_text}")
    print(
        f"{data.time.size} samples, {result.evaluations} evaluations in {result.wall_time:.1f} s "
        f"({result.status}); results in {out}/"
    )
    if not result.success:
        print(f"lubrig fit: warning: {unconverged(result.to_dict())}", file=sys.stderr)
    estimates = result.to_dict()["estimates"]
    for name in result.at_bound:
        print(f"lubrig fit: warning: {bound_warning(name, estimates[name])}", file=sys.stderr)
    for name, ratio in result.misfit().items():
        print(
            f"lubrig fit: warning: the fit leaves {ratio:.1f} × the noise in {name}: the fitted model "
            "does not explain the data (a local minimum, or other parameters to free); see fit.md",
            file=sys.stderr,
        )
    if result.undetermined:
        for name, why in result.undetermined.items():
            print(f"lubrig fit: warning: {name} is not determined by the data: {why}", file=sys.stderr)
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add `lubrig fit`."""
    parser = subparsers.add_parser(
        "fit",
        help="identify rig and friction parameters from a measured record (fit.json, config.yaml, page)",
        description="Fit the named parameters to a measured record by multiple shooting and bounded "
        "nonlinear least squares on the compiled core. DATA: a CSV with a header "
        "time,band_velocity,displacement[,friction_coefficient] in SI units (s, m/s, m, 1; "
        "time_s, band_velocity_m_s, displacement_m accepted), uniformly sampled; or a bag directory "
        "recorded by `lubrig rig` (displacement and μ from <ns>/state_block, band velocity from "
        "<ns>/band_velocity_block). Writes fit.json, config.yaml (+ band.csv), fit.md and figures "
        "to --out. Parameters the data cannot determine are named on stderr and in fit.json, and so "
        "is a fit that stops without converging or leaves a parameter on a bound of its range.",
    )
    parser.add_argument("data", metavar="DATA", help="CSV file or bag directory")
    parser.add_argument(
        "--free", metavar="NAME", nargs="+", action="extend", required=True, help=_free_help()
    )
    add_run_source(parser)
    parser.add_argument("--out", metavar="DIR", required=True, help="output directory")
    parser.add_argument(
        "--segment",
        metavar="S",
        default=str(SEGMENT_SECONDS),
        help=f"multiple-shooting segment length, s (default {SEGMENT_SECONDS:g})",
    )
    parser.add_argument(
        "--workers",
        metavar="N",
        default=str(os.cpu_count() or 1),
        help=f"processes for the Jacobian's runs, 1..{MAX_LOCAL_WORKERS} (default: one per core, "
        f"{os.cpu_count() or 1} here)",
    )
    parser.add_argument(
        "--max-evaluations",
        metavar="N",
        default=str(MAX_EVALUATIONS),
        help=f"residual evaluations per stage at most (default {MAX_EVALUATIONS})",
    )
    add_force(parser)
    parser.set_defaults(func=run)
