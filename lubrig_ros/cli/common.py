"""Helpers shared by the `lubrig` subcommands: one-line number errors, the run-selection options.

The options (--case | --config, band and rig overrides) map onto app/selection.py's RunSelection.
"""

from __future__ import annotations

import argparse
import math
import os
import re
from pathlib import Path

from lubrig_ros.core.errors import InputError

from ..app.selection import RunSelection
from ..core import schema
from ..core.params import CONVENTION_CHOICES
from ..core.profiles import BandProfile, ConstantBand, RegularCycle, TableBand
from ..core.schema import FieldSpec

# argparse (Python < 3.13) takes "-1e-7" for an option; accept any signed float literal as a value.
NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-(inf|nan)$", re.IGNORECASE)


def parse_finite(option: str, text: str, what: str) -> float:
    """Parse one command-line number; non-numbers and NaN/inf raise ValueError naming the value."""
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"{option} {text!r} is not a number; expected {what}") from None
    if not math.isfinite(value):
        raise InputError(f"{option} {text!r} is not finite; expected {what}")
    return value


#: Local worker processes at most (--workers): a few per core; more only thrash the machine.
MAX_LOCAL_WORKERS = 4 * (os.cpu_count() or 1)


def parse_workers(text: str, option: str = "--workers") -> int:
    """A local worker count: an integer 1..MAX_LOCAL_WORKERS."""
    what = f"an integer 1..{MAX_LOCAL_WORKERS} (4 per core of this machine)"
    try:
        value = int(text)
    except ValueError:
        raise InputError(f"{option} {text!r} is not an integer; expected {what}") from None
    if not 1 <= value <= MAX_LOCAL_WORKERS:
        raise InputError(f"{option} {value} is not valid; expected {what}")
    return value


def parse_coupling(text: str, option: str = "--velocity-coupling") -> str | float:
    """A velocity coupling γ: a convention name (physical | paper | hertz) or a finite number > 0."""
    from ..core.params import CONVENTIONS

    if text in CONVENTIONS:
        return text
    what = f"one of {'|'.join(CONVENTIONS)} or a number > 0 (γ in v_rel = v_band − γ ẋ)"
    value = parse_finite(option, text, what)
    if value <= 0.0:
        raise InputError(f"{option} {text!r} must be > 0; expected {what}")
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


def _ranged(text: str, spec: FieldSpec) -> str:
    """Help text with the field's physical range (core/schema.py)."""
    return f"{text}; physical range {spec.range_text()}"


def add_run_selection(parser: argparse.ArgumentParser) -> None:
    """Options that choose and override a run (`lubrig simulate`); help shows each range."""
    add_run_source(parser)
    rig, sim = schema.RIG_FIELDS, schema.SIMULATION_FIELDS
    cycle = schema.BAND_FIELDS["cycle"]
    band = parser.add_mutually_exclusive_group()
    band.add_argument(
        "--band-velocity",
        metavar="V",
        help=_ranged("constant band velocity, m/s", schema.band_field("velocity")),  # type: ignore[arg-type]
    )
    band.add_argument(
        "--cycle",
        nargs=4,
        metavar=("V1", "V2", "TC", "TRAMP"),
        help=f"study band cycle: V1 < V2 in {cycle['low_velocity'].range_text()}, TC in "
        f"{cycle['plateau_time'].range_text()}, TRAMP in {cycle['ramp_time'].range_text()}",
    )
    band.add_argument("--profile", metavar="CSV", help="table of time_s,band_velocity_m_s (piecewise linear)")
    parser.add_argument(
        "--convention", metavar="C", help=f"relative-velocity convention: {CONVENTION_CHOICES}"
    )
    parser.add_argument(
        "--velocity-coupling",
        metavar="G",
        help=_ranged(
            "γ in v_rel = v_band − γ ẋ: physical (1) | paper (1/ω0) | hertz (1/f0) | a number",
            rig["velocity_coupling"],
        ),
    )
    for spec in rig_options():
        parser.add_argument(str(spec.cli_option), metavar=spec.cli_metavar, help=_ranged(spec.label, spec))
    area = schema.friction_field("junction_kinetics", "contact_area")
    parser.add_argument(
        "--contact-area",
        metavar="A",
        help=_ranged("corrected | printed | area in m²", area),  # type: ignore[arg-type]
    )
    parser.add_argument("--duration", metavar="S", help=_ranged("rig time to simulate, s", sim["duration"]))
    parser.add_argument(
        "--sample-rate",
        metavar="HZ",
        help=_ranged("output sample rate, Hz (default 1000)", sim["sample_rate"]),
    )
    parser.add_argument("--rtol", metavar="R", help=_ranged("integrator relative tolerance", sim["rtol"]))
    allow_negative_numbers(parser)


#: Memory `lubrig simulate` needs per output sample, bytes: the trajectory's six float64 columns,
#: the summary's and figures' temporaries and the CSV rows (a generous estimate, not a measurement
#: of one run: the wavelet analysis is bounded on its own, app/analysis/policy.py).
SIMULATE_BYTES_PER_SAMPLE = 400


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation (Linux MemAvailable), None if unknown."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (OSError, ValueError, AttributeError):
        return None


def check_fits_in_memory(
    samples: int, sample_rate: float, bytes_per_sample: int = SIMULATE_BYTES_PER_SAMPLE
) -> None:
    """ValueError when a run of `samples` output samples would not fit in the available memory."""
    free = available_memory()
    if free is None:
        return
    most = int(0.5 * free / bytes_per_sample)  # half of what is free: leave room for the rest
    if samples > most:
        raise InputError(
            f"{samples} samples need about {samples * bytes_per_sample / 1e9:.3g} GB of memory, this "
            f"machine has {free / 1e9:.3g} GB available: at most {most} samples (--duration <= "
            f"{most / sample_rate:g} s at {sample_rate:g} Hz)"
        )


def _number(args: argparse.Namespace, name: str, option: str, what: str) -> float | None:
    text = getattr(args, name, None)
    return None if text is None else parse_finite(option, text, what)


def rig_options() -> list[schema.RigField]:
    """The rig fields with a `lubrig simulate` option (`--zeta`, `--mass`, ...), schema order."""
    return [spec for spec in schema.RIG_FIELDS.values() if spec.override and spec.cli_option]


def _rig_option(args: argparse.Namespace, spec: schema.RigField) -> float | None:
    option = str(spec.cli_option)
    dest = option.removeprefix("--").replace("-", "_")
    return _number(args, dest, option, f"a {spec.name.replace('_', ' ')} in {spec.range_text()}")


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
            None
            if getattr(args, "velocity_coupling", None) is None
            else parse_coupling(args.velocity_coupling)
        ),
        **{spec.name: _rig_option(args, spec) for spec in rig_options()},
        duration=_number(args, "duration", "--duration", "a duration > 0 in s"),
        sample_rate=_number(args, "sample_rate", "--sample-rate", "a sample rate > 0 in Hz"),
        rtol=_number(args, "rtol", "--rtol", "a relative tolerance in [1e-13, 1e-2]"),
    )
