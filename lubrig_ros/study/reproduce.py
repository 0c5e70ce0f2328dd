"""`lubrig paper`: reproduce the study offline and score every statement of it, per reading.

For each named velocity-coupling convention (physical γ = 1, paper γ = 1/ω0, hertz γ = 1/f0) it
runs the ten Table 1 cases and the 2e-8 m/s stick-slip run, measures them (study.runs) and
evaluates every statement of the model doc's section 8 (study.statements.STATEMENTS); with a coupling
scan table ({s: metrics}, from the sweep engine or the committed CSV) it adds the scorecard over
s = γ · A / A_default with its figures. DIR/comparison.md embeds every figure from DIR/study/
(relative links only, so the page and DIR/study/ can be copied into docs/ as they are); the run
directories are in DIR/runs/<convention>/.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import shutil
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

import numpy as np

from lubrig_ros.core.errors import InputError

from ..app.selection import base_config
from ..core.params import CONVENTIONS, RigParameters
from ..core.run import simulate, summarize
from .floquet import period_doubling
from .page import (
    CASE_FIGURES,
    FIGURES,
    HTML_PAGE,
    PAGE,
    comparison_markdown,
    readings,
    scan_scorecards,
    score,
)
from .runs import STICKSLIP, Metrics, case_metrics, rig_with_coupling, study_configs
from .statements import STATEMENTS, Verdict, scorecard

MIN_DURATION = 4.0
#: Worker processes `lubrig paper` uses at most (its runs and the Floquet computation in parallel).
PAPER_WORKERS = 2
#: What `lubrig paper` writes into its folder (what --force replaces); the scan table and the
#: recomputed scan are written by the command (cli/paper.py).
PAGE_OUTPUTS = (PAGE, HTML_PAGE, FIGURES, "runs")
#: Called after every run: (rig seconds simulated so far, what was just done).
ProgressCallback = Callable[[float, str], None]


def _copy_small(source: Path, destination: Path) -> None:
    """Copy a PNG figure, as an 8-bit palette image (about 3 × smaller, same look)."""
    from PIL import Image

    with Image.open(source) as image:
        image.convert("RGB").quantize(colors=255, method=Image.Quantize.FASTOCTREE).save(destination)


def _run_case(
    coupling: str,
    number: int,
    duration: float,
    out: Path,
    figures: Path | None,
    wavelet: bool,
) -> tuple[int, dict[str, Any], dict[str, Any]]:
    """Simulate and measure one study run of one reading; write its run directory.

    With `figures` (the presets' reading) the run directory holds the CSV, config.yaml,
    summary.json and the embedded figures (time history, phase plot, wavelet.png with `wavelet`),
    copied to `figures` too; otherwise only config.yaml and summary.json are written (the page
    quotes their numbers). Returns (number, metrics, summary); runs in a worker process.
    """
    from ..app.analysis.policy import DEFAULT_POLICY, analyze_displacement
    from ..app.rundir import write_json, write_run
    from ..figures.run import WAVELET_FIGURE, write_wavelet_figure
    from ..figures.style import DPI
    from ..figures.timeseries import FIGURES as RUN_FIGURES

    config = study_configs(coupling, duration)[number]
    trajectory = simulate(config)
    summary = summarize(trajectory, config)
    name = "stickslip" if number == STICKSLIP else f"case{number:02d}"
    directory = out / name
    if figures is not None:
        analysis = None
        if wavelet and number != STICKSLIP:  # app/analysis/policy.py's one policy (second half)
            analysis = analyze_displacement(
                trajectory.time,
                trajectory.displacement,
                config.sample_rate,
                config.band.fundamental_hz,
                DEFAULT_POLICY,
            )
        # figures/run.py's directory with the figures the page embeds (the stick-slip run's
        # are left out: rendering is most of the page's cost)
        if analysis is not None:
            section = dict(analysis.summary_section(), figure=WAVELET_FIGURE)
            summary = dict(summary, wavelet=section)
        write_run(directory, config, trajectory, summary)
        if number != STICKSLIP:
            for figure in CASE_FIGURES:
                if figure in RUN_FIGURES:
                    RUN_FIGURES[figure](
                        trajectory, config.name, config.rig.coupling_name, config.rig
                    ).savefig(directory / figure, dpi=DPI)
        if analysis is not None:
            write_wavelet_figure(directory, config, analysis)
    else:
        directory.mkdir(parents=True, exist_ok=True)
        (directory / "config.yaml").write_text(config.to_yaml())
        write_json(directory / "summary.json", summary)
    metrics = case_metrics(config, trajectory)
    if figures is not None and number != STICKSLIP:
        figures.mkdir(parents=True, exist_ok=True)
        for figure in CASE_FIGURES:
            if (directory / figure).is_file():
                _copy_small(directory / figure, figures / f"{name}_{figure}")
    return number, metrics, summary


@contextlib.contextmanager
def _single_threaded_blas() -> Iterator[None]:
    """BLAS/OpenMP thread counts of 1 in the environment that spawned workers start with."""
    names = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
    saved = {name: os.environ.get(name) for name in names}
    os.environ.update(dict.fromkeys(names, "1"))
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def paper_workers() -> int:
    """Worker processes for `lubrig paper`: the CPUs this process may use, at most PAPER_WORKERS."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cpus = os.cpu_count() or 1
    return max(1, min(cpus, PAPER_WORKERS))


def _scan_figures(cards: dict[float, list[Verdict]], scan: dict[float, Metrics], figures: Path) -> list[str]:
    from .figures import agreed_figure, measures_figure, save, verdict_map_figure

    marks = readings()
    s = np.array(sorted(cards))
    agreed = np.array([score(cards[v]) for v in s])
    keys = [st.key for st in STATEMENTS]
    grid = np.array([[next(v.agree for v in cards[x] if v.key == k) for x in s] for k in keys])

    def series(case: int, key: str) -> np.ndarray:
        return np.array([np.nan if scan[v][case][key] is None else scan[v][case][key] for v in s])

    ratio = series(7, "x_peak_to_peak") / series(5, "x_peak_to_peak")
    names = []
    save(agreed_figure(s, agreed, len(STATEMENTS), marks), figures / "scan_agreed.png")
    names.append("scan_agreed.png")
    save(verdict_map_figure(s, keys, grid, marks), figures / "scan_verdicts.png")
    names.append("scan_verdicts.png")
    measures = {
        "case 7 / case 5 peak-to-peak (study: eight times)": (ratio, "ratio", (6.0, 10.0)),
        "case 8: growth rate of the 10 Hz subharmonic (> 0: the 20 Hz orbit period-doubles)": (
            series(8, "f0_growth_rate"),
            "1/s",
            None,
        ),
        "case 8: late 10 Hz amplitude": (series(8, "f0_amplitude_late"), "m", None),
        "case 8: stick fraction (second half)": (series(8, "stick_fraction"), "fraction", (0.05, 1.0)),
        "case 3: envelope rate on V1 plateaus (study: > 0)": (series(3, "growth_v1"), "1/s", None),
    }
    fig = measures_figure(s, measures, marks)
    fig.axes[2].set_yscale("log")
    save(fig, figures / "scan_measures.png")
    names.append("scan_measures.png")
    return names


def total_rig_time(duration: float) -> float:
    """Rig seconds `lubrig paper` simulates: every study run of every named reading."""
    return float(sum(c.duration for name in CONVENTIONS for c in study_configs(name, duration).values()))


def run_paper(
    out: str | Path,
    duration: float = 20.0,
    scan: dict[float, Metrics] | None = None,
    scan_source: str = "",
    force: bool = False,
    progress: ProgressCallback | None = None,
    workers: int | None = None,
) -> Path:
    """Write the runs, every figure, comparison.md and comparison.html into out; return the .md.

    An existing non-empty out is refused unless force (PAGE_OUTPUTS are replaced then);
    progress(rig seconds done, detail) is called after every run.
    """
    from ..app import rundir  # noqa: F401  (imported once here, inherited by forked workers)
    from ..app.analysis import policy  # noqa: F401  (the same)
    from ..app.rundir import prepare_output_dir
    from ..figures import run, timeseries  # noqa: F401
    from ..figures.curves import plot_friction_curve, plot_stability_map, save_figure
    from ..report.html import write_html_page

    if not (np.isfinite(duration) and duration >= MIN_DURATION):
        raise InputError(f"--duration {duration!r} is not valid; expected at least {MIN_DURATION:g} s")
    out = prepare_output_dir(Path(out), force, "--out", PAGE_OUTPUTS)
    done = [0.0]

    def advance(seconds: float, detail: str) -> None:
        done[0] += seconds
        if progress is not None:
            progress(done[0], detail)

    started = time.perf_counter()
    figures = out / FIGURES
    figures.mkdir(parents=True, exist_ok=True)
    preset = base_config(case=1).rig.coupling_name
    cards: dict[str, list[Verdict]] = {}
    summaries: dict[str, dict[int, dict[str, Any]]] = {name: {} for name in CONVENTIONS}
    metrics: dict[str, Metrics] = {name: {} for name in CONVENTIONS}
    # every run of every reading (the presets' reading first: its figures cost most) and the
    # Floquet computation in worker processes; the friction curve and stability maps meanwhile here
    order = [preset, *(name for name in CONVENTIONS if name != preset)]
    # spawned workers with one BLAS thread each: forked ones inherit the parent's OpenBLAS thread
    # pool, and 2 workers × 2 spinning BLAS threads on 2 cores made the run slower than serial
    # (docs/report.md)
    with (
        _single_threaded_blas(),
        ProcessPoolExecutor(
            workers or paper_workers(), mp_context=multiprocessing.get_context("spawn")
        ) as pool,
    ):
        doubling_job = pool.submit(period_doubling)
        jobs = {
            pool.submit(
                _run_case,
                name,
                number,
                duration,
                out / "runs" / name,
                figures / name if name == preset else None,
                name == preset,
            ): name
            for name in order
            for number in study_configs(name, duration)
        }
        save_figure(plot_friction_curve(), figures / "friction_curve.png")
        for name in CONVENTIONS:
            save_figure(
                plot_stability_map(rig_with_coupling(RigParameters(), name)),
                figures / f"stability_map_{name}.png",
            )
        scan_cards = scan_scorecards(scan) if scan else {}
        scan_figures = _scan_figures(scan_cards, scan, figures) if scan else []
        for job in as_completed(jobs):
            name = jobs[job]
            number, metrics[name][number], summaries[name][number] = job.result()
            label = "stickslip" if number == STICKSLIP else f"case{number:02d}"
            advance(duration, f"{name} {label}")
        doubling = doubling_job.result()
    for name in CONVENTIONS:
        summaries[name] = dict(sorted(summaries[name].items()))
        cards[name] = scorecard(dict(sorted(metrics[name].items())), rig_with_coupling(RigParameters(), name))
    page = out / PAGE
    page.write_text(
        comparison_markdown(
            cards,
            summaries,
            scan,
            scan_source,
            duration,
            preset,
            scan_figures,
            time.perf_counter() - started,
            scan_cards=scan_cards,
            doubling=doubling,
        )
    )
    write_html_page(page, "The study reproduced, statement by statement")
    return page


def copy_to_docs(page: Path, docs: str | Path) -> Path:
    """Copy comparison.md to DOCS/study.md and its figure directory to DOCS/study/ (links stay valid)."""
    docs = Path(docs)
    target = docs / FIGURES
    if target.exists():
        for old in target.rglob("*.png"):
            old.unlink()
    for figure in (page.parent / FIGURES).rglob("*.png"):
        destination = target / figure.relative_to(page.parent / FIGURES)
        destination.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(figure, destination)
    shutil.copyfile(page, docs / "study.md")
    return docs / "study.md"
