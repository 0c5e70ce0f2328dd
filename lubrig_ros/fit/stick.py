"""Stick phases of a measured record, and the shooting grid around its slips.

While the mass sticks, it moves with the band: ẋ = v_band / γ, and v_rel stays inside the friction
law's first zone (|v_rel| below the peak's 4.08e-12 m/s for the study's law). Two things follow for
multiple shooting on stick-slip records:

* A segment that starts in a stick phase cannot take its start velocity from the data: the
  smoothed slope of 1 %-noise data is off by ~1e-7 m/s, five decades more than the stick allows,
  and a start past the peak slips at once. Such a segment starts stuck instead: ẋ_i = v_band / γ
  (v_rel = 0, from which the integration settles onto the stick branch within nanoseconds, or slips
  if k x_i exceeds N μ_peak), and ẋ_i is no free variable of the fit (ShootingProblem.tied).
* A slip must lie well inside one segment: its time moves with the parameters (the threshold
  x = N μ_peak / k), and a segment whose model slips past its end no longer sees the slip in its
  Jacobian. So no boundary lies between the middles of the two stick phases around a slip; the
  middles themselves are boundaries (a start there is stuck, in data and model alike).

A sample is stuck when, over a window around it, the measured x minus the band's travel
∫ v_band / γ dt is a constant to within the noise (mean square of the deviations from their mean
below STICK_TOLERANCE standard deviations of that statistic above σ_x²). The window's half-width
is STICK_WINDOW_S, longer where the band is slow: the band must travel STICK_TRAVEL σ_x across it,
so that a mass standing still (sliding with ẋ ≈ 0, as at the start of case 1 in the physical
convention) fails the test (a ramp of 10 σ has a mean square deviation of 8 σ²).
"""

from __future__ import annotations

import itertools
import math

import numpy as np

#: Half-width of the window of the stick test, s (half a period of the study's 10 Hz rig).
STICK_WINDOW_S = 0.05
#: The band's travel over the window, in σ_x: a stuck mass must be told from one standing still.
STICK_TRAVEL = 10.0
#: Longest half-width, s: a band too slow for this to see STICK_TRAVEL σ gives no stick phases.
MAX_STICK_WINDOW_S = 1.0
#: The stick test's threshold, in standard deviations of the windowed mean square (χ² statistic).
STICK_TOLERANCE = 4.0
#: Only a slip (the gap between two stick phases) of at most this many segments gets the layout.
MAX_SLIP_SEGMENTS = 4
#: A stick phase shorter than this (s) is not used to place boundaries.
MIN_STICK_S = 0.2
#: A step of the measured μ from one sample to the next above this many σ_μ, and above
#: TRANSITION_SHARE of μ's range, is a stick–slip transition (a 10 Hz oscillation over the whole
#: range moves μ by 3 % of it per millisecond; case 1's transitions by 40–60 %).
TRANSITION_JUMP = 10.0
TRANSITION_SHARE = 0.1
#: μ samples left out either side of a transition: the model's transition may lie this far from
#: the data's at the solution without a left-in sample between them.
TRANSITION_MARGIN = 3


def stuck_samples(
    displacement: np.ndarray, band: np.ndarray, sample_rate: float, gamma: float, sigma: float
) -> np.ndarray:
    """Per sample, True where the measured x moves with the band (ẋ = v_band / γ) around it."""
    n = displacement.size
    half = _half_window(band, sample_rate, gamma, sigma)
    if half is None or n < 2 * half + 1:
        return np.zeros(n, dtype=bool)
    deviation = (displacement - _travel(band, sample_rate, gamma)) / sigma
    width = 2 * half + 1
    kernel = np.ones(width) / width
    mean = np.convolve(deviation, kernel, mode="valid")
    mean_square = np.convolve(deviation**2, kernel, mode="valid")
    variance = (mean_square - mean**2) * width / (width - 1)
    limit = 1.0 + STICK_TOLERANCE * math.sqrt(2.0 / (width - 1))
    stuck = np.zeros(n, dtype=bool)
    stuck[half : n - half] = variance <= limit
    return stuck


def transition_samples(friction: np.ndarray, sigma: float) -> np.ndarray:
    """Per sample, True within TRANSITION_MARGIN samples of a stick–slip transition of measured μ.

    μ jumps by about 0.16 within microseconds where the mass starts or stops slipping, so the
    residual of a sample next to a transition is a step function of the parameters: it changes
    by the whole jump when the model's transition crosses the sample time, and not at all
    otherwise. Left in, those samples make the cost a staircase in the parameters that move the
    transition (a slip's end moves with ζ), whose steps of (jump / σ_μ)² / 2 (about 900 at 1 %
    noise) pin each model transition to the data's millisecond, and a forward-difference step that
    crosses one gives an entry out of all proportion. Left out, the transitions' times are seen
    through the smooth samples around them.
    """
    step = np.abs(np.diff(friction))
    threshold = max(TRANSITION_JUMP * sigma, TRANSITION_SHARE * float(np.ptp(friction)))
    near = np.zeros(friction.size, dtype=bool)
    for k in np.flatnonzero(step > threshold):  # the jump lies between samples k and k + 1
        near[max(0, k + 1 - TRANSITION_MARGIN) : k + 1 + TRANSITION_MARGIN] = True
    return near


def _half_window(band: np.ndarray, sample_rate: float, gamma: float, sigma: float) -> int | None:
    """Half-width of the stick test's window in samples; None when the band is too slow for one."""
    speed = float(np.mean(np.abs(band))) / abs(gamma)  # how fast a stuck mass moves, typically
    if speed == 0.0:
        return None  # a band at rest: sticking looks like standing still
    # the window must see the band travel STICK_TRAVEL σ, or a mass standing still would pass
    travel = math.ceil(0.5 * STICK_TRAVEL * sigma / speed * sample_rate)
    half = max(2, round(STICK_WINDOW_S * sample_rate), travel)
    return None if half > MAX_STICK_WINDOW_S * sample_rate else half


def _travel(band: np.ndarray, sample_rate: float, gamma: float) -> np.ndarray:
    """∫ v_band / γ dt from the record's start at every sample (trapezoids: the band is linear)."""
    steps = 0.5 * (band[1:] + band[:-1]) / sample_rate
    return np.concatenate([[0.0], np.cumsum(steps)]) / gamma


def stuck_positions(
    displacement: np.ndarray,
    band: np.ndarray,
    sample_rate: float,
    gamma: float,
    sigma: float,
    stuck: np.ndarray,
    samples: np.ndarray,
) -> np.ndarray:
    """The displacement at each of `samples` (stuck ones) from the stick line through the data.

    The mass moves with the band there, so x = c + ∫ v_band / γ dt with one constant c: its mean
    over the stuck samples of the window (up to the stick test's half-width either side) is
    σ_x / √(samples) precise, where a smoothing filter of the noisy x is not.
    """
    travel = _travel(band, sample_rate, gamma)
    half = _half_window(band, sample_rate, gamma, sigma) or 2
    positions = np.empty(samples.size)
    for k, i in enumerate(samples):
        low, high = int(i), int(i)
        while low > max(0, i - half) and stuck[low - 1]:
            low -= 1
        while high < min(stuck.size - 1, i + half) and stuck[high + 1]:
            high += 1
        window = slice(low, high + 1)
        positions[k] = travel[i] + float(np.mean(displacement[window] - travel[window]))
    return positions


def _runs(flags: np.ndarray, minimum: int) -> list[tuple[int, int]]:
    """(first, last) sample of every run of True at least `minimum` samples long."""
    padded = np.concatenate([[False], flags, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(padded))
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2], strict=True) if b - a >= minimum]


def segment_starts(samples: int, segment_samples: int, stuck: np.ndarray, sample_rate: float) -> np.ndarray:
    """Start samples of the shooting segments: the regular grid, with no boundary near a slip.

    Between the middles of two stick phases that enclose a slip (a gap of at most
    MAX_SLIP_SEGMENTS segments: a long phase of sliding keeps its grid), the regular boundaries are
    dropped and the two middles are boundaries; a regular boundary closer than half a segment to
    such a middle is dropped too. Without stick phases this is the regular grid.
    """
    count = max(1, (samples - 1) // segment_samples)
    grid = [k * segment_samples for k in range(count)]
    runs = _runs(stuck, max(2, round(MIN_STICK_S * sample_rate)))
    protected = [
        ((a0 + b0) // 2, (a1 + b1) // 2)
        for (a0, b0), (a1, b1) in itertools.pairwise(runs)
        if a1 - b0 <= MAX_SLIP_SEGMENTS * segment_samples
    ]
    if not protected:
        return np.array(grid, dtype=np.int64)
    middles = sorted({m for pair in protected for m in pair})
    kept = [
        k
        for k in grid
        if k == 0
        or (
            not any(a < k < b for a, b in protected)
            and all(abs(k - m) >= segment_samples // 2 for m in middles)
        )
    ]
    starts = sorted({*kept, *(m for m in middles if 0 < m < samples - 1)})
    return np.array(starts, dtype=np.int64)
