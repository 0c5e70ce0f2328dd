"""Start-up weight (issue 12): what a node process imports before it can take part in a run.

A rig run starts five Python processes on 2 cores at once, so every heavy import is paid in the
start-up of the run: numba (about 1 s of CPU, through the friction-law modules) and scipy.signal
(about 1 s, through find_peaks) were imported by every node when the topic contract pulled in the
default law's module. Each case runs a fresh interpreter and checks sys.modules.
"""

from __future__ import annotations

import subprocess
import sys

import pytest

from lubrig_ros.core.friction_laws import BUILTIN_LAWS, law_named, law_parameters

# module -> packages it must not import (the plant needs numba: it integrates)
LIGHT = {
    "lubrig_ros.app.interface.contract": ("numba", "scipy"),
    "lubrig_ros.core.presets": ("numba", "scipy"),
    "lubrig_ros.nodes.belt_drive": ("numba", "scipy"),
    "lubrig_ros.nodes.recorder": ("numba", "scipy"),
    "lubrig_ros.nodes.analysis": ("numba", "scipy.signal"),
    "lubrig_ros.core.online": ("numba", "scipy.signal"),
    "lubrig_ros.cli.rig": ("numba", "scipy"),
    "lubrig_ros.core.stribeck": ("numba", "scipy"),  # a law module: its kernel compiles when used
}


@pytest.mark.parametrize("module", sorted(LIGHT))
def test_module_does_not_import_heavy_packages(module: str) -> None:
    code = f"import sys, {module}; print(' '.join(p for p in {LIGHT[module]!r} if p in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "", f"{module} imports {out.stdout.strip()}"


@pytest.mark.parametrize("name", sorted(BUILTIN_LAWS))
def test_law_parameters_are_the_registered_laws(name: str) -> None:
    """The light lookup (BUILTIN_PARAMETERS, else the law's module) gives the dataclass it registers."""
    assert law_parameters(name) is law_named(name).parameters


def test_law_parameters_names_the_valid_laws_for_an_unknown_one() -> None:
    from lubrig_ros.core.params import ParameterError

    with pytest.raises(ParameterError, match="'coulomb' is not valid; expected one of"):
        law_parameters("coulomb")


def test_local_maxima_are_find_peaks() -> None:
    """core.wavelet_components.local_maxima (no scipy.signal import) finds what scipy.signal.find_peaks finds.

    Random arrays of 0-40 values, half of them small integers so that flat tops (plateaus, of
    even and odd length, at the ends too) are common.
    """
    import numpy as np
    from scipy.signal import find_peaks

    from lubrig_ros.core.wavelet_components import local_maxima

    rng = np.random.default_rng(12)
    for trial in range(5000):
        n = int(rng.integers(0, 41))
        x = rng.integers(0, 4, n).astype(float) if trial % 2 else rng.random(n)
        assert np.array_equal(local_maxima(x), find_peaks(x)[0]), x
    assert local_maxima(np.array([0.0, 1.0, 1.0, 1.0, 1.0, 0.0])).tolist() == [2]


FIRST_UPDATE = """
import sys
import numpy as np
import lubrig_ros.nodes.analysis  # what the node has imported before it runs
from lubrig_ros.app.analysis.session import AnalysisSession
from lubrig_ros.core.presets import load_case
session = AnalysisSession(load_case(1))
before = set(sys.modules)
t = np.arange(5000) / 1000.0
x = 1e-9 * np.sin(2 * np.pi * 9.5 * t)
session.samples_input(x, x, np.full_like(t, 1e-7), np.full_like(t, 1e-7), float(t[-1]))
assert session.tick().skipped is None
print(" ".join(sorted(set(sys.modules) - before)))
"""


def test_the_first_analysis_update_imports_nothing() -> None:
    """The analysis session loads the law's compiled module and scipy.optimize when it is built.

    Imported inside the node's first update (a timer callback) instead, a SIGINT interrupting the
    import killed the node with exit 1: numpy turns a KeyboardInterrupt inside its import into an
    ImportError ("PyCapsule_Import could not import module datetime").
    """
    out = subprocess.run([sys.executable, "-c", FIRST_UPDATE], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "", f"imported in the first update: {out.stdout.strip()[:500]}"
