"""What `lubrig fit` writes: fit.json, the fitted config.yaml (+ band.csv) and fit.md with figures.

* fit.json: estimates with standard errors, units, bounds and start values, the correlation
  matrix, the parameters the data cannot determine and why, the fitted initial state, residual
  RMS and noise per stream, cost, evaluations, method, what was free and what was held fixed, and
  the data's fingerprint (SHA-256 of its arrays, fit.data.MeasuredData.fingerprint);
* config.yaml: the start configuration with the fitted values, the measured band as a table
  profile (band.csv beside it, time_s,band_velocity_m_s), the record's duration and sample rate and
  the initial perturbation of the fitted x(0) — a run configuration every command and node reads
  (`lubrig simulate --config DIR/config.yaml`, the belt_drive node's profile.path);
* fit.md with fit_time_history.png (measured against the fitted rig run once over the whole
  record from the fitted initial state, and the shooting segments the fit matched),
  fit_residuals.png, fit_friction.png (the fitted μ(v) over the data's (v_rel, μ) points, when μ
  was measured) and fit_stability.png (the stability map of the fitted rig).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from matplotlib.figure import Figure

from ..app.fileio import write_text_atomic
from ..core.friction import friction_coefficient
from ..core.integrator import RigIntegrator
from ..core.presets import RunConfig
from ..core.schema import SIMULATION_FIELDS
from ..core.trajectory import Trajectory, concatenate
from ..figures import style
from ..figures.curves import plot_stability_map, save_figure
from .data import MeasuredData
from .parameters import fixed_values
from .shooting import FIT_INTEGRATION
from .solve import FitResult, bound_warning, unconverged

#: Every file `lubrig fit` writes into --out (replaced with --force).
FIT_FILES: tuple[str, ...] = (
    "fit.json",
    "config.yaml",
    "band.csv",
    "fit.md",
    "fit_time_history.png",
    "fit_residuals.png",
    "fit_friction.png",
    "fit_stability.png",
)
UNITS = {"displacement": "m", "friction_coefficient": "–"}


def fitted_run(result: FitResult, data: MeasuredData) -> Trajectory:
    """The fitted rig integrated once over the whole record from the fitted initial state."""
    assert result.config is not None
    integrator = RigIntegrator(
        result.config.rig,
        float(data.band_velocity[0]),
        sample_rate=data.sample_rate,
        rtol=result.config.rtol,
        **FIT_INTEGRATION,
        initial_displacement=float(result.initial_state[0]),
        initial_velocity=float(result.initial_state[1]),
    )
    return concatenate([integrator.current(), integrator.advance(data.band_velocity[1:])])


def initial_perturbation(result: FitResult, data: MeasuredData) -> float:
    """x(0) / x0 − 1 of the fitted rig (x0 its equilibrium at the first band velocity), in range."""
    assert result.config is not None
    rig = result.config.rig
    mu = float(friction_coefficient(np.array([data.band_velocity[0]]), rig.friction)[0])
    equilibrium = mu * rig.normal_force / rig.stiffness
    spec = SIMULATION_FIELDS["initial_perturbation"]
    ratio = result.initial_state[0] / equilibrium - 1.0 if equilibrium else 0.0
    return float(np.clip(ratio, spec.low, spec.high))


def fitted_config(result: FitResult, data: MeasuredData) -> dict[str, Any]:
    """The fitted run configuration as a mapping, its band the table in band.csv."""
    assert result.config is not None
    config: RunConfig = result.config
    mapping = config.to_dict()
    mapping["name"] = "fit"
    mapping["description"] = f"fitted by lubrig fit to {data.source} (free: {', '.join(result.names)})"
    mapping["band"] = {"kind": "table", "path": "band.csv"}
    mapping["simulation"].update(
        duration=float(data.time[-1]),
        sample_rate=float(round(data.sample_rate, 6)),
        initial_perturbation=initial_perturbation(result, data),
    )
    return mapping


def fit_document(result: FitResult, data: MeasuredData, start: str) -> dict[str, Any]:
    """fit.json's content."""
    assert result.config is not None
    document = result.to_dict()
    document["free"] = result.names
    document["fixed"] = fixed_values(result.config, result.parameters)
    document["start_configuration"] = start
    document["initial_perturbation"] = initial_perturbation(result, data)
    document["data"] = {
        "source": data.source,
        "sha256": data.fingerprint(),
        "samples": int(data.time.size),
        "sample_rate_hz": data.sample_rate,
        "duration_s": float(data.time[-1]),
        "streams": list(data.streams),
    }
    return document


def _time_history(data: MeasuredData, result: FitResult, run: Trajectory) -> Figure:
    streams = list(data.streams)
    fig = Figure(figsize=style.WIDE, dpi=style.DPI, layout="constrained")
    axes = fig.subplots(len(streams), 1, sharex=True, squeeze=False)[:, 0]
    for ax, name in zip(axes, streams, strict=True):
        fitted = run.displacement if name == "displacement" else run.friction_coefficient
        ax.plot(data.time, data.streams[name], ".", ms=1.5, color="0.6", label="measured")
        ax.plot(
            data.time, result.model[name], lw=1.0, color=style.COLOURS[name], label="fit (shooting segments)"
        )
        ax.plot(
            data.time, fitted, lw=0.9, ls="--", color="black", label="fitted rig, one run from x(0), ẋ(0)"
        )
        ax.set_ylabel(f"{name.replace('_', ' ')} ({UNITS[name]})")
        ax.legend(fontsize=style.LEGEND_SIZE, loc="best")
    axes[-1].set_xlabel(style.TIME)
    axes[0].set_title("Measured against fitted", fontsize=style.TITLE_SIZE)
    return fig


def _residuals(data: MeasuredData, result: FitResult) -> Figure:
    streams = list(data.streams)
    fig = Figure(figsize=style.WIDE, dpi=style.DPI, layout="constrained")
    axes = fig.subplots(len(streams), 1, sharex=True, squeeze=False)[:, 0]
    for ax, name in zip(axes, streams, strict=True):
        residual = data.streams[name] - result.model[name]
        ax.plot(data.time, residual, lw=0.6, color=style.COLOURS[name])
        noise = result.noise[name]
        ax.axhspan(
            -noise, noise, color="0.85", zorder=0, label=f"±σ noise estimate ({noise:.3g} {UNITS[name]})"
        )
        ax.set_ylabel(f"measured − fit ({UNITS[name]})")
        ax.legend(fontsize=style.LEGEND_SIZE, loc="upper right")
    axes[-1].set_xlabel(style.TIME)
    axes[0].set_title(
        "Residuals of the fit (RMS "
        + ", ".join(f"{k} {v:.3g}" for k, v in result.residual_rms.items())
        + ")",
        fontsize=style.TITLE_SIZE,
    )
    return fig


def _friction(data: MeasuredData, result: FitResult, run: Trajectory) -> Figure:
    assert result.config is not None and data.friction_coefficient is not None
    relative = run.relative_velocity
    fig = Figure(figsize=style.SQUARE, dpi=style.DPI, layout="constrained")
    ax = fig.add_subplot()
    positive = relative > 0
    ax.plot(
        relative[positive],
        data.friction_coefficient[positive],
        ".",
        ms=2,
        color="0.55",
        label="measured μ at the fitted v_rel",
        zorder=3,
    )
    low = float(relative[positive].min()) if positive.any() else 1e-12
    high = float(relative[positive].max()) if positive.any() else 1e-6
    grid = np.logspace(np.log10(low / 3.0), np.log10(3.0 * high), 400)
    curve = friction_coefficient(grid, result.config.rig.friction)
    ax.plot(grid, curve, color=style.COLOURS["curve"], lw=1.5, label="fitted μ(v)", zorder=2)
    ax.set_xscale("log")
    ax.set_xlabel(style.V_REL)
    ax.set_ylabel("friction coefficient μ (–)")
    ax.set_title("Fitted friction law over the data", fontsize=style.TITLE_SIZE)
    ax.legend(fontsize=style.LEGEND_SIZE)
    return fig


def _markdown(document: dict[str, Any], figures: list[str]) -> str:
    lines = [
        "# Fit",
        "",
        f"Data: {document['data']['source']} ({document['data']['samples']} samples, "
        f"{document['data']['sample_rate_hz']:g} Hz, sha256 `{document['data']['sha256'][:16]}…`).",
        "",
    ]
    lines += [
        "| parameter | estimate | standard error | unit | start | identifiable |",
        "|---|---|---|---|---|---|",
    ]
    for name, e in document["estimates"].items():
        error = "—" if e["standard_error"] is None else f"{e['standard_error']:.3g}"
        seen = "yes" if e["identifiable"] else "**no**"
        lines.append(f"| {name} | {e['value']:.6g} | {error} | {e['unit']} | {e['start']:.6g} | {seen} |")
    lines.append("")
    if not document["success"]:
        lines.append(f"- **not converged**: {unconverged(document)}.")
    for name, e in document["estimates"].items():
        if e["at_bound"]:
            lines.append(f"- **at a bound**: {bound_warning(name, e)}.")
    for name, why in document["undetermined"].items():
        lines.append(f"- **{name}** is not determined by the data: {why}.")
    for name, ratio in document["misfit"].items():
        lines.append(
            f"- **misfit**: {ratio:.1f} × the noise left in {name}; the model does not explain the data."
        )
    rms = ", ".join(f"{k} {v:.3g}" for k, v in document["residual_rms"].items())
    lines += [
        "",
        f"Residual RMS: {rms}; cost {document['cost']:.4g}; {document['function_evaluations']} evaluations; "
        f"{document['status']}",
        "",
    ]
    lines += [f"![{name}]({name})" for name in figures]
    return "\n".join(lines) + "\n"


def write_outputs(out: Path, data: MeasuredData, result: FitResult, start: str) -> dict[str, Any]:
    """Write every file of FIT_FILES that applies into `out`; fit.json's content."""
    out.mkdir(parents=True, exist_ok=True)
    document = fit_document(result, data, start)
    write_text_atomic(out / "fit.json", json.dumps(document, indent=2) + "\n")
    table = "time_s,band_velocity_m_s\n" + "".join(
        f"{t:.9f},{v:.17g}\n" for t, v in zip(data.time, data.band_velocity, strict=True)
    )
    write_text_atomic(out / "band.csv", table)
    write_text_atomic(out / "config.yaml", yaml.safe_dump(fitted_config(result, data), sort_keys=False))
    run = fitted_run(result, data)
    figures = {
        "fit_time_history.png": _time_history(data, result, run),
        "fit_residuals.png": _residuals(data, result),
    }
    if data.friction_coefficient is not None:
        figures["fit_friction.png"] = _friction(data, result, run)
    assert result.config is not None
    figures["fit_stability.png"] = plot_stability_map(result.config.rig)
    for name, figure in figures.items():
        save_figure(figure, out / name)
    write_text_atomic(out / "fit.md", _markdown(document, list(figures)))
    return document
