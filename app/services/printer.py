"""The identify use case for a printer's files: Klipper's resonance CSV and resonance tests, and the shaper to set in
the firmware (``target``).

- A record's format is told from its header (optim.identification.formats) unless ``format`` names it.
- Klipper's resonance CSV (``klipper_psd``) and a raw record of a swept excitation (a resonance test: told by
  optim.identification.excitation) are answered from their power spectral density: the spectrum, its peaks
  (frequency, and a damping estimate from the half-power width), and its modes with 95 % intervals, fitted with the
  test (its settings in the query: sweep_*, sweeping_*) as the excitation (optim.identification.sweep_fit).
- With a ``target`` every record's answer gets ``recommendation.shaper`` and its fields
  (optim.families.input_shaped.firmware_pick): the PSD is Klipper's (computed from a raw record as Klipper does,
  or read), normalised as Klipper normalises it, and the frequency interval the shaper is made robust over is
  ``frequency_tolerance`` where given, else the lowest identified mode's 95 % interval, else the PSD's resolution at
  its lowest peak (half a bin either side: the largest share of a peak's frequency).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from app.presenters import present
from app.schemas.identify import MeasurementParams
from optim.families.input_shaped import calibration as cal
from optim.families.input_shaped.firmware_pick import each_type, firmware_pick, firmware_report
from optim.identification.excitation import sweep_band
from optim.identification.formats import PsdRecord, RecordFormat, detect_format, parse_psd_csv
from optim.identification.modal import FittedMode
from optim.identification.record import Record, uniform_record
from optim.identification.resonance_test import ResonanceTest, overlay_amplitude, start_in_record
from optim.identification.spectrum import psd_peaks
from optim.identification.sweep_fit import SpectralMode, SweepIdentification, identify_sweep
from optim.identification.sweep_spectrum import MeasuredSpectrum, csv_spectrum, record_spectrum

__all__ = ["SpectrumAnswer", "psd_answer", "record_format", "record_psd", "shaper_recommendation", "sweep_answer"]

FIRMWARE_NAMES = {"klipper": "Klipper", "reprapfirmware": "RepRapFirmware", "marlin": "Marlin"}
BAND_FIELDS = ("sweep_min_freq", "sweep_max_freq", "sweep_hz_per_sec")
KLIPPER_REFERENCE = "Klipper's resonance calibration criteria (klippy/extras/shaper_calibrate.py, 84104bbbd)"


def record_format(text: str, params: MeasurementParams) -> RecordFormat:
    return detect_format(text) if params.format == "auto" else params.format


def record_psd(record: Record) -> tuple[np.ndarray, np.ndarray]:
    """Klipper's PSD of a raw record, summed over its signals (as psd_xyz), not normalised."""
    frequency, psd = cal.klipper_psd(np.asarray(record.time_s, float), np.atleast_2d(record.signals))
    total = np.sum(psd, axis=0)
    return frequency, total


def _peaks(frequency: np.ndarray, psd: np.ndarray, max_modes: int) -> list[dict[str, Any]]:
    resolution = float(frequency[1] - frequency[0]) if frequency.size > 1 else 0.0
    return [
        {
            "frequency_hz": f,
            "damping_ratio_half_power": zeta,
            "frequency_interval_hz": [f - resolution / 2, f + resolution / 2],
        }
        for f, zeta in psd_peaks(frequency, psd, max_modes)
    ]


def _interval(
    params: MeasurementParams, peaks: list[dict[str, Any]], mode: FittedMode | None
) -> tuple[tuple[float, float], str]:
    if params.frequency_tolerance is not None:
        tol = params.frequency_tolerance
        return (1.0 - tol, 1.0 + tol), f"frequency_tolerance: +-{100 * tol:g} %"
    if mode is not None:
        lo, hi = mode.natural_frequency_ci_hz
        f = mode.natural_frequency_hz
        return (lo / f, hi / f), f"the 95 % interval of the {f:.4g} Hz mode's natural frequency"
    if peaks:  # the lowest peak: half a bin is the largest share of its frequency
        low = min(peaks, key=lambda p: p["frequency_hz"])
        lo, hi = low["frequency_interval_hz"]
        f = low["frequency_hz"]
        return (lo / f, hi / f), f"the spectrum's resolution at its {f:.4g} Hz peak (half a bin either side)"
    return (1.0, 1.0), "none: no peak to measure the frequency by"


def shaper_recommendation(
    frequency: np.ndarray,
    psd_normalized: np.ndarray,
    params: MeasurementParams,
    peaks: list[dict[str, Any]],
    mode: FittedMode | None = None,
) -> dict[str, Any]:
    """``recommendation``'s fields for ``params.target`` (see the module)."""
    assert params.target is not None
    interval, source = _interval(params, peaks, mode)
    robust_first = params.frequency_tolerance is not None
    choice = firmware_pick(
        frequency,
        psd_normalized,
        params.target,
        interval,
        params.square_corner_velocity,
        robust_first,
        params.max_smoothing,
    )
    pick, reference, klipper = choice.pick, choice.reference, choice.klipper
    quiet = "" if robust_first else " and leaving no more vibration"
    whose = "Klipper's" if reference is klipper else "that"
    reason = (
        f"{choice.note + '. ' if choice.note else ''}Of the {FIRMWARE_NAMES[params.target]} shapers as fast as "
        f"{whose} pick ({reference.kind} at "
        f"{reference.frequency_hz:.1f} Hz, max_accel {reference.max_accel_mm_s2:.0f} mm/s^2){quiet}, the one leaving "
        f"least over the frequency interval {interval[0]:.4g}..{interval[1]:.4g} ({source})"
    )
    return {
        "target": params.target,
        "shaper": {
            "type": choice.firmware_type,
            "frequency_hz": pick.frequency_hz,
            "damping_ratio": pick.scores.damping_ratio,
        },
        "max_acceleration": pick.max_accel_mm_s2,
        "remaining_vibration_percent": 100.0 * pick.vibrations,
        "robust_remaining_vibration_percent": 100.0 * choice.robust_vibrations,
        "smoothing": pick.smoothing_mm,
        "robust_over": {"frequency_ratio_interval": list(interval), "source": source},
        "klipper_calibration": {
            "type": klipper.kind,
            "frequency_hz": klipper.frequency_hz,
            "max_acceleration": klipper.max_accel_mm_s2,
            "remaining_vibration_percent": 100.0 * klipper.vibrations,
            "smoothing": klipper.smoothing_mm,
            "each_type": each_type(choice.klipper_each),
        },
        "dominates_klipper": choice.dominates,
        "firmware": present(firmware_report(pick, KLIPPER_REFERENCE)),
        "response": _response(frequency, psd_normalized, pick, klipper),
        "shaper_reason": reason,
    }


def _response(frequency: np.ndarray, psd_normalized: np.ndarray, pick: cal.Pick, klipper: cal.Pick) -> dict[str, Any]:
    """What the page plots (Klipper's graph): the scored spectrum, and each shaper's V at its worst over the
    printer's damping ratios, bin by bin."""
    bins, p = cal.scored_bins(frequency, psd_normalized)
    return {
        "frequency_hz": bins,
        "psd_normalized": p,
        "recommended": cal.worst_response(pick.impulses, bins),
        "klipper": cal.worst_response(klipper.impulses, bins),
    }


def _spectrum_body(frequency: np.ndarray, psd: np.ndarray, normalized: np.ndarray) -> dict[str, Any]:
    return {
        "frequency_hz": frequency,
        "psd": psd,
        "psd_normalized": normalized,
        "resolution_hz": float(frequency[1] - frequency[0]) if frequency.size > 1 else 0.0,
        "window": "kaiser(6), Klipper's segments",
    }


@dataclass(frozen=True)
class SpectrumAnswer:
    """A spectrum's answer body (the route's design is added by app.services.identify) and its modes."""

    body: dict[str, Any]
    modes: tuple[SpectralMode, ...]


def resonance_test(params: MeasurementParams) -> ResonanceTest:
    """The resonance test the query's sweep_* and sweeping_* describe."""
    return ResonanceTest(
        min_freq_hz=params.sweep_min_freq,
        max_freq_hz=params.sweep_max_freq,
        hz_per_sec=params.sweep_hz_per_sec,
        accel_per_hz=params.sweep_accel_per_hz,
        sweeping_accel_mm_s2=params.sweeping_accel,
        sweeping_period_s=params.sweeping_period,
    )


def _fit_body(fit: SweepIdentification, test: ResonanceTest) -> dict[str, Any]:
    return {
        "model": "each axis's Welch PSD = gain x (the test through the modes' PSD) + noise floor, least squares "
        "whitened by the PSD's covariance",
        "test": {
            "min_freq": test.min_freq_hz,
            "max_freq": test.max_freq_hz,
            "hz_per_sec": test.hz_per_sec,
            "accel_per_hz": test.accel_per_hz,
            "sweeping_accel": test.sweeping_accel_mm_s2,
            "sweeping_period": test.sweeping_period_s,
            "start_s": test.start_s,
        },
        "reduced_chi_squared": fit.reduced_chi_squared if fit.modes or fit.simulations else None,
        "bins": fit.bins,
        "segments": fit.segments,
        "simulations": fit.simulations,
    }


def _answer(
    fmt: str,
    excitation: str,
    frequency: np.ndarray,
    psd: np.ndarray,
    normalized: np.ndarray,
    params: MeasurementParams,
    measured: MeasuredSpectrum,
    test: ResonanceTest,
    notes: list[str],
) -> SpectrumAnswer:
    keep = frequency <= cal.MAX_PSD_FREQ_HZ
    peaks = _peaks(frequency[keep], psd[keep], params.max_modes)
    starts = [(p["frequency_hz"], p["damping_ratio_half_power"]) for p in peaks]
    fit = identify_sweep(measured, test, starts, params.max_modes)
    lowest = fit.modes[0] if fit.modes else None
    recommendation: dict[str, Any] = {"plant": None, "frequency_ratio_interval": None, "candidates": []}
    if params.target is None:
        recommendation["reason"] = "no target given: add target=klipper|reprapfirmware|marlin for the firmware's shaper"
    else:
        recommendation.update(shaper_recommendation(frequency, normalized, params, peaks, lowest))
        recommendation["reason"] = recommendation.pop("shaper_reason")
        recommendation["frequency_ratio_interval"] = recommendation["robust_over"]["frequency_ratio_interval"]
    body = {
        "format": fmt,
        "excitation": excitation,
        "spectrum": _spectrum_body(frequency[keep], psd[keep], normalized[keep]),
        "peaks": peaks,
        "modes": [present(m) for m in fit.modes],
        "fit": _fit_body(fit, test),
        "recommended": None,
        "recommendation": recommendation,
        "warnings": [*notes, *fit.warnings],
    }
    return SpectrumAnswer(body, fit.modes)


def psd_answer(text: str, params: MeasurementParams, max_rows: int) -> SpectrumAnswer:
    """The answer for Klipper's resonance CSV: normalised as Klipper normalises it unless it already is (a file
    with shaper columns is SHAPER_CALIBRATE's, written normalised; TEST_RESONANCES writes none, raw). Its modes are
    fitted to the file's axes as written (psd_x, psd_y, psd_z; psd_xyz alone where they are not given)."""
    record: PsdRecord = parse_psd_csv(text, max_rows=max_rows)
    normalized = record.psd if record.normalized else cal.normalized(record.frequency_hz, record.psd)
    raw = cal.denormalized(record.frequency_hz, record.psd) if record.normalized else record.psd
    written = np.vstack(list(record.axes.values())) if record.axes else record.psd[None, :]
    ones = np.ones_like(record.frequency_hz)
    factor = cal.normalized(record.frequency_hz, ones) if record.normalized else ones
    test = resonance_test(params)
    measured = csv_spectrum(record.frequency_hz, written, factor, test)
    return _answer("klipper_psd", "spectrum", record.frequency_hz, raw, normalized, params, measured, test, [])


def _snapped(value: float, step: float, within: float) -> float:
    """``value`` on the nearest multiple of ``step`` if within ``within`` of it (the round settings people type),
    else to 3 significant digits."""
    nearest = round(value / step) * step
    return round(nearest, 6) if abs(value - nearest) <= within else float(f"{value:.3g}")


def _test_in_record(params: MeasurementParams, signals: np.ndarray, rate_hz: float) -> tuple[ResonanceTest, list[str]]:
    """The query's test, its unstated band and rate read off the record's ridge (excitation.sweep_band) and snapped to
    round settings (0.05 Hz/s within 0.5 %, 1 Hz within 0.3 Hz), where it starts in the record
    (resonance_test.start_in_record: Klipper's accelerometer runs before the test's first move), and, sweeping_period
    unstated,
    whether the record holds the sweeping overlay (resonance_test.overlay_amplitude: under half the expected
    amplitude, it is fitted without)."""
    test = resonance_test(params)
    line = sweep_band(signals, rate_hz)
    if line is None:
        return test, []
    at_start, at_end, slope = line
    stated = params.model_fields_set
    read: list[str] = []
    if "sweep_hz_per_sec" not in stated:
        test = replace(test, hz_per_sec=_snapped(slope, 0.05, 0.005 * slope))
        read.append(f"{test.hz_per_sec:g} Hz/s")
    if "sweep_min_freq" not in stated and at_start > test.min_freq_hz + 1.0:  # FREQ_START above the default
        test = replace(test, min_freq_hz=_snapped(at_start, 1.0, 0.3))
        read.append(f"from {test.min_freq_hz:g} Hz")
    if "sweep_max_freq" not in stated:
        test = replace(test, max_freq_hz=min(max(_snapped(at_end, 1.0, 0.3), test.min_freq_hz), 300.0))
        read.append(f"to {test.max_freq_hz:g} Hz")
    test = replace(test, start_s=start_in_record(signals, rate_hz, test))
    notes = []
    if read:
        notes.append(
            f"the test's settings read off the record's ridge: {', '.join(read)}, starting {test.start_s:.3g} s into "
            f"the record (state {', '.join(BAND_FIELDS)} to set them)"
        )
    if "sweeping_period" not in stated and test.sweeping_period_s > 0.0:
        amplitude, error = overlay_amplitude(signals, rate_hz, test)
        if amplitude < 0.5 * test.sweeping_accel_mm_s2:  # Klipper before the sweeping test, or SWEEPING_PERIOD=0
            notes.append(
                f"no sweeping overlay in the record ({amplitude:.3g} +- {error:.2g} mm/s^2 of the "
                f"{test.sweeping_accel_mm_s2:g} expected): fitted without it (state sweeping_period to set it)"
            )
            test = replace(test, sweeping_period_s=0.0)
    if abs(slope / test.hz_per_sec - 1.0) > 0.05:
        notes.append(f"the record's ridge rises {slope:.3g} Hz/s, not the {test.hz_per_sec:g} stated")
    return test, notes


def sweep_answer(record: Record, fmt: str, params: MeasurementParams) -> SpectrumAnswer:
    """The answer for a raw record of a swept excitation: its Klipper PSD, peaks, modes and the target's shaper, the
    test placed in the record by its ridge (_test_in_record)."""
    frequency, psd = record_psd(record)
    dt, signals, _ = uniform_record(record.time_s, np.atleast_2d(record.signals))
    test, notes = _test_in_record(params, signals, 1.0 / dt)
    measured = record_spectrum(signals, 1.0 / dt, test)
    return _answer(fmt, "sweep", frequency, psd, cal.normalized(frequency, psd), params, measured, test, notes)
