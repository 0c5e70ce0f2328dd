"""`lubrig simulate`: integrate one run offline and write time series, figures and a summary.

Output directory layout (documented in docs/simulate.md):
- timeseries.csv: header `time_s,displacement_m,velocity_m_s,friction_coefficient,
  band_velocity_m_s,relative_velocity_m_s`, one row per sample, uniform sampling from t = 0;
- config.yaml: the full run configuration (feed it back with --config to repeat the run);
- summary.json: stationary measures of the second half of the run;
- time_history.png, phase.png, friction_velocity.png.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from ..core.presets import RunConfig, default_config, from_mapping, load_case, load_config
from ..core.profiles import ConstantBand, RegularCycle, TableBand
from ..core.run import simulate, summarize
from .common import allow_negative_numbers, parse_finite, write_json

CSV_COLUMNS = (
    "time_s,displacement_m,velocity_m_s,friction_coefficient,band_velocity_m_s,relative_velocity_m_s"
)


def _number(option: str, text: str | None, what: str) -> float | None:
    return None if text is None else parse_finite(option, text, what)


def config_from_args(args: argparse.Namespace) -> RunConfig:
    """The run configuration selected and overridden by the command-line options."""
    if args.case is not None:
        config = load_case(args.case)
    elif args.config is not None:
        config = load_config(args.config)
    else:
        config = default_config()
    if args.band_velocity is not None:
        velocity = parse_finite("--band-velocity", args.band_velocity, "a finite velocity in m/s")
        config = config.with_overrides(band=ConstantBand(velocity))
    elif args.cycle is not None:
        names = ("V1", "V2", "TC", "TRAMP")
        values = [
            parse_finite(f"--cycle {n}", t, "a finite number")
            for n, t in zip(names, args.cycle, strict=True)
        ]
        config = config.with_overrides(band=RegularCycle(*values))
    elif args.profile is not None:
        config = config.with_overrides(band=TableBand.from_csv(args.profile))
    if args.contact_area is not None:
        data = config.to_dict()
        data["rig"]["friction"]["contact_area"] = args.contact_area
        config = from_mapping(data)
    return config.with_overrides(
        convention=args.convention,
        damping_ratio=_number("--zeta", args.zeta, "a damping ratio >= 0"),
        mass=_number("--mass", args.mass, "a mass > 0 in kg"),
        natural_frequency=_number("--natural-frequency", args.natural_frequency, "a frequency > 0 in Hz"),
        duration=_number("--duration", args.duration, "a duration > 0 in s"),
        sample_rate=_number("--sample-rate", args.sample_rate, "a sample rate > 0 in Hz"),
        rtol=_number("--rtol", args.rtol, "a relative tolerance in [1e-13, 1e-2]"),
    )


def write_run(out: Path, config: RunConfig, trajectory: object, summary: dict) -> None:
    """Write the run directory (CSV, config, summary, figures)."""
    from ..figures.timeseries import FIGURES

    out.mkdir(parents=True, exist_ok=True)
    columns = np.column_stack(list(trajectory.as_columns().values()))
    np.savetxt(out / "timeseries.csv", columns, delimiter=",", header=CSV_COLUMNS, comments="", fmt="%.17g")
    (out / "config.yaml").write_text(config.to_yaml())
    write_json(out / "summary.json", summary)
    for filename, make in FIGURES.items():
        make(trajectory, config.name, config.rig.convention).savefig(out / filename, dpi=110)


def run(args: argparse.Namespace) -> int:
    """Entry of `lubrig simulate`."""
    config = config_from_args(args)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {str(out)!r} exists and is not a directory")
    started = time.perf_counter()
    trajectory = simulate(config)
    elapsed = time.perf_counter() - started
    summary = summarize(trajectory, config)
    summary["wall_time_s"] = elapsed
    write_run(out, config, trajectory, summary)
    print(
        f"{config.name}: {config.duration:g} s of rig time in {elapsed:.3f} s "
        f"({config.rig.convention} convention); x peak-to-peak {summary['x_peak_to_peak']:.3e} m, "
        f"μ {summary['mu_min']:.4g}…{summary['mu_max']:.4g}, stick fraction {summary['stick_fraction']:.2f}; "
        f"results in {out}/",
        file=sys.stdout,
    )
    return 0


def add_run_selection(parser: argparse.ArgumentParser) -> None:
    """Options that choose and override a run (shared with other subcommands)."""
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--case", metavar="N", help="study Table 1 case 1..10 (paper convention)")
    source.add_argument("--config", metavar="FILE", help="run configuration YAML (see config/)")
    band = parser.add_mutually_exclusive_group()
    band.add_argument("--band-velocity", metavar="V", help="constant band velocity, m/s")
    band.add_argument("--cycle", nargs=4, metavar=("V1", "V2", "TC", "TRAMP"), help="study band cycle")
    band.add_argument("--profile", metavar="CSV", help="table of time_s,band_velocity_m_s (piecewise linear)")
    parser.add_argument("--convention", metavar="C", help="relative-velocity convention: physical | paper")
    parser.add_argument("--zeta", metavar="Z", help="damping ratio ζ")
    parser.add_argument("--mass", metavar="KG", help="mass m, kg")
    parser.add_argument("--natural-frequency", metavar="HZ", help="natural frequency f0, Hz")
    parser.add_argument("--contact-area", metavar="A", help="corrected | printed | area in m²")
    parser.add_argument("--duration", metavar="S", help="rig time to simulate, s")
    parser.add_argument("--sample-rate", metavar="HZ", help="output sample rate, Hz (default 1000)")
    parser.add_argument("--rtol", metavar="R", help="integrator relative tolerance (default 1e-8)")
    allow_negative_numbers(parser)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add `lubrig simulate`."""
    parser = subparsers.add_parser(
        "simulate",
        help="integrate one run offline (time series, figures, summary.json)",
        description="Integrate the rig offline and write timeseries.csv, config.yaml, summary.json "
        "and figures to --out.",
    )
    add_run_selection(parser)
    parser.add_argument("--out", metavar="DIR", required=True, help="output directory")
    parser.set_defaults(func=run)
