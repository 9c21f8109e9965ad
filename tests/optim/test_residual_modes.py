"""A mode the record's spectrum hides, found in the fit's residual (optim.identification.modal): two well-damped
modes whose peaks make one, under a knock of tests/printer_records.py (2 x 4 ms at 0.1 s, 1 s at 3200 Hz).

The records are bench/identify_coverage.py's seeds 132 and 47, rounded. With the spectrum's peaks alone each was
fitted with one mode whose 95 % interval missed the truth (measured: 120.587 Hz in [120.29, 120.88] for 119.51;
62.106 Hz in [61.94, 62.28] for 62.5): the mode left out biased the other. With the residual's peak both modes are
found, within 1 % (the lower mode of seed 132 is 0.9 % off at 6 % noise, inside its interval), and every interval
holds the truth. The decay's spectra over its first n, n/2, ... samples, each signal over its own noise
(spectrum.decay_peaks), now show both peaks without the residual; with the whole record's summed spectrum
(``_whole_record_peaks``, the peaks before) the residual's peak alone finds the second mode.
"""

from __future__ import annotations

import numpy as np
import pytest

import optim.identification.modal as modal
from optim.identification.decay_start import identify_free_decay
from optim.identification.record import Record
from optim.identification.record_csv import parse_record_csv
from optim.identification.spectrum import record_spectrum, spectral_peaks
from tests.printer_records import RATE_HZ, knock, knock_case, raw_record

# (modes (f Hz, zeta, share), noise mm/s^2 (6 % and 5 % of the decay's peak), seed)
CASES = {
    "seed-132": (((82.96, 0.08, 0.5), (119.51, 0.032, 0.5)), 3200.0, 7132),
    "seed-47": (((62.5, 0.047, 0.52), (141.5, 0.09, 0.48)), 1400.0, 7047),
}


def _record(modes: tuple[tuple[float, float, float], ...], noise: float, seed: int) -> Record:
    table = np.round(raw_record(knock(RATE_HZ, 1.0), np.random.default_rng(seed), modes, noise_mm_s2=noise), 6)
    return Record(table[:, 0], table[:, 1:].T, ("accel_x", "accel_y", "accel_z"))


def _whole_record_peaks(window: np.ndarray, rate: float, max_modes: int) -> list[tuple[float, float]]:
    return spectral_peaks(record_spectrum(window, rate), max_modes)


def _check(fit: modal.ModalIdentification, modes: tuple[tuple[float, float, float], ...]) -> None:
    assert len(fit.modes) == 2
    for mode, (f, zeta, _) in zip(fit.modes, modes, strict=True):
        assert mode.natural_frequency_hz == pytest.approx(f, rel=0.01)
        assert mode.natural_frequency_ci_hz[0] <= f <= mode.natural_frequency_ci_hz[1]
        assert mode.damping_ratio_ci[0] <= zeta <= mode.damping_ratio_ci[1]


@pytest.mark.parametrize("case", CASES)
def test_a_mode_the_spectrum_hides_is_found_in_the_residual(case: str, monkeypatch: pytest.MonkeyPatch) -> None:
    modes, noise, seed = CASES[case]
    record = _record(modes, noise, seed)
    _check(identify_free_decay(record), modes)
    # the whole record's spectrum alone shows one peak: the residual's finds the other
    monkeypatch.setattr(modal, "decay_peaks", _whole_record_peaks)
    _check(identify_free_decay(record), modes)
    # without the residual's peak either: from the excursion one mode, whose interval misses the truth (the failure
    # this mends; decay_start's agreement test then moves the start on until the mode left out has died away)
    monkeypatch.setattr(modal, "_residual_peak", lambda *_: None)
    alone = modal.identify_modes(record)
    assert len(alone.modes) == 1
    mode = alone.modes[0]
    f = min((m[0] for m in modes), key=lambda g: abs(g - mode.natural_frequency_hz))
    assert not mode.natural_frequency_ci_hz[0] <= f <= mode.natural_frequency_ci_hz[1]


def test_a_peak_split_by_the_noise_that_cannot_be_fitted_as_two_modes_is_fitted_as_one() -> None:
    """tests/printer_records.knock_case(635): one mode (118.48 Hz, zeta 0.0497) at 17 % noise, whose decay's spectrum
    shows two peaks (116.2 and 121.1 Hz). Their two-mode fit runs out of evaluations (100: damped_fit's 25 per
    parameter; it converged to a degenerate pair after 278 with no cap), and the record was refused; it is fitted
    as one mode, whose intervals hold the truth, with a warning."""
    modes, _, text = knock_case(635, "klipper_raw")
    fit = modal.identify_modes(parse_record_csv(text, max_rows=10_000))
    assert any("could not be fitted as two modes" in w for w in fit.warnings)
    (mode,) = fit.modes
    ((f, zeta, _),) = modes
    assert mode.natural_frequency_ci_hz[0] <= f <= mode.natural_frequency_ci_hz[1]
    assert mode.damping_ratio_ci[0] <= zeta <= mode.damping_ratio_ci[1]


def test_a_record_shorter_than_the_shortest_span_is_searched_whole() -> None:
    """40 samples at 1 kHz of a 60 Hz decay (zeta 0.05, noise 0.1 % of its start): the decay's spectra go down to
    spectrum.MIN_SPAN (64) samples, but a shorter record is searched whole, as before them (60.077 Hz, as 23ce762)."""
    t = np.arange(40) / 1000.0
    wn = 2 * np.pi * 60.0
    y = np.exp(-0.05 * wn * t) * np.cos(wn * np.sqrt(1 - 0.05**2) * t)
    y = y + 0.001 * np.random.default_rng(0).standard_normal(t.size)
    (mode,) = identify_free_decay(Record(t, y[None, :], ("a",))).modes
    assert mode.natural_frequency_hz == pytest.approx(60.0, rel=0.005)
