"""Integrator cost at equal accuracy: lubrig's Radau IIA vs numbalsoda's LSODA vs scipy's LSODA.

Issue 25's comparison. For each case, an independent tight reference (lubrig_testkit.reference_rig:
the model document's equations written again, scipy LSODA at rtol 1e-12 with steps of at most one
sample period), then a tolerance sweep of three solvers of the same equation with the band linear
between the 1 kHz samples:

* lubrig: core.run.simulate's integrator (the RigIntegrator, compiled Radau IIA, steps spanning
  samples where the band is a line: core/stepper.py), timed on its states alone
  (RigIntegrator.advance_states: x and ẋ at the samples, what the other two return); the columns
  a run also derives at every sample (μ, v_rel) are timed apart and printed beside it;
* lubrig 1/sample: the same with max_step_samples=1 (every step ends on a sample), in the same run;
* numbalsoda: the C++ LSODA of numbalsoda (a benchmark dependency, `make bench-setup`) on a
  right-hand side compiled with numba's cfunc that calls the project's own compiled law kernel
  (core.junction.mu_and_slope), state scaled so that its one scalar atol equals lubrig's
  per-component atol (rtol x 1e-2 N/k and that x omega0);
* scipy LSODA: solve_ivp(method="LSODA") on the law written in plain numpy (no Jacobian, no step
  bound), each run stopped after --scipy-budget s of CPU (a failure).

Each run's error is the largest pointwise displacement difference from the reference relative to
the reference's range; cost is CPU time (time.process_time, best of --repeat; scipy once). A
solver that gives up ("too many steps", numbalsoda's `success` false, scipy's status -1) is
recorded as failed with its message. At each error bound (--bounds) each solver's run at the
loosest rtol from which every completed tighter run is within the bound is taken (a tolerance a
user could choose; stick-slip errors are not monotonic in rtol), and lubrig's cost is given as a
ratio of numbalsoda's and scipy's (below 1: lubrig cheaper).

Run: .venv/bin/python bench/bench_integrator.py [--cases sliding const case1] [--repeat 3]
     [--bounds 1e-4 1e-5 1e-6] [--scipy-budget 5]
     .venv/bin/python bench/bench_integrator.py --case 1 --convention paper --duration 10
"""

from __future__ import annotations

import argparse
import functools
import os
import sys
import tempfile
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from lubrig_testkit.reference_rig import reference_displacement
from scipy.integrate import solve_ivp

from lubrig_ros.core.params import FrictionParameters, RigParameters
from lubrig_ros.core.presets import RunConfig, config_dir, load_case, load_config
from lubrig_ros.core.run import band_samples, integrator_for, simulate

#: The issue's cases: name → (what it is, how to load it).
CASES: dict[str, tuple[str, Callable[[], RunConfig]]] = {
    "sliding": (
        "case 4, physical: slides throughout (20 s)",
        lambda: load_case(4).with_overrides(convention="physical", duration=20.0),
    ),
    "const": (
        "constant band 2e-8 m/s, physical: stick-slip (config/stickslip.yaml, 60 s)",
        lambda: load_config(config_dir() / "stickslip.yaml").with_overrides(convention="physical"),
    ),
    "case1": (
        "case 1, physical: stick-slip on a band cycle (20 s)",
        lambda: load_case(1).with_overrides(convention="physical", duration=20.0),
    ),
}
#: Tolerance sweeps (half decades for the compiled solvers, decades for scipy's Python LSODA). The
#: compiled sweeps start at 1e-4: where a solver is within a bound at a looser tolerance than
#: 1e-6 (lubrig sliding: 1.6e-6 of the range at rtol 1e-6), the bound's cost is that tolerance's.
LUBRIG_RTOLS = tuple(10.0 ** (-e / 2) for e in range(8, 25))  # 1e-4 … 1e-12
NUMBALSODA_RTOLS = tuple(10.0 ** (-e / 2) for e in range(8, 27))  # 1e-4 … 1e-13
SCIPY_RTOLS = tuple(10.0**-e for e in range(6, 13))  # 1e-6 … 1e-12


@dataclass
class Result:
    solver: str
    rtol: float
    cpu: float  # s, best of the repeats (nan when failed)
    error: float  # max |x − x_ref| / range (nan when failed)
    failure: str = ""
    steps: int = 0  # lubrig: accepted Radau steps (0: not known)


# ---------------------------------------------------------------------------------------- solvers


def cpu_best(run: Callable[[], tuple[np.ndarray, int]], repeat: int) -> tuple[np.ndarray, int, float]:
    """The last result and the best CPU time of `repeat` calls."""
    best = np.inf
    x, steps = np.empty(0), 0
    for _ in range(repeat):
        started = time.process_time()
        x, steps = run()
        best = min(best, time.process_time() - started)
    return x, steps, best


def lubrig_run(config: RunConfig, rtol: float, span: int | None = None) -> tuple[np.ndarray, int]:
    """core.run.simulate's integrator over the band samples, states only; x and substeps.

    span: max_step_samples (None: the integrator's default).
    """
    config = config.with_overrides(rtol=rtol)
    integrator = integrator_for(config)
    if span is not None:
        integrator = replace(integrator, max_step_samples=span)
    first = integrator.current().displacement
    x, _ = integrator.advance_states(band_samples(config, 0, config.samples))
    return np.concatenate([first, x]), integrator.substeps


def derived_columns_cpu(config: RunConfig, repeat: int) -> float:
    """CPU s of what advance adds to advance_states at the default rtol: μ, v_rel, the Trajectory."""
    band = band_samples(config, 0, config.samples)
    full = states = np.inf
    for _ in range(repeat):
        started = time.process_time()
        integrator_for(config).advance(band)
        full = min(full, time.process_time() - started)
        started = time.process_time()
        integrator_for(config).advance_states(band)
        states = min(states, time.process_time() - started)
    return full - states


#: Layout of the numbalsoda right-hand side's data array (after it: the law's parameters, then
#: the band samples).
_HEAD = ("mass", "damping", "stiffness", "gamma", "normal_force", "omega0", "length", "sample_rate")
_N_HEAD = len(_HEAD) + 2  # + law parameter count, band sample count


@functools.cache
def _numbalsoda_rhs() -> tuple[int, Callable[..., tuple[float, float]]]:
    """The cfunc right-hand side (its address) and the law kernel it calls, compiled once."""
    import numba as nb
    from numbalsoda import lsoda_sig

    from lubrig_ros.core.junction import mu_and_slope

    law = mu_and_slope.dispatcher  # the project's compiled kernel, callable from a cfunc

    @nb.cfunc(lsoda_sig)
    def rhs(t, u, du, data):  # type: ignore[no-untyped-def]
        head = nb.carray(data, _N_HEAD)
        n_law = int(head[8])
        n_band = int(head[9])
        d = nb.carray(data, _N_HEAD + n_law + n_band)
        m, c, k, gamma, normal, omega0, length, rate = (
            d[0], d[1], d[2], d[3], d[4], d[5], d[6], d[7],
        )  # fmt: skip
        # band linear between samples (as np.interp over k / rate)
        s = t * rate
        i = min(max(int(s), 0), n_band - 2)
        band = d[_N_HEAD + n_law :]
        vb = band[i] + (s - i) * (band[i + 1] - band[i])
        x = u[0] * length
        xdot = u[1] * length * omega0
        mu, _ = law(vb - gamma * xdot, d[_N_HEAD : _N_HEAD + n_law])
        du[0] = omega0 * u[1]
        du[1] = (normal * mu - c * xdot - k * x) / m / (length * omega0)

    return rhs.address, law


def numbalsoda_data(rig: RigParameters, law_params: np.ndarray, band: np.ndarray, rate: float) -> np.ndarray:
    length = 1e-2 * rig.friction.normal_force / rig.stiffness  # lubrig's atol is rtol × this
    head = [
        rig.mass, rig.damping, rig.stiffness, rig.velocity_factor, rig.friction.normal_force,
        rig.angular_frequency, length, rate, float(law_params.size), float(band.size),
    ]  # fmt: skip
    return np.ascontiguousarray(np.concatenate([head, law_params, band]), dtype=np.float64)


class CapturedStderr:
    """fd 2 to a temporary file while open (numbalsoda's C++ LSODA writes its reasons there)."""

    def __enter__(self) -> CapturedStderr:
        sys.stderr.flush()
        self._file = tempfile.TemporaryFile(mode="w+b")
        self._saved = os.dup(2)
        os.dup2(self._file.fileno(), 2)
        self.text = ""
        return self

    def __exit__(self, *exc: object) -> None:
        os.dup2(self._saved, 2)
        os.close(self._saved)
        self._file.seek(0)
        self.text = self._file.read().decode(errors="replace")
        self._file.close()


class Numbalsoda:
    """numbalsoda's lsoda on the cfunc right-hand side; x in m from the scaled state."""

    def __init__(self, config: RunConfig, time_s: np.ndarray, band: np.ndarray, x0: float) -> None:
        from numbalsoda import lsoda

        from lubrig_ros.core.friction_laws import law_for

        self._lsoda = lsoda
        self._address, _ = _numbalsoda_rhs()
        rig = config.rig
        params = law_for(rig.friction).pack(rig.friction)
        self.data = numbalsoda_data(rig, params, band, config.sample_rate)
        self._length = 1e-2 * rig.friction.normal_force / rig.stiffness
        self._u0 = np.array([x0 / self._length, 0.0])
        self._time = np.ascontiguousarray(time_s, dtype=np.float64)

    def run(self, rtol: float) -> tuple[np.ndarray, bool]:
        usol, success = self._lsoda(self._address, self._u0, self._time, data=self.data, rtol=rtol, atol=rtol)
        return usol[:, 0] * self._length, bool(success)


def numpy_friction(v: float, p: FrictionParameters) -> float:
    """The friction law written directly in numpy (what a user without our kernel would write)."""
    sign = np.sign(v)
    v = np.abs(v)
    if v == 0.0:
        return 0.0
    u = p.critical_velocity / v
    lifetime = p.thermal_break_time * (-np.expm1(-u))
    ratio = 1.0 - u * np.exp(-u) / (-np.expm1(-u)) if u > 1e-3 else u / 2.0 - u * u / 12.0
    stretch = v * p.thermal_break_time * ratio
    tau = p.reference_activation_time * (v / p.reference_velocity) ** p.activation_exponent
    phi = lifetime / (lifetime + tau)
    eta = p.reference_viscosity * (v / p.reference_velocity) ** p.shear_thinning_exponent
    sigma = (
        p.shear_modulus * phi * stretch / p.interface_thickness
        + (1 - phi) * eta * v / p.interpenetration_thickness
    )
    return float(sign * p.contact_area / p.normal_force * sigma)


class OverBudgetError(Exception):
    """A scipy run used more CPU time than it is allowed."""


def scipy_lsoda(  # type: ignore[no-untyped-def]
    rig: RigParameters, t_s: np.ndarray, v_s: np.ndarray, x0: float, rtol: float, budget: float
):
    """scipy solve_ivp(LSODA) on the numpy law, lubrig's atol; (x, success, message).

    Stopped after `budget` s of CPU time (reported as a failure): without a step bound its step
    control can crawl through stick phases for many minutes (docs/integrator.md, Accuracy).
    """
    m, c, k, gamma = rig.mass, rig.damping, rig.stiffness, rig.velocity_factor
    normal = rig.friction.normal_force
    p = rig.friction
    deadline = time.process_time() + budget

    def rhs(t, y):  # type: ignore[no-untyped-def]
        if time.process_time() > deadline:
            raise OverBudgetError(f"stopped after {budget:g} s of CPU at t = {t:.6g} s")
        vb = np.interp(t, t_s, v_s)
        return [y[1], (normal * numpy_friction(vb - gamma * y[1], p) - c * y[1] - k * y[0]) / m]

    scale = 1e-2 * normal / k
    atol = [rtol * scale, rtol * scale * rig.angular_frequency]
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            sol = solve_ivp(
                rhs, (t_s[0], t_s[-1]), [x0, 0.0], method="LSODA", t_eval=t_s, rtol=rtol, atol=atol
            )
    except OverBudgetError as exc:
        return np.empty(0), False, str(exc)
    message = str(sol.message)
    if caught and not sol.success:
        message += f" ({caught[0].message})"
    return sol.y[0], bool(sol.success), message


# ------------------------------------------------------------------------------------------ sweep


def error_of(x: np.ndarray, reference: np.ndarray) -> float:
    if x.shape != reference.shape or not np.all(np.isfinite(x)):
        return float("nan")
    return float(np.max(np.abs(x - reference)) / np.ptp(reference))


def sweep_case(config: RunConfig, repeat: int, scipy_budget: float, with_numbalsoda: bool) -> list[Result]:
    first = simulate(config)  # also compiles / loads lubrig's kernel
    t_s, v_s, x0 = first.time, first.band_velocity, float(first.displacement[0])
    started = time.process_time()
    reference = reference_displacement(t_s, v_s, x0, config.rig.velocity_factor)
    elapsed = time.process_time() - started
    print(f"  reference (testkit: scipy LSODA rtol 1e-12, steps <= 1 sample): {elapsed:.1f} s CPU")
    results = []
    for name, span in (("lubrig", None), ("lubrig 1/sample", 1)):
        for rtol in LUBRIG_RTOLS:
            x, steps, cpu = cpu_best(lambda r=rtol, s=span: lubrig_run(config, r, s), repeat)
            results.append(Result(name, rtol, cpu, error_of(x, reference), steps=steps))
    derived = derived_columns_cpu(config, repeat)
    print(
        f"  lubrig's μ, v_rel and Trajectory at every sample (advance − advance_states, default rtol): "
        f"{derived * 1e3:.2f} ms CPU, not in the figures below"
    )
    if with_numbalsoda:
        results += numbalsoda_sweep(config, t_s, v_s, x0, reference, repeat)
    if scipy_budget > 0:
        for rtol in SCIPY_RTOLS:
            started = time.process_time()
            x, ok, message = scipy_lsoda(config.rig, t_s, v_s, x0, rtol, scipy_budget)
            cpu = time.process_time() - started
            results.append(
                Result("scipy LSODA", rtol, cpu, error_of(x, reference))
                if ok
                else Result("scipy LSODA", rtol, cpu, float("nan"), message)
            )
    return results


def numbalsoda_sweep(
    config: RunConfig, t_s: np.ndarray, v_s: np.ndarray, x0: float, reference: np.ndarray, repeat: int
) -> list[Result]:
    solver = Numbalsoda(config, t_s, v_s, x0)
    solver.run(1e-6)  # compiles numbalsoda's lsoda wrapper for these types
    results = []
    for rtol in NUMBALSODA_RTOLS:
        best, x, ok, reason = np.inf, np.empty(0), True, ""
        for _ in range(repeat):
            with CapturedStderr() as err:
                started = time.process_time()
                x, ok = solver.run(rtol)
                best = min(best, time.process_time() - started)
            if not ok:
                lines = [line.strip() for line in err.text.splitlines() if line.strip()]
                reason = lines[0] if lines else "success false, no message"
                break
        if ok:
            results.append(Result("numbalsoda", rtol, best, error_of(x, reference)))
        else:
            results.append(Result("numbalsoda", rtol, best, float("nan"), reason))
    return results


def matched(results: list[Result], solver: str, bound: float) -> Result | None:
    """The loosest rtol whose run and every completed tighter run are within the bound.

    (Not simply the cheapest run within it: stick-slip errors are not monotonic in rtol, and a
    lucky loose run is no tolerance a user could choose.) A failed run breaks no chain: it is
    counted apart.
    """
    runs = sorted((r for r in results if r.solver == solver and not r.failure), key=lambda r: r.rtol)
    chosen = None
    for r in runs:  # tightest first
        if not r.error <= bound:
            break
        chosen = r
    return chosen


def print_results(results: list[Result]) -> None:
    print(f"  {'solver':15s} {'rtol':>8s} {'CPU ms':>9s}  {'error/range':11s} steps (lubrig)")
    for r in results:
        head = f"  {r.solver:15s} {r.rtol:8.1e} {r.cpu * 1e3:9.2f}"
        if r.failure:
            print(f"{head}  FAILED: {r.failure}")
        else:
            print(f"{head}  {r.error:<11.2g} {r.steps or ''}".rstrip())


def summarize(name: str, results: list[Result], bounds: list[float]) -> list[str]:
    rows = []
    solvers = list(dict.fromkeys(r.solver for r in results))
    failed = {s: sum(1 for r in results if r.solver == s and r.failure) for s in solvers}
    runs = {s: sum(1 for r in results if r.solver == s) for s in solvers}
    for bound in bounds:
        best = {s: matched(results, s, bound) for s in solvers}
        cells = []
        for s in solvers:
            b = best[s]
            cells.append(f"{s} {b.cpu * 1e3:.1f} ms (rtol {b.rtol:.1e})" if b else f"{s} none within")
        ratios = []
        ours = best.get("lubrig")
        for s in solvers:
            if s != "lubrig" and ours and best[s]:
                ratios.append(f"lubrig/{s} = {ours.cpu / best[s].cpu:.2f}")  # type: ignore[union-attr]
        tail = "  ->  " + ", ".join(ratios) if ratios else ""
        rows.append(f"{name:8s} error <= {bound:.0e}: " + "; ".join(cells) + tail)
    rows.append(f"{name:8s} failures: " + ", ".join(f"{s} {failed[s]} of {runs[s]}" for s in solvers))
    return rows


def load_average() -> str:
    with open("/proc/loadavg") as f:
        return f.read().strip()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", choices=sorted(CASES), default=list(CASES))
    parser.add_argument("--case", type=int, help="instead of --cases: this study case ...")
    parser.add_argument("--convention", default="physical", help="... in this convention (with --case)")
    parser.add_argument("--duration", type=float, help="rig time, s (default: each case's)")
    parser.add_argument("--repeat", type=int, default=3, help="CPU time: best of this many runs")
    parser.add_argument("--bounds", type=float, nargs="+", default=[1e-4, 1e-5, 1e-6])
    parser.add_argument(
        "--scipy-budget", type=float, default=5.0, help="CPU s allowed per scipy run (0: skip scipy)"
    )
    args = parser.parse_args()

    try:
        import numbalsoda  # noqa: F401

        with_numbalsoda = True
    except ImportError:
        print("numbalsoda is not installed (make bench-setup): compared with scipy LSODA only")
        with_numbalsoda = False
    if args.case is not None:
        chosen = {
            f"case{args.case}-{args.convention}": (
                f"case {args.case}, {args.convention} (20 s)",
                lambda: load_case(args.case).with_overrides(convention=args.convention, duration=20.0),
            )
        }
    else:
        chosen = {name: CASES[name] for name in args.cases}
    print(f"load average before: {load_average()}")
    summary = []
    for name, (label, load) in chosen.items():
        config = load()
        if args.duration:
            config = config.with_overrides(duration=args.duration)
        print(f"{name}: {label}; {config.duration:g} s of rig time at {config.sample_rate:g} Hz")
        results = sweep_case(config, args.repeat, args.scipy_budget, with_numbalsoda)
        print_results(results)
        summary += summarize(name, results, args.bounds)
    print(
        "at equal accuracy (per bound, the loosest rtol from which every completed run is within it;"
        f" CPU, best of {args.repeat} for the compiled solvers):"
    )
    for row in summary:
        print("  " + row)
    print(f"load average after: {load_average()}")


if __name__ == "__main__":
    main()
