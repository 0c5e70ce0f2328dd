"""`lubrig analyze DIR` on a synthetic directory in the `lubrig simulate` format."""

import json

import numpy as np
import pytest

from lubrig_ros.cli.main import main

HEADER = "time_s,displacement_m,velocity_m_s,friction_coefficient,band_velocity_m_s,relative_velocity_m_s"


def write_run(directory, rate=1000.0, seconds=6.0, fundamental=10 / 3, extra=None):
    """Write timeseries.csv and summary.json like `lubrig simulate` does, from a known signal."""
    directory.mkdir(parents=True, exist_ok=True)
    t = np.arange(int(seconds * rate)) / rate
    x = 2e-6 + 1e-7 * np.sin(2 * np.pi * 10.0 * t) + 4e-8 * np.sin(2 * np.pi * 3 * 10.0 * t)
    v = np.gradient(x, t)
    band = np.full_like(t, 1e-6)
    table = np.column_stack((t, x, v, np.full_like(t, 0.1), band, band - v))
    np.savetxt(directory / "timeseries.csv", table, delimiter=",", header=HEADER, comments="")
    summary = {
        "convention": "physical",
        "sample_rate_hz": rate,
        "band_fundamental_hz": fundamental,
        "natural_frequency_hz": 10.0,
        "case": "synthetic",
    }
    summary.update(extra or {})
    (directory / "summary.json").write_text(json.dumps(summary))
    return directory


def test_analyze_writes_figure_and_summary(tmp_path, capsys):
    run = write_run(tmp_path / "run")
    assert main(["analyze", str(run), "--start", "0.5"]) == 0
    png = run / "wavelet.png"
    assert png.is_file() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    summary = json.loads((run / "summary.json").read_text())
    assert summary["case"] == "synthetic" and summary["convention"] == "physical"
    section = summary["wavelet"]
    dom = section["dominant_frequencies"]
    assert abs(dom[0]["frequency_hz"] / 10 - 1) < 0.03
    assert dom[0]["label"] == "3rd harmonic of 3.33 Hz"
    assert abs(dom[1]["frequency_hz"] / 30 - 1) < 0.03 and "9th harmonic" in dom[1]["label"]
    assert dom[0]["power"] >= dom[1]["power"]
    assert set(dom[0]) >= {"frequency_hz", "power", "label"}
    assert abs(section["global_peak"]["frequency_hz"] / 10 - 1) < 0.06
    assert section["start_s"] == 0.5
    assert "3rd harmonic" in capsys.readouterr().out


def test_null_fundamental(tmp_path):
    run = write_run(tmp_path / "run", fundamental=None)
    assert main(["analyze", str(run)]) == 0
    dom = json.loads((run / "summary.json").read_text())["wavelet"]["dominant_frequencies"]
    assert dom[0]["label"] == "10 Hz"


@pytest.mark.parametrize("what", ["dir", "csv", "summary"])
def test_missing_input_is_one_line_exit_2(tmp_path, capsys, what):
    run = write_run(tmp_path / "run")
    if what == "dir":
        run = tmp_path / "nope"
    else:
        (run / ("timeseries.csv" if what == "csv" else "summary.json")).unlink()
    assert main(["analyze", str(run)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("lubrig analyze: error:") and "\n" not in err
    assert ("no such directory" in err) if what == "dir" else ("missing" in err)


@pytest.mark.parametrize(
    "args, match",
    [
        (["--start", "5.99"], "samples after --start"),
        (["--start", "-1"], "--start"),
        (["--dj", "0"], "--dj"),
        (["--fmin", "50", "--fmax", "20"], "--fmin"),
    ],
)
def test_bad_options(tmp_path, capsys, args, match):
    run = write_run(tmp_path / "run")
    assert main(["analyze", str(run), *args]) == 2
    assert match in capsys.readouterr().err


def test_constant_displacement_is_clear_error(tmp_path, capsys):
    run = write_run(tmp_path / "run")
    lines = (run / "timeseries.csv").read_text().splitlines()
    rows = [line.split(",") for line in lines[1:]]
    for row in rows:
        row[1] = "1e-6"
    (run / "timeseries.csv").write_text("\n".join([lines[0]] + [",".join(r) for r in rows]))
    assert main(["analyze", str(run)]) == 2
    assert "constant" in capsys.readouterr().err


def write_tone(directory, seconds, rate=1000.0):
    """A long 10 Hz tone in the simulate format (only time and displacement vary)."""
    directory.mkdir(parents=True, exist_ok=True)
    t = np.arange(int(seconds * rate)) / rate
    x = 1e-7 * np.sin(2 * np.pi * 10.0 * t)
    zeros = np.zeros_like(t)
    table = np.column_stack((t, x, zeros, zeros, zeros, zeros))
    np.savetxt(directory / "timeseries.csv", table, delimiter=",", header=HEADER, comments="", fmt="%.9g")
    summary = {"sample_rate_hz": rate, "band_fundamental_hz": None, "natural_frequency_hz": 10.0}
    (directory / "summary.json").write_text(json.dumps(summary))
    return directory


@pytest.fixture(scope="module")
def long_tone(tmp_path_factory):
    return write_tone(tmp_path_factory.mktemp("long") / "run", seconds=600.0)


def _peak_bytes(call):
    import tracemalloc

    tracemalloc.start()
    try:
        assert call() == 0
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.slow
def test_long_record_default_fmax_is_decimated_to_the_cap(long_tone):
    """600 s at 1 kHz: the default fmax no longer blocks the cap (was ~190 scales × 6e5 samples)."""
    from lubrig_ros.cli.analyze import MAX_POWER_POINTS

    peak = _peak_bytes(lambda: main(["analyze", str(long_tone)]))
    section = json.loads((long_tone / "summary.json").read_text())["wavelet"]
    n_scales = round(np.log2(section["fmax_hz"] / section["fmin_hz"]) / section["dj"]) + 1
    assert section["decimation"] > 1 and "decimated by" in section["decimation_note"]
    assert np.ceil(600_000 / section["decimation"]) * n_scales <= MAX_POWER_POINTS * 1.01
    assert section["fmax_hz"] <= 0.4 * 1000.0 / section["decimation"] * 1.0001
    assert abs(section["dominant_frequencies"][0]["frequency_hz"] / 10 - 1) < 0.03
    assert peak < 40 * MAX_POWER_POINTS  # a few copies of the capped power, not several GB
    # an explicit --fmax above the decimated band is honoured: the record is shortened instead
    assert main(["analyze", str(long_tone), "--fmax", "300"]) == 0
    section = json.loads((long_tone / "summary.json").read_text())["wavelet"]
    assert section["decimation"] == 1 and "only the last" in section["decimation_note"]
    assert abs(section["fmax_hz"] / 300 - 1) < 0.1 and section["analysed_from_s"] > 0
    assert abs(section["dominant_frequencies"][0]["frequency_hz"] / 10 - 1) < 0.03
