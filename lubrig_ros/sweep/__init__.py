"""Design maps: parameter sweeps of full core runs, resumable, on local cores or a Dask cluster."""

from .engine import SweepResult, run_sweep
from .point import run_point
from .spec import Axis, Point, SpecError, SweepSpec, load_spec, parse_spec
from .store import SweepStore, records_table

__all__ = [
    "Axis",
    "Point",
    "SpecError",
    "SweepResult",
    "SweepSpec",
    "SweepStore",
    "load_spec",
    "parse_spec",
    "records_table",
    "run_point",
    "run_sweep",
]
