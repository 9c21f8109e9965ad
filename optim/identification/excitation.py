"""What excited a record: a free decay (a knock, a move's end) or a sweep (a resonance test), told from how its
dominant frequency moves with time.

The record is cut into segments of SEGMENT_S; each segment whose spectral peak stands SEGMENT_SNR above the
segment's own median bin (a tone, not noise) gives the frequency of that peak. A free vibration rings at its modes: the
peak stays at one of them while the power decays. A swept excitation (Klipper's TEST_RESONANCES: a chirp from
5 to 135 Hz at 1 Hz/s) moves the peak with the sweep: the peaks' frequency rises (or falls) with time, with a rank
correlation above SWEEP_CORRELATION over at least MIN_SEGMENTS live segments (their peaks' running median over
RIDGE_MEDIAN segments: a segment whose peak is noise, where the sweep excites little, drops out), through at least
MIN_DISTINCT frequencies (a decay of several modes steps from one mode's to another's: few distinct peaks).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy.signal import medfilt
from scipy.stats import spearmanr, theilslopes

__all__ = ["Excitation", "excitation_of", "sweep_band"]

Excitation = Literal["free_decay", "sweep"]
SEGMENT_S = 0.5
MIN_SEGMENTS = 8
SEGMENT_SNR = 30.0  # a live segment's peak bin over its median bin (15 dB: white noise's peak of ~500 bins stays
# under 10, e^(-30) the chance a bin of it exceeds 30 x its mean)
SWEEP_CORRELATION = (
    0.7  # (a run of segments where a harmonic of the square wave rings a higher mode stays off the ridge)
)
MIN_DISTINCT = 6  # distinct peak frequencies a sweep passes through (a decay shows at most its modes')
LOW_HZ = 2.0  # peaks below this (gravity, drift, the sweeping overlay) are not looked at
RIDGE_MEDIAN = 5  # live segments the peaks' running median spans


def _peak_hz(spectra: NDArray[np.float64], frequency: NDArray[np.float64]) -> NDArray[np.float64]:
    """Each row's peak frequency, refined by a parabola through the log of its bin and its neighbours."""
    k = np.clip(np.argmax(spectra, axis=1), 1, spectra.shape[1] - 2)
    rows = np.arange(spectra.shape[0])
    a, b, c = (np.log(np.maximum(spectra[rows, k + d], 1e-300)) for d in (-1, 0, 1))
    curvature = a - 2.0 * b + c
    shift = np.where(curvature < 0.0, 0.5 * (a - c) / np.where(curvature < 0.0, curvature, -1.0), 0.0)
    peak: NDArray[np.float64] = frequency[k] + np.clip(shift, -0.5, 0.5) * (frequency[1] - frequency[0])
    return peak


def _ridge(signals: NDArray[np.float64], sample_rate_hz: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(the live segments' centre times, s, their peaks' running median, Hz): empty where fewer than MIN_SEGMENTS."""
    n = int(SEGMENT_S * sample_rate_hz)
    count = signals.shape[1] // n if n >= 16 else 0
    none = (np.empty(0), np.empty(0))
    if count < MIN_SEGMENTS:
        return none
    segments = signals[:, : count * n].reshape(signals.shape[0], count, n)
    segments = segments - np.mean(segments, axis=2, keepdims=True)
    spectra = np.sum(np.abs(np.fft.rfft(segments * np.hanning(n), axis=2)) ** 2, axis=0)  # (count, bins)
    frequency = np.asarray(np.fft.rfftfreq(n, 1.0 / sample_rate_hz), float)
    spectra[:, frequency < LOW_HZ] = 0.0
    peak = np.max(spectra, axis=1)
    floor = np.median(spectra[:, frequency >= LOW_HZ], axis=1)
    live = peak > SEGMENT_SNR * floor
    if np.count_nonzero(live) < MIN_SEGMENTS:
        return none
    peaks = medfilt(_peak_hz(spectra[live], frequency), RIDGE_MEDIAN)  # a segment's noise peak drops out
    times = np.asarray((np.flatnonzero(live) + 0.5) * n / sample_rate_hz, float)
    return times, np.asarray(peaks, float)


def excitation_of(signals: NDArray[np.float64], sample_rate_hz: float) -> Excitation:
    """``sweep`` where the record's dominant frequency moves monotonically with time (see the module), else
    ``free_decay``."""
    times, peaks = _ridge(signals, sample_rate_hz)
    if np.unique(np.round(peaks * SEGMENT_S)).size < MIN_DISTINCT:  # distinct bins (1 / SEGMENT_S apart)
        return "free_decay"
    rank = spearmanr(times, peaks).statistic
    return "sweep" if np.isfinite(rank) and abs(float(rank)) >= SWEEP_CORRELATION else "free_decay"


def sweep_band(signals: NDArray[np.float64], sample_rate_hz: float) -> tuple[float, float, float] | None:
    """(Hz at the record's first sample, Hz at its last, Hz per s) of a rising sweep, read off its ridge: the
    Theil-Sen line through the live segments' peaks (robust to the segments where a mode or a harmonic outshines the
    sweep), extended to the record's ends; None where the ridge does not rise. Where the noise hides the sweep's
    ends, the live segments do not reach them; the line does."""
    times, peaks = _ridge(signals, sample_rate_hz)
    if times.size < MIN_SEGMENTS:
        return None
    slope, intercept, _, _ = theilslopes(peaks, times)
    if not slope > 0.0:
        return None
    duration = signals.shape[1] / sample_rate_hz
    return float(intercept), float(intercept + slope * duration), float(slope)
