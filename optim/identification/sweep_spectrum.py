"""A resonance test's measured spectrum as optim.identification.sweep_fit compares its model with: Klipper's Welch PSD
per axis (calc_freq_response: segments of 2^bitlen(int(fs WINDOW_S - 1)) samples, half overlap, each segment's mean
removed, a symmetric Kaiser(6) window, density scaling), computed from a raw record or read from Klipper's resonance
CSV, and what the fit's covariance needs of the window.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from optim.identification.resonance_test import ResonanceTest

__all__ = ["MeasuredSpectrum", "csv_spectrum", "record_spectrum", "welch_segments", "window_correlation"]

Array = NDArray[np.float64]
KAISER_BETA = 6.0
CORRELATED_BINS = 8  # the window's bin correlation |c_m| kept (|c_8| < 1e-6 for Kaiser(6))
WINDOW_S = 0.5  # Klipper's WINDOW_T_SEC
CSV_SEGMENT = 2048  # Klipper's segment for 2048-4095 Hz (an ADXL345's 3200 Hz)
PRINTED_HZ = 0.1  # the CSV's frequency column (%.1f): a uniform rounding, std 0.1 / sqrt(12)
LOW_HZ = 2.0
FIT_MARGIN_BINS = 3
MAX_FIT_HZ = 200.0  # Klipper's MAX_FREQ: its CSV's last row


@dataclass(frozen=True)
class MeasuredSpectrum:
    """A Welch PSD per axis and how it was made: what the fit compares its model with."""

    frequency_hz: Array  # the bins fitted (multiples of rate / segment)
    psd: Array  # (axes, bins), (signal units)^2 / Hz
    rate_hz: float  # the record's sample rate (a CSV's: rate = bin x segment)
    segment: int  # Welch segment, samples
    segments: int  # K: the segments averaged
    rounding_variance: Array  # (axes, bins): a CSV's rounding, else zeros
    frequency_scale_std: float = 0.0  # relative: a CSV's bin spacing, read from frequencies printed to 0.1 Hz
    samples: int = 0  # the record's samples (the model simulates as many); 0 for a CSV: the test's own


def window_correlation(
    segment: int, lags: int = CORRELATED_BINS
) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """(c_m, e_m), m = 0..lags-1: white noise's windowed DFT correlated between bins m apart in one segment (c) and
    in two segments half a segment apart (e, times (-1)^F at bin F; see optim.identification.sweep_fit)."""
    w = np.kaiser(segment, KAISER_BETA)
    j = np.arange(segment)
    phases = np.exp(-2j * np.pi * np.outer(np.arange(lags), j) / segment)
    half = segment // 2
    c: NDArray[np.complex128] = phases @ w**2 / np.sum(w**2)
    e: NDArray[np.complex128] = phases[:, :half] @ (w[:half] * w[half:]) / np.sum(w**2)
    return c, e


def welch_segments(signal: Array, segment: int, rate_hz: float) -> NDArray[np.complex128]:
    """(K, segment // 2 + 1): each Welch segment's windowed DFT, scaled so that the one-sided density PSD is the mean
    of their squared moduli (scipy.signal.welch's, as klipper_psd calls it, at the bins other than 0 and Nyquist)."""
    count = (signal.size - segment) // (segment // 2) + 1
    window = np.kaiser(segment, KAISER_BETA)
    start = (segment // 2) * np.arange(count)
    parts = signal[start[:, None] + np.arange(segment)[None, :]]
    parts = parts - np.mean(parts, axis=1, keepdims=True)
    scale = math.sqrt(2.0 / (rate_hz * float(np.sum(window**2))))
    spectra: NDArray[np.complex128] = np.fft.rfft(parts * window, axis=1) * scale
    return spectra


def _fitted_bins(frequency_hz: Array, test: ResonanceTest, rate_hz: float, segment: int) -> NDArray[np.bool_]:
    """The bins fitted: from FIT_MARGIN_BINS above the test's start (the edge of its sweep, and the overlay's lines
    below it) to FIT_MARGIN_BINS above its end (above it only the square wave's harmonics excite the axis: a test
    that swept further, its settings misstated, would be misfitted there), at most MAX_FIT_HZ, below Nyquist."""
    bin_hz = rate_hz / segment
    low = max(test.min_freq_hz, LOW_HZ) + FIT_MARGIN_BINS * bin_hz
    high = min(MAX_FIT_HZ, rate_hz / 2.0 - bin_hz, test.max_freq_hz + FIT_MARGIN_BINS * bin_hz)
    keep: NDArray[np.bool_] = (frequency_hz >= low) & (frequency_hz <= high)
    return keep


def record_spectrum(signals: Array, rate_hz: float, test: ResonanceTest) -> MeasuredSpectrum:
    """A raw record's Welch PSD per signal as Klipper computes it (calc_freq_response: segments of
    2^bitlen(int(fs WINDOW_S - 1)) samples), on the bins fitted."""
    segment = 1 << int(rate_hz * WINDOW_S - 1).bit_length()
    frequency = np.asarray(np.fft.rfftfreq(segment, 1.0 / rate_hz), float)
    keep = _fitted_bins(frequency, test, rate_hz, segment)
    parts = [welch_segments(np.asarray(s, float), segment, rate_hz)[:, keep] for s in np.atleast_2d(signals)]
    psd = np.array([np.mean(np.abs(p) ** 2, axis=0) for p in parts])
    count = np.atleast_2d(signals).shape[1]
    return MeasuredSpectrum(frequency[keep], psd, rate_hz, segment, parts[0].shape[0], np.zeros_like(psd), 0.0, count)


def csv_spectrum(
    frequency_hz: Array, written: Array, factor: Array, test: ResonanceTest, significant_digits: int = 4
) -> MeasuredSpectrum:
    """A Klipper resonance CSV's PSD per axis: ``written`` (axes, rows) as printed (``%.3e``), the measured PSD being
    written / ``factor`` (the normalisation of SHAPER_CALIBRATE's file, else ones). Klipper's accelerometers
    sample at 1.6-4 kHz and its segments have CSV_SEGMENT samples there: the rate is taken as the bins' spacing x
    CSV_SEGMENT, the spacing the slope of the printed frequencies (its standard error, from their rounding, widens
    every frequency's interval); K is the test's own segment count (a record is at least that long: the variance is
    not understated by it)."""
    rows = np.arange(frequency_hz.size)
    bin_hz = float(np.polyfit(rows, frequency_hz, 1)[0])  # the rows print the bins to 0.1 Hz
    slope_std = PRINTED_HZ / math.sqrt(12.0) / math.sqrt(float(np.sum((rows - rows.mean()) ** 2)))
    rate = bin_hz * CSV_SEGMENT
    exact = np.asarray(rows * bin_hz + float(np.mean(frequency_hz - rows * bin_hz)), float)
    keep = _fitted_bins(exact, test, rate, CSV_SEGMENT)
    magnitude = np.maximum(np.abs(written[:, keep]), 1e-300)
    step = 10.0 ** (np.floor(np.log10(magnitude)) - (significant_digits - 1))
    psd = written[:, keep] / factor[keep]
    segments = (int(test.duration_s * rate) - CSV_SEGMENT) // (CSV_SEGMENT // 2) + 1
    rounding = step**2 / 12.0 / factor[keep] ** 2
    return MeasuredSpectrum(exact[keep], psd, rate, CSV_SEGMENT, max(segments, 1), rounding, slope_std / bin_hz)
