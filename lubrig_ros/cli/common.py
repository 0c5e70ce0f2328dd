"""Helpers shared by the `lubrig` subcommands: one-line number errors, the run-selection options.

The options (--case | --config, band and rig overrides) map onto app/selection.py's RunSelection.
"""

from __future__ import annotations

import argparse
import math
import re
from pathlib import Path

from ..app.selection import RunSelection
from ..core.profiles import BandProfile, ConstantBand, RegularCycle, TableBand

# argparse (Python < 3.13) takes "-1e-7" for an option; accept any signed float literal as a value.
NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-(inf|nan)$", re.IGNORECASE)


def parse_finite(option: str, text: str, what: str) -> float:
    """Parse one command-line number; non-numbers and NaN/inf raise ValueError naming the value."""
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{option} {text!r} is not a number; expected {what}") from None
    if not math.isfinite(value):
        raise ValueError(f"{option} {text!r} is not finite; expected {what}")
    return value


def parse_coupling(text: str, option: str = "--velocity-coupling") -> str | float:
    """A velocity coupling γ: a convention name (physical | paper | hertz) or a finite number > 0."""
    from ..core.params import CONVENTIONS

    if text in CONVENTIONS:
        return text
    what = f"one of {'|'.join(CONVENTIONS)} or a number > 0 (γ in v_rel = v_band − γ ẋ)"
    value = parse_finite(option, text, what)
    if value <= 0.0:
        raise ValueError(f"{option} {text!r} must be > 0; expected {what}")
    return value


def allow_negative_numbers(parser: argparse.ArgumentParser) -> None:
    """Let values such as "-1e-7" reach our own validation instead of argparse's option parsing."""
    parser._negative_number_matcher = NEGATIVE_NUMBER


def add_force(parser: argparse.ArgumentParser) -> None:
    """--force: replace the outputs in an existing, non-empty output folder (else refused)."""
    parser.add_argument(
        "--force",
        action="store_true",
        help="write into an existing non-empty output folder, replacing this command's files there",
    )


def add_run_source(parser: argparse.ArgumentParser) -> None:
    """--case N | --config FILE (neither: the default run, config/rig.yaml)."""
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--case", metavar="N", help="study Table 1 case 1..10 (paper convention)")
    source.add_argument("--config", metavar="FILE", help="run configuration YAML (see config/)")


def add_run_selection(parser: argparse.ArgumentParser) -> None:
    """Options that choose and override a run (`lubrig simulate`)."""
    add_run_source(parser)
    band = parser.add_mutually_exclusive_group()
    band.add_argument("--band-velocity", metavar="V", help="constant band velocity, m/s")
    band.add_argument("--cycle", nargs=4, metavar=("V1", "V2", "TC", "TRAMP"), help="study band cycle")
    band.add_argument("--profile", metavar="CSV", help="table of time_s,band_velocity_m_s (piecewise linear)")
    parser.add_argument(
        "--convention", metavar="C", help="relative-velocity convention: physical | paper | hertz"
    )
    parser.add_argument(
        "--velocity-coupling",
        metavar="G",
        help="γ in v_rel = v_band − γ ẋ: physical (1) | paper (1/ω0) | hertz (1/f0) | a number > 0",
    )
    parser.add_argument("--zeta", metavar="Z", help="damping ratio ζ")
    parser.add_argument("--mass", metavar="KG", help="mass m, kg")
    parser.add_argument("--natural-frequency", metavar="HZ", help="natural frequency f0, Hz")
    parser.add_argument("--contact-area", metavar="A", help="corrected | printed | area in m²")
    parser.add_argument("--duration", metavar="S", help="rig time to simulate, s")
    parser.add_argument("--sample-rate", metavar="HZ", help="output sample rate, Hz (default 1000)")
    parser.add_argument("--rtol", metavar="R", help="integrator relative tolerance (default 1e-12)")
    allow_negative_numbers(parser)


def _number(args: argparse.Namespace, name: str, option: str, what: str) -> float | None:
    text = getattr(args, name, None)
    return None if text is None else parse_finite(option, text, what)


def band_from_args(args: argparse.Namespace) -> BandProfile | None:
    """The band override of --band-velocity | --cycle | --profile, None without one."""
    if getattr(args, "band_velocity", None) is not None:
        return ConstantBand(parse_finite("--band-velocity", args.band_velocity, "a finite velocity in m/s"))
    if getattr(args, "cycle", None) is not None:
        names = ("V1", "V2", "TC", "TRAMP")
        values = [
            parse_finite(f"--cycle {n}", t, "a finite number") for n, t in zip(names, args.cycle, strict=True)
        ]
        return RegularCycle(*values)
    if getattr(args, "profile", None) is not None:
        return TableBand.from_csv(args.profile)
    return None


def source_from_args(args: argparse.Namespace) -> RunSelection:
    """Only the source (--case | --config | default) of the parsed options, no overrides."""
    config = getattr(args, "config", None)
    return RunSelection(case=getattr(args, "case", None), config_file=Path(config) if config else None)


def selection_from_args(args: argparse.Namespace) -> RunSelection:
    """The RunSelection of the parsed options (options a subcommand lacks count as not given)."""
    config = getattr(args, "config", None)
    return RunSelection(
        case=getattr(args, "case", None),
        config_file=Path(config) if config is not None else None,
        band=band_from_args(args),
        contact_area=getattr(args, "contact_area", None),
        convention=getattr(args, "convention", None),
        velocity_coupling=(
            None if getattr(args, "velocity_coupling", None) is None
            else parse_coupling(args.velocity_coupling)
        ),
        damping_ratio=_number(args, "zeta", "--zeta", "a damping ratio >= 0"),
        mass=_number(args, "mass", "--mass", "a mass > 0 in kg"),
        natural_frequency=_number(args, "natural_frequency", "--natural-frequency", "a frequency > 0 in Hz"),
        duration=_number(args, "duration", "--duration", "a duration > 0 in s"),
        sample_rate=_number(args, "sample_rate", "--sample-rate", "a sample rate > 0 in Hz"),
        rtol=_number(args, "rtol", "--rtol", "a relative tolerance in [1e-13, 1e-2]"),
    )
