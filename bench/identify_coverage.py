"""Benchmark (issue 27's acceptance): identification of seeded knock records and resonance tests, in a printer's
formats.

``python bench/identify_coverage.py [N] [FIRST] [FORMAT ...]`` makes N (default 200) seeded knock records (seeds
FIRST.., default 0; the rules were tuned on 0-199, 200-399 check them)
(tests/printer_records.knock_case: a 2 x 4 ms pulse of 20,000 mm/s^2 at 0.1 s, then 0.9 s of rest, measured at 3200 Hz)
of axes with one or two modes (the first at 20 to 120 Hz, the second 1.3 to 2.5 times higher up to 200 Hz, damping
ratios 0.02 to 0.15; half the records have two) and white noise of std 0 to 30 % of the free decay's peak (after
the pulse), printed in each FORMAT (``klipper_raw``, Klipper's accelerometer CSV; ``rrf_accelerometer``,
RepRapFirmware's), and seeded resonance tests (tests/printer_records.sweep_case: Klipper's test from 5 to 200 Hz at
1 Hz/s with its sweeping overlay, noise std 0 to 30 % of the response's peak, the same modes' draw) as the raw record
(``sweep_raw``) or as Klipper's resonance CSV (``sweep_psd``); default all four. Each is identified as
POST /v1/identify does (app.services.identify.identify_csv; sweep_max_freq=200 for the CSV, the raw record's band
read off it). For each format it prints:

- the modes missed (a refused record, or no identified mode within 5 % of a true one);
- for the modes found, the relative errors of the natural frequency and the damping ratio (median, 95 %, max),
  the share within the issue's 0.5 % and 15 % (over all, and by the record's noise), and how often the 95 %
  intervals hold the truth (the issue: 90 %);
- the first failures (seed, truth, estimate, noise share).
"""

from __future__ import annotations

import asyncio
import sys
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from app.schemas.identify import MeasurementParams  # noqa: E402
from app.services.identify import identify_csv  # noqa: E402
from models.errors import InvalidParameter  # noqa: E402
from tests.printer_records import SWEEP_MAX_HZ, estimate_of, knock_case, sweep_case  # noqa: E402

SWEEPS = {"sweep_raw": "klipper_raw", "sweep_psd": "klipper_psd"}  # a resonance test's record, and its CSV


PEAKS: list[
    tuple[bool, bool, bool]
] = []  # a sweep's peaks against the truth: (interval holds f, f within 0.5 %, zeta 15 %)


def _score_peaks(modes: tuple[tuple[float, float, float], ...], peaks: list[dict[str, Any]]) -> None:
    """The answer's peaks (a spectrum's only estimate before its modes were fitted: the bin's half-width as the
    frequency's interval, the half-power damping) scored like the modes, into PEAKS."""
    for f, zeta, _ in modes:
        near = min(peaks, key=lambda p: abs(float(p["frequency_hz"]) - f), default=None)
        if near is None or abs(float(near["frequency_hz"]) - f) > 0.05 * f:
            PEAKS.append((False, False, False))
            continue
        lo, hi = near["frequency_interval_hz"]
        estimate, damping = float(near["frequency_hz"]), float(near["damping_ratio_half_power"])
        PEAKS.append((lo <= f <= hi, abs(estimate / f - 1) <= 0.005, abs(damping / zeta - 1) <= 0.15))


def identified(seed: int, fmt: str) -> tuple[tuple[tuple[float, float, float], ...], float, list[SimpleNamespace]]:
    """(the true modes, the noise share, the modes POST /v1/identify answers) for record ``seed`` in ``fmt`` (a
    sweep's peaks scored into PEAKS)."""
    if fmt in SWEEPS:
        modes, share, text = sweep_case(seed, SWEEPS[fmt])
        # a raw record's band and rate are read off it; a CSV's are stated (its FREQ_END)
        params = MeasurementParams(**({"sweep_max_freq": SWEEP_MAX_HZ} if fmt == "sweep_psd" else {}))
    else:
        modes, share, text = knock_case(seed, fmt)
        params = MeasurementParams()
    body = asyncio.run(identify_csv(text, params, None, max_rows=1_000_000))
    if fmt in SWEEPS:
        _score_peaks(modes, body["peaks"])
    return modes, share, [SimpleNamespace(**m) for m in body["modes"]]


def run(count: int, fmt: str, first: int = 0) -> None:
    f_err: list[float] = []
    z_err: list[float] = []
    noise: list[float] = []  # the record's noise share, per mode found
    covered_f = covered_z = missed = total = 0
    failures: list[str] = []
    began = time.perf_counter()
    for seed in range(first, first + count):
        try:
            modes, share, found = identified(seed, fmt)
        except InvalidParameter as exc:
            modes, share = (sweep_case if fmt in SWEEPS else knock_case)(seed, SWEEPS.get(fmt, fmt))[:2]
            missed += len(modes)
            total += len(modes)
            failures.append(f"#{seed} refused (noise {share:.2f}, modes {[round(m[0], 1) for m in modes]}): {exc}")
            continue
        total += len(modes)
        for f, zeta, _ in modes:
            near = estimate_of(found, f)
            if near is None:
                missed += 1
                failures.append(
                    f"#{seed} {f:.2f} Hz missed (found {[round(m.natural_frequency_hz, 2) for m in found]})"
                )
                continue
            f_err.append(abs(near.natural_frequency_hz / f - 1.0))
            noise.append(share)
            z_err.append(abs(near.damping_ratio / zeta - 1.0))
            in_f = near.natural_frequency_ci_hz[0] <= f <= near.natural_frequency_ci_hz[1]
            in_z = near.damping_ratio_ci[0] <= zeta <= near.damping_ratio_ci[1]
            covered_f, covered_z = covered_f + in_f, covered_z + in_z
            if not (in_f and in_z):
                failures.append(
                    f"#{seed} {f:.2f} Hz zeta {zeta:.4f}: {near.natural_frequency_hz:.3f} Hz zeta "
                    f"{near.damping_ratio:.4f}, outside its interval (noise {share:.2f})"
                )
    ef, ez = np.array(f_err), np.array(z_err)
    print(f"{fmt}: {count} records, {total} modes, {missed} missed, {time.perf_counter() - began:.0f} s")
    if ef.size:
        print(
            f"  f error median {np.median(ef):.3%}, 95 % {np.quantile(ef, 0.95):.3%}, max {ef.max():.2%}; within 0.5 % "
            f"{np.mean(ef <= 0.005):.1%}"
        )
        print(
            f"  zeta error median {np.median(ez):.2%}, 95 % {np.quantile(ez, 0.95):.1%}, max {ez.max():.1%}; within "
            f"15 % {np.mean(ez <= 0.15):.1%}"
        )
        print(f"  95 % intervals hold the truth: f {covered_f / ef.size:.1%}, zeta {covered_z / ez.size:.1%}")
        shares = np.array(noise)
        for low, high in ((0.0, 0.05), (0.05, 0.1), (0.1, 0.2), (0.2, 0.3)):
            band = (shares >= low) & (shares < high)
            if np.any(band):
                print(
                    f"  noise {low:.0%}-{high:.0%} ({np.count_nonzero(band)} modes): f within 0.5 % "
                    f"{np.mean(ef[band] <= 0.005):.1%}, zeta within 15 % {np.mean(ez[band] <= 0.15):.1%}"
                )
    if PEAKS:
        held, close, damped = np.mean(np.array(PEAKS), axis=0)
        print(
            f"  the peaks alone (the answer's estimate before the fit): the bin holds f {held:.1%}, f within 0.5 % "
            f"{close:.1%}, half-power zeta within 15 % {damped:.1%} (of {len(PEAKS)} modes)"
        )
        PEAKS.clear()
    lost = [line for line in failures if "missed" in line or "refused" in line]  # every one: they are few
    for line in lost + [line for line in failures if line not in lost][:12]:
        print("   " + line[:200])


def main(argv: list[str]) -> int:
    count = int(argv[0]) if argv else 200
    first = int(argv[1]) if len(argv) > 1 and argv[1].isdigit() else 0
    for fmt in [a for a in argv[1:] if not a.isdigit()] or ["klipper_raw", "rrf_accelerometer", *SWEEPS]:
        run(count, fmt, first)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
