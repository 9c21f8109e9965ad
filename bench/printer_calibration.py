"""Benchmark: the firmware shaper recommended from a resonance test against Klipper's calibration, on seeded records.

``python bench/printer_calibration.py [N] [KLIPPY_DIR]`` makes N (default 200) seeded resonance tests
(tests/printer_records.py: Klipper's chirp, 10 to 140 Hz at 2 Hz/s, measured at 3200 Hz and printed as Klipper
prints it) of axes with one or two modes (the first at 20 to 120 Hz, the second 1.3 to 2.5 times higher, damping
ratios 0.02 to 0.15) and noise of std 0 to 30 % of the response's peak; and for each:

- the recommendation for Klipper (optim.families.input_shaped.firmware_pick, as POST /v1/identify?target=klipper):
  its remaining vibrations and max_accel over Klipper's pick's (at most 1 and at least 1 by construction: the
  table says how often it is strictly better);
- with KLIPPY_DIR (the ``klippy`` folder of a Klipper checkout), Klipper's own find_best_shaper on the same record:
  whether its pick is the one we compute as Klipper's (type and frequency), and the largest differences of the
  remaining vibrations and max_accel;
- the spectrum's peaks against the true modes (the frequency error, in bins of the spectrum).
"""

from __future__ import annotations

import importlib
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from optim.families.input_shaped import calibration as cal  # noqa: E402
from optim.families.input_shaped.firmware_pick import firmware_pick  # noqa: E402
from optim.identification.spectrum import psd_peaks  # noqa: E402
from tests.printer_records import RATE_HZ, chirp, raw_record, toolhead  # noqa: E402

COMMAND = chirp(RATE_HZ, 10.0, 140.0, hz_per_sec=2.0)


def record(seed: int) -> tuple[np.ndarray, tuple[tuple[float, float, float], ...]]:
    rng = np.random.default_rng(1000 + seed)
    first = (float(rng.uniform(20, 120)), float(rng.uniform(0.02, 0.15)), 1.0)
    modes: tuple[tuple[float, float, float], ...] = (first,)
    if rng.random() < 0.5:
        share = float(rng.uniform(0.2, 0.6))
        second = (min(first[0] * float(rng.uniform(1.3, 2.5)), 150.0), float(rng.uniform(0.02, 0.15)), share)
        modes = ((first[0], first[1], 1 - share), second)
    peak = float(np.max(np.abs(toolhead(COMMAND, RATE_HZ, modes))))
    noise = float(rng.uniform(0.0, 0.3)) * peak
    return np.round(raw_record(COMMAND, rng, modes, noise_mm_s2=noise), 6), modes


def main(count: int, klippy: str | None) -> None:
    calibrate = None
    if klippy:
        sys.path.insert(0, klippy)
        calibrate = importlib.import_module("extras.shaper_calibrate")
    better = matched = 0
    vibration_ratio, accel_ratio, agree, diff_v, diff_a, peak_bins = [], [], 0, 0.0, 0.0, []
    began = time.perf_counter()
    for seed in range(count):
        table, modes = record(seed)
        frequency, psd = cal.klipper_psd(table[:, 0], table[:, 1:].T)
        normalized = cal.normalized(frequency, psd.sum(axis=0))
        choice = firmware_pick(frequency, normalized, "klipper")
        pick, reference = choice.pick, choice.klipper
        vibration_ratio.append(pick.vibrations / reference.vibrations if reference.vibrations > 0 else 1.0)
        accel_ratio.append(pick.max_accel_mm_s2 / reference.max_accel_mm_s2)
        better += pick.vibrations < reference.vibrations or pick.max_accel_mm_s2 > reference.max_accel_mm_s2
        resolution = float(frequency[1])
        found = [f for f, _ in psd_peaks(frequency, psd.sum(axis=0), 4)]
        for f, _, _ in modes:
            if found:
                peak_bins.append(min(abs(p - f) for p in found) / resolution)
        if calibrate is not None:
            helper = calibrate.ShaperCalibrate(None)
            data = helper.process_accelerometer_data(f"seed{seed}", table)
            data.normalize_to_frequencies()
            best, _ = helper.find_best_shaper(data, scv=5.0)
            same = best.name == reference.kind and abs(best.freq - reference.frequency_hz) < 1e-6
            agree += same
            matched += 1
            if same:
                diff_v = max(diff_v, abs(best.vibrs - reference.vibrations))
                diff_a = max(diff_a, abs(best.max_accel - reference.max_accel_mm_s2))
    took = time.perf_counter() - began
    print(f"{count} records in {took:.0f} s")
    print(
        f"ours over Klipper's pick: remaining vibrations at most x{max(vibration_ratio):.6g}, max_accel at least "
        f"x{min(accel_ratio):.6g}; strictly better in {better} of {count}"
    )
    if matched:
        print(
            f"Klipper's own find_best_shaper: the same pick in {agree} of {matched}; vibrations within {diff_v:.2g}, "
            f"max_accel within {diff_a:.2g} mm/s^2"
        )
    bins = np.array(peak_bins)
    print(
        f"peaks: {bins.size} modes found, frequency error in bins: median {np.median(bins):.3g}, "
        f"95 % {np.quantile(bins, 0.95):.3g}, max {np.max(bins):.3g}"
    )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 200, sys.argv[2] if len(sys.argv) > 2 else None)
