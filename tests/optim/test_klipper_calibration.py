"""Klipper's calibration criteria (optim.families.input_shaped.calibration) against Klipper's own code.

The expected numbers are Klipper's: klippy/extras/shaper_calibrate.py at Klipper3d/klipper 84104bbbd (master of
2026-08-07) run by bench/klipper_reference.py on the same seeded records (tests/printer_records.py), and its
``_estimate_shaper``, ``_get_shaper_smoothing`` and ``find_shaper_max_accel`` run at 50 Hz, zeta 0.1, scv 5 mm/s
(printed to 6 significant figures: the tolerances are that rounding).
"""

from __future__ import annotations

import numpy as np
import pytest

from optim.families.input_shaped import calibration as cal
from optim.families.input_shaped.firmware import klipper_impulses
from optim.families.input_shaped.firmware_pick import most_robust
from tests.printer_records import RATE_HZ, chirp, raw_record

KINDS = ("zv", "mzv", "ei", "2hump_ei", "3hump_ei", "zvd")
# Klipper's V at 25, 50 and 75 Hz of each shaper at 50 Hz, zeta 0.1 (the oscillator's zeta 0.1 too)
RESPONSE = {
    "zv": (0.649395, 0.0, 0.554557),
    "mzv": (0.562079, 0.0, 0.092040),
    "ei": (0.392141, 0.050616, 0.286176),
    "2hump_ei": (0.178367, 0.000514, 0.083484),
    "3hump_ei": (0.022934, 0.049204, 0.030220),
    "zvd": (0.421714, 0.0, 0.307534),
}
SMOOTHING_AT_5000 = {"zv": 0.067696, "mzv": 0.081468, "ei": 0.131798, "2hump_ei": 0.226502, "3hump_ei": 0.361658,
                     "zvd": 0.123167}  # fmt: skip
MAX_ACCEL = {"zv": 9742.84, "mzv": 7364.83, "ei": 4552.44, "2hump_ei": 2648.98, "3hump_ei": 1533.15, "zvd": 4871.42}
# bench/klipper_reference.py, seed 0: Klipper's pick of each type (find_best_shaper's list) and its best
EACH = {
    "zv": (67.0, 0.29064672458313845, 17494.252333139775),
    "mzv": (42.2, 0.0, 5246.231109386391),
    "ei": (55.2, 0.018146807581643398, 5548.5847230432455),
    "2hump_ei": (67.0, 0.00036588891822929536, 4756.514561401574),
    "3hump_ei": (84.2, 0.0003913028739890267, 4704.765127565497),
}
BEST = ("mzv", 42.2, 0.11436781710319756)  # type, Hz, smoothing (mm)
# the same with max_smoothing 0.1 mm (bench/klipper_reference.py KLIPPY_DIR 0.1): fit_shaper stops its scan there
EACH_SMOOTHED = {
    "zv": (41.8, 0.2641946624047862, 6809.235341176667),
    "mzv": (45.2, 0.018760957608813297, 6018.654121496497),
    "ei": (57.6, 0.029946356115798146, 6041.5591691432855),
    "2hump_ei": (75.4, 0.0344758605952493, 6023.957746475157),
    "3hump_ei": (95.2, 0.03530345618547356, 6014.335642112047),
}
BEST_SMOOTHED = ("mzv", 45.2, 0.09969006157983125)


def _arrays(kind: str) -> tuple[np.ndarray, np.ndarray]:
    impulses = klipper_impulses(kind, 50.0, 0.1)
    return impulses.amplitudes[None, :], impulses.times_s[None, :]


@pytest.mark.parametrize("kind", KINDS)
def test_the_criteria_are_klippers_at_50_hz(kind: str) -> None:
    a, t = _arrays(kind)
    response = cal.shaper_response(a, t, 0.1, np.array([25.0, 50.0, 75.0]))[0]
    assert response == pytest.approx(RESPONSE[kind], abs=1e-6)
    assert cal.smoothing_mm(a, t, 5000.0, 5.0)[0] == pytest.approx(SMOOTHING_AT_5000[kind], abs=1e-6)
    # closed form where Klipper bisects to 1e-8 mm/s^2 (its figure printed to 0.01)
    assert cal.max_acceleration(a, t, 5.0)[0] == pytest.approx(MAX_ACCEL[kind], abs=0.01)
    accel = cal.max_acceleration(a, t, 5.0)
    assert cal.smoothing_mm(a, t, float(accel[0]), 5.0)[0] == pytest.approx(cal.TARGET_SMOOTHING_MM, rel=1e-12)


@pytest.fixture(scope="module")
def sweep_spectrum() -> tuple[np.ndarray, np.ndarray]:
    """bench/klipper_reference.py's seed-0 record: a 20-120 Hz resonance test at 2 Hz/s, printed as Klipper does;
    its normalised PSD summed over the axes."""
    table = np.round(raw_record(chirp(RATE_HZ, 20.0, 120.0, hz_per_sec=2.0), np.random.default_rng(0)), 6)
    frequency, psd = cal.klipper_psd(table[:, 0], table[:, 1:].T)
    return frequency, cal.normalized(frequency, psd.sum(axis=0))


@pytest.fixture(scope="module")
def sweep_types(sweep_spectrum: tuple[np.ndarray, np.ndarray]) -> list[cal.Scores]:
    return [cal.evaluate(kind, klipper_impulses, *sweep_spectrum) for kind in cal.KLIPPER_TYPES]


@pytest.mark.parametrize(
    ("max_smoothing", "expected", "expected_best"), [(None, EACH, BEST), (0.1, EACH_SMOOTHED, BEST_SMOOTHED)]
)
def test_the_pick_of_each_type_and_the_best_are_klippers(
    sweep_types: list[cal.Scores], max_smoothing: float | None, expected: dict, expected_best: tuple
) -> None:
    """Vibrations to 1e-9: the same sums in another order (a 6-decimal rounding flipped by one ulp of the record
    would move them by ~1e-7, and never did); max_accel to Klipper's bisection's 1e-8 mm/s^2."""
    best, each = cal.klipper_pick(sweep_types, max_smoothing)
    for pick in each:
        frequency, vibrations, accel = expected[pick.kind]
        assert pick.frequency_hz == pytest.approx(frequency, abs=1e-9), pick.kind
        assert pick.vibrations == pytest.approx(vibrations, abs=1e-9), pick.kind
        assert pick.max_accel_mm_s2 == pytest.approx(accel, abs=2e-8), pick.kind
    assert (best.kind, best.frequency_hz) == pytest.approx(expected_best[:2])
    assert best.smoothing_mm == pytest.approx(expected_best[2], rel=1e-12)


def test_the_dominating_pick_is_never_worse_by_klippers_criteria(
    sweep_types: list[cal.Scores], sweep_spectrum: tuple[np.ndarray, np.ndarray]
) -> None:
    """Against Klipper's best and each type's pick: no more vibrations, no lower max_accel, and (by brute force over
    every candidate) none at least as fast leaves fewer vibrations."""
    best, each = cal.klipper_pick(sweep_types)
    vibrations = np.concatenate([s.vibrations for s in sweep_types])
    accel = np.concatenate([s.max_accel_mm_s2 for s in sweep_types])
    for reference in [best, *each]:
        found = most_robust(sweep_types, reference, *sweep_spectrum, [], robust_first=False, max_smoothing_mm=None)
        assert found is not None
        ours = found[2]
        assert ours.vibrations <= reference.vibrations and ours.max_accel_mm_s2 >= reference.max_accel_mm_s2
        assert not np.any((accel >= reference.max_accel_mm_s2) & (vibrations < ours.vibrations))
