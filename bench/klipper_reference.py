"""Klipper's own calibration on the synthetic resonance tests of tests/printer_records.py: the reference numbers of
tests/optim/test_klipper_calibration.py, and how our pick compares with Klipper's.

``python bench/klipper_reference.py KLIPPY_DIR [MAX_SMOOTHING]`` (the ``klippy`` folder of a Klipper checkout, e.g.
84104bbbd: ``git clone https://github.com/Klipper3d/klipper``; its shaper_calibrate.py needs only numpy) runs
Klipper's ``process_accelerometer_data``, ``normalize_to_frequencies`` and ``find_best_shaper`` (scv 5, and
max_smoothing in mm where given) on each seeded record and prints Klipper's pick of each type and its best beside
ours (optim.families.input_shaped.calibration): type, frequency, remaining vibrations, smoothing and max_accel.
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from optim.families.input_shaped import calibration as cal  # noqa: E402
from optim.families.input_shaped.firmware import klipper_impulses  # noqa: E402
from optim.families.input_shaped.firmware_pick import most_robust  # noqa: E402
from tests.printer_records import RATE_HZ, chirp, raw_record  # noqa: E402

SEEDS = (0, 1, 2)
MAX_SMOOTHING: list[float | None] = [None]  # Klipper's max_smoothing (mm), as the command line sets it


def sweep(seed: int) -> np.ndarray:
    """The reference record: a 20-120 Hz resonance test at 2 Hz/s on the issue's axis (tests/printer_records.py),
    times and accelerations rounded as Klipper prints them."""
    table = raw_record(chirp(RATE_HZ, 20.0, 120.0, hz_per_sec=2.0), np.random.default_rng(seed))
    return np.round(table, 6)


def ours(table: np.ndarray) -> tuple[cal.Pick, cal.Pick]:
    frequency, psd = cal.klipper_psd(table[:, 0], table[:, 1:].T)
    total = cal.normalized(frequency, psd.sum(axis=0))
    types = [cal.evaluate(kind, klipper_impulses, frequency, total) for kind in cal.KLIPPER_TYPES]
    klipper, _ = cal.klipper_pick(types, MAX_SMOOTHING[0])
    found = most_robust(types, klipper, frequency, total, [], robust_first=False, max_smoothing_mm=MAX_SMOOTHING[0])
    assert found is not None  # (Klipper's pick itself qualifies)
    return klipper, found[2]


def main(klippy: str, max_smoothing: float | None = None) -> None:
    sys.path.insert(0, klippy)
    calibrate = importlib.import_module("extras.shaper_calibrate")
    for seed in SEEDS:
        table = sweep(seed)
        helper = calibrate.ShaperCalibrate(None)
        data = helper.process_accelerometer_data(f"seed{seed}", table)
        data.normalize_to_frequencies()
        best, each = helper.find_best_shaper(data, scv=5.0, max_smoothing=max_smoothing)
        mine, dominating = ours(table)
        for pick in each:
            print(
                f"        Klipper's {pick.name}: {pick.freq:.1f} Hz vibrations {pick.vibrs!r} "
                f"max_accel {pick.max_accel!r}"
            )
        print(
            f"seed {seed}: Klipper {best.name} {best.freq:.1f} Hz vibrations {best.vibrs!r} smoothing "
            f"{best.smoothing!r} max_accel {best.max_accel!r}"
        )
        print(
            f"        ours {mine.kind} {mine.frequency_hz:.1f} Hz vibrations {mine.vibrations!r} smoothing "
            f"{mine.smoothing_mm!r} max_accel {mine.max_accel_mm_s2!r}"
        )
        print(
            f"        dominating {dominating.kind} {dominating.frequency_hz:.1f} Hz vibrations "
            f"{dominating.vibrations!r} max_accel {dominating.max_accel_mm_s2!r}"
        )


if __name__ == "__main__":
    MAX_SMOOTHING[0] = float(sys.argv[2]) if len(sys.argv) > 2 else None
    main(sys.argv[1], MAX_SMOOTHING[0])
