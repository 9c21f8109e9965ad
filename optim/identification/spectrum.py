"""A record's spectrum by Welch's method (Welch 1967, a rectangular window) and its peaks (scipy's find_peaks)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.signal import find_peaks, welch

__all__ = [
    "MAX_SPECTRUM_POINTS",
    "MIN_SPAN",
    "Spectrum",
    "contrast_spectrum",
    "decay_peaks",
    "decay_spans",
    "peak_at",
    "psd_peaks",
    "record_spectrum",
    "spectral_peaks",
]

MAX_SPECTRUM_POINTS = 2049  # welch's one-sided spectrum of at most 4096-sample segments
MAX_SEGMENT = 4096
PEAK_FLOOR_FACTOR = 30.0  # a peak stands 15 dB above the spectrum's median (noise bins exceed it w.p. 1e-9)
PEAK_RELATIVE = 1e-3  # and at most 30 dB below the highest peak
# a measured spectrum's peak (a resonance test: the excitation spans the band, so its median is no noise floor)
# rises 1.5 dB above its surroundings (3 or 5 dB missed modes) and above the highest / 20: on 60 of
# bench/printer_calibration.py's resonance tests, a peak within 0.28 bins of a mode (median), no spurious peak, and
# 3 of 90 modes missed (second modes weaker than the highest / 20: below what Klipper's criteria score)
MIN_SPAN = 64  # the shortest span of a free decay whose spectrum is searched for peaks (50 Hz bins at 3200 Hz)
PSD_PEAK_PROMINENCE = 0.15  # decades of the PSD
PSD_PEAK_RELATIVE = 1.0 / 20.0  # ... and stands above the highest one / 20, the part of the PSD Klipper scores
PSD_PEAK_BAND_HZ = (10.0, 200.0)  # where a printer's resonances are looked for (Klipper scores up to 200 Hz)


@dataclass(frozen=True)
class Spectrum:
    frequency_hz: NDArray[np.float64]
    psd: NDArray[np.float64]  # summed over the signals, (signal units)^2 / Hz
    resolution_hz: float
    segment_samples: int


def record_spectrum(signals: NDArray[np.float64], sample_rate_hz: float) -> Spectrum:
    """Welch's PSD of every signal (segments of min(samples, 4096), half overlap, mean removed), summed
    over the signals: at most 2049 frequencies.

    The window is rectangular (boxcar), the practice for a free vibration that decays within the block
    (impact testing: a Hann window would weight the record's start, where the vibration is, by ~0 and hide
    the fast-decaying modes); the decay itself keeps the leakage low."""
    frequency, psd, segment = _welch(signals, sample_rate_hz)
    return Spectrum(frequency, np.sum(psd, axis=0), sample_rate_hz / segment, segment)


def _welch(signals: NDArray[np.float64], sample_rate_hz: float) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
    """(frequencies, Welch's PSD per signal (signals, bins), segment samples): segments of min(samples, 4096), half
    overlap, mean removed, a rectangular window."""
    segment = int(min(signals.shape[1], MAX_SEGMENT))
    frequency, psd = welch(signals, fs=sample_rate_hz, window="boxcar", nperseg=segment, detrend="constant", axis=-1)
    return np.asarray(frequency, float), np.atleast_2d(np.asarray(psd, float)), segment


def contrast_spectrum(signals: NDArray[np.float64], sample_rate_hz: float) -> Spectrum:
    """The largest, over the signals, of each one's Welch PSD (as ``record_spectrum``'s) over its own median: a peak's
    height over its signal's noise floor. An accelerometer's axes carry noise alike but the vibration mostly on one;
    their sum dilutes its peak by the others' noise (three axes: a peak 7.6 times the median of the sum is 20 times
    that of its own axis)."""
    frequency, psd, segment = _welch(signals, sample_rate_hz)
    contrast = np.max(psd / np.maximum(np.median(psd, axis=1, keepdims=True), 1e-300), axis=0)
    return Spectrum(frequency, contrast, sample_rate_hz / segment, segment)


def spectral_peaks(spectrum: Spectrum, max_modes: int) -> list[tuple[float, float]]:
    """(frequency Hz, half-power damping estimate) of the strongest peaks, lowest frequency first.

    A peak counts when it stands 15 dB (30 times) above the spectrum's median (the noise floor), within 30 dB of the
    highest one, and rises by half its height above its surroundings (find_peaks' prominence); the DC bins
    are skipped. Its frequency is refined by a parabola through the log PSD of its three bins; the damping
    estimate is the half-power bandwidth over twice the frequency (clipped to [0.002, 0.3])."""
    f, p = spectrum.frequency_hz, spectrum.psd
    if p.size < 5 or not np.any(p > 0):
        return []
    floor = float(np.median(p))
    top = float(np.max(p[2:])) if p.size > 2 else 0.0
    height = max(PEAK_FLOOR_FACTOR * floor, PEAK_RELATIVE * top)
    peaks, props = find_peaks(p, height=height, prominence=0.0)
    keep = (peaks >= 2) & (props["prominences"] >= 0.5 * p[peaks])
    peaks = peaks[keep]
    if peaks.size == 0:
        return []
    peaks = peaks[np.argsort(p[peaks])[::-1][:max_modes]]
    return [peak_at(f, p, int(k), spectrum.resolution_hz) for k in np.sort(peaks)]


def decay_peaks(signals: NDArray[np.float64], sample_rate_hz: float, max_modes: int) -> list[tuple[float, float]]:
    """``spectral_peaks`` of a free decay's spectra over its first n, n/2, n/4, ... samples (down to MIN_SPAN), lowest
    frequency first, at most ``max_modes``.

    A well-damped mode rings for a few hundredths of a second of a record that lasts a second: in the whole record's
    spectrum its wide peak lies under the noise of the rest (the peak over the floor falls as the span grows past the
    decay), while the spectrum of the span where it rings shows it. Longer spans come first (finer bins); a shorter one
    adds only the peaks farther than two of its bins from those already found."""
    found: list[tuple[float, float]] = []
    for length in decay_spans(signals.shape[1]):
        if len(found) >= max_modes:
            break
        spectrum = contrast_spectrum(signals[:, :length], sample_rate_hz)
        for f, zeta in spectral_peaks(spectrum, max_modes):
            if len(found) < max_modes and all(abs(f - g) > 2.0 * spectrum.resolution_hz for g, _ in found):
                found.append((f, zeta))
    return sorted(found)


def decay_spans(samples: int) -> list[int]:
    """The spans whose spectra are searched from a free decay's start: ``samples``, then half as many, and so on down
    to MIN_SPAN (``samples`` alone where it is shorter)."""
    spans = [samples]
    while spans[-1] // 2 >= MIN_SPAN:
        spans.append(spans[-1] // 2)
    return spans


def peak_at(f: NDArray[np.float64], p: NDArray[np.float64], k: int, df: float) -> tuple[float, float]:
    """(frequency Hz, half-power damping estimate) of the peak at bin ``k``: its frequency refined by a parabola
    through the log PSD of its three bins, its damping the width where the PSD falls to half, over twice the
    frequency (clipped to [0.002, 0.3])."""
    shift = 0.0
    if 0 < k < p.size - 1:
        a, b, c = np.log(np.maximum(p[k - 1 : k + 2], 1e-300))
        denom = a - 2 * b + c
        shift = float(np.clip(0.5 * (a - c) / denom, -0.5, 0.5)) if denom < 0 else 0.0
    frequency = float(f[k] + shift * df)
    half = p[k] / 2.0
    below_left = np.flatnonzero(p[:k] <= half)
    below_right = np.flatnonzero(p[k:] <= half)
    left = int(below_left[-1]) if below_left.size else 0
    right = k + int(below_right[0]) if below_right.size else p.size - 1
    width = float(f[right] - f[left])
    zeta = float(np.clip(width / (2.0 * frequency), 0.002, 0.3)) if frequency > 0 else 0.05
    return frequency, zeta


def psd_peaks(frequency_hz: NDArray[np.float64], psd: NDArray[np.float64], max_peaks: int) -> list[tuple[float, float]]:
    """(frequency Hz, half-power damping estimate) of a measured PSD's most prominent peaks in PSD_PEAK_BAND_HZ,
    lowest frequency first: each rising PSD_PEAK_PROMINENCE decades above its surroundings (find_peaks on log10)
    and above the highest peak's PSD_PEAK_RELATIVE (the square-wave excitation's harmonics make bumps far below),
    its frequency refined by a parabola through the log PSD of its three bins, its damping the half-power width
    over twice the frequency (clipped to [0.002, 0.3]; the window widens a peak narrower than a few bins)."""
    low, high = PSD_PEAK_BAND_HZ
    band = (frequency_hz >= low) & (frequency_hz <= high)
    f, p = frequency_hz[band], psd[band]
    if f.size < 3 or not np.any(p > 0):
        return []
    logp = np.log10(np.maximum(p, np.max(p) * 1e-30))
    found, props = find_peaks(
        logp, prominence=PSD_PEAK_PROMINENCE, height=float(np.max(logp)) + math.log10(PSD_PEAK_RELATIVE)
    )
    strongest = np.sort(found[np.argsort(props["prominences"])[::-1][:max_peaks]])
    return [peak_at(f, p, int(k), float(f[1] - f[0])) for k in strongest]
