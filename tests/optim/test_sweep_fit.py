"""optim.identification.sweep_fit: modes with 95 % intervals from a resonance test's spectrum.

- The Welch estimate's covariance (the fit's weights and intervals) against a Monte-Carlo of the estimate itself.
- Issue 27's seeded check for the resonance test's formats: records tests/printer_records.sweep_table draws (one or
  two modes, 20-200 Hz, zeta 0.02-0.15, noise 0-30 % of the response's peak; seeds 400.., which nothing was tuned
  on), as Klipper's resonance CSV and as the raw record's arrays. The issue asks for 95 % intervals holding the
  truth in at least 90 % of 200 records (bench/identify_coverage.py); here fewer, so the bar is 90 % less about 2.5
  standard deviations of a binomial share over the intervals counted.
"""

from __future__ import annotations

import numpy as np
import pytest

from optim.families.input_shaped import calibration as cal
from optim.identification.formats import parse_psd_csv
from optim.identification.resonance_test import ResonanceTest
from optim.identification.spectrum import psd_peaks
from optim.identification.sweep_fit import _covariance, identify_sweep
from optim.identification.sweep_spectrum import csv_spectrum, record_spectrum, welch_segments, window_correlation
from tests.printer_records import RATE_HZ, SWEEP_MAX_HZ, estimate_of, psd_csv, sweep_table

TEST = ResonanceTest(max_freq_hz=SWEEP_MAX_HZ)


def test_the_covariance_of_welchs_estimate_is_its_monte_carlo_covariance():
    """A chirp in white noise, 2000 draws: the empirical covariance of the PSD's bins, on the diagonal and one bin
    apart, is the formula's (the mean over 60 bins; its Monte-Carlo error is about sqrt(2 / 2000) / sqrt(60 / 3))."""
    rate, segment, n = 1000.0, 256, 256 * 20
    t = np.arange(n) / rate
    signal = 3.0 * np.sin(2 * np.pi * (40 * t + 3 * t**2))
    bins = np.arange(30, 90)
    y = welch_segments(signal, segment, rate)[:, bins]
    floor = 2.0 / rate  # white noise of unit variance: its one-sided density
    rng = np.random.default_rng(0)
    draws = np.array(
        [
            np.mean(np.abs(welch_segments(signal + rng.normal(0, 1, n), segment, rate)[:, bins]) ** 2, 0)
            for _ in range(2000)
        ]
    )
    empirical = np.cov(draws.T)
    formula = _covariance(y, bins, 1.0, floor, y.shape[0], window_correlation(segment))
    for lag in (0, 1):
        ratio = np.mean(np.diagonal(empirical, lag)) / np.mean(np.diagonal(formula, lag))
        assert ratio == pytest.approx(1.0, abs=0.03)
    # without the half-overlapping neighbours' terms the diagonal is understated by about 6 %: the check can fail
    c, e = window_correlation(segment)
    alone = _covariance(y, bins, 1.0, floor, y.shape[0], (c, np.zeros_like(e)))
    assert np.mean(np.diagonal(empirical)) / np.mean(np.diagonal(alone)) > 1.04


def _csv_modes(seed: int):
    modes, _, table = sweep_table(seed)
    frequency, psd = cal.klipper_psd(table[:, 0], table[:, 1:].T)
    record = parse_psd_csv(psd_csv(frequency, psd), max_rows=10_000)
    written = np.vstack(list(record.axes.values()))
    spectrum = csv_spectrum(record.frequency_hz, written, np.ones_like(record.frequency_hz), TEST)
    return modes, identify_sweep(spectrum, TEST, psd_peaks(record.frequency_hz, record.psd, 4), 4)


def _raw_modes(seed: int):
    modes, _, table = sweep_table(seed)
    frequency, psd = cal.klipper_psd(table[:, 0], table[:, 1:].T)
    spectrum = record_spectrum(table[:, 1:].T, RATE_HZ, TEST)
    return modes, identify_sweep(spectrum, TEST, psd_peaks(frequency, np.sum(psd, axis=0), 4), 4)


@pytest.mark.parametrize(("fit", "seeds"), [(_csv_modes, range(400, 420)), (_raw_modes, range(430, 440))])
def test_the_intervals_hold_the_truth_at_their_rate(fit, seeds):
    covered, counted, missed, close = 0, 0, 0, []
    for seed in seeds:
        modes, found = fit(seed)
        for f, zeta, _ in modes:
            mode = estimate_of(found.modes, f)
            if mode is None:
                missed += 1
                continue
            lo, hi = mode.natural_frequency_ci_hz
            zlo, zhi = mode.damping_ratio_ci
            covered += (lo <= f <= hi) + (zlo <= zeta <= zhi)
            counted += 2
            close += [abs(mode.natural_frequency_hz / f - 1) <= 0.005, abs(mode.damping_ratio / zeta - 1) <= 0.15]
    share = covered / counted
    assert share >= 0.9 - 2.5 * np.sqrt(0.9 * 0.1 / counted), (share, counted)
    assert missed == 0  # every drawn mode is swept through (5-200 Hz)
    assert np.mean(close) >= 0.95  # the 0.5 % and 15 %


def test_a_mode_the_peaks_miss_is_found_in_the_misfit():
    """Seed 18 of the bench: a 200 Hz mode at the spectrum's last row is no peak (find_peaks needs a fall on both
    sides): with the first mode alone the model misfits, and the mode added where the data exceed it most is kept."""
    modes, _, table = sweep_table(18)
    assert modes[1][0] == pytest.approx(200.0)
    spectrum = record_spectrum(table[:, 1:].T, RATE_HZ, TEST)
    found = identify_sweep(spectrum, TEST, [(modes[0][0] * 1.01, 0.03)], 4)
    assert estimate_of(found.modes, 200.0) is not None and found.reduced_chi_squared < 1.5
    alone = identify_sweep(spectrum, TEST, [(modes[0][0] * 1.01, 0.03)], 1)
    assert alone.reduced_chi_squared > 10 and any("does not fit" in w for w in alone.warnings)


def test_a_test_that_swept_further_than_stated_is_told():
    """A test swept to 200 Hz sent as Klipper's default (to 135 Hz): the 175 Hz peak above the stated band is not
    fitted, and the misfit its skirt leaves below 135 Hz is told, naming sweep_max_freq. Stated right, it fits."""
    modes, _, table = sweep_table(3)
    starts = [(m[0], m[1]) for m in modes]
    found = identify_sweep(record_spectrum(table[:, 1:].T, RATE_HZ, ResonanceTest()), ResonanceTest(), starts, 4)
    assert any("175.4 Hz lies above" in w and "sweep_max_freq" in w for w in found.warnings)
    assert any("does not fit" in w and "sweep_max_freq" in w for w in found.warnings)
    right = identify_sweep(record_spectrum(table[:, 1:].T, RATE_HZ, TEST), TEST, starts, 4)
    assert right.warnings == () and right.reduced_chi_squared < 1.5
    for (f, _, _), mode in zip(modes, right.modes, strict=True):
        assert mode.natural_frequency_ci_hz[0] <= f <= mode.natural_frequency_ci_hz[1]
