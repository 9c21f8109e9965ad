"""Synthetic printer records in Klipper's formats, with a known truth.

An axis whose toolhead hangs on modes (f_n, zeta, share; shares sum to 1) is driven by a commanded acceleration
a_c(t) held between the generator's samples. The toolhead's acceleration is a_c through the base-excited modes,
sum_i share_i (2 zeta_i w_i s + w_i^2) / (s^2 + 2 zeta_i w_i s + w_i^2) (unit gain at rest), discretised exactly
for the held input (zero-order hold, scipy.signal.cont2discrete), measured by an accelerometer at RATE_HZ with
white noise, gravity on z and a little of x seen on y (a mounting skew). Klipper's files print times ``%.6f`` and
accelerations ``%.6f`` (adxl345.py write_to_file); its resonance CSV ``%.1f`` and ``%.3e``.

Excitations: Klipper's resonance test (resonance_tester.py, VibrationPulseTestGenerator: at frequency f a square
wave of +-accel_per_hz f in quarter periods, f rising hz_per_sec per second; the sweeping overlay, below 1 Hz, is
left out) and a short pulse (a knock) followed by free decay.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from scipy.signal import cont2discrete, lfilter, ss2tf

from optim.identification.modal import IdentifiedMode

Array = NDArray[np.float64]
AXIS = ((42.0, 0.07, 0.6), (71.0, 0.10, 0.4))  # the axis: (f_n Hz, zeta, share)
RATE_HZ = 3200.0
NOISE_MM_S2 = 150.0
GRAVITY_MM_S2 = 9806.65
SKEW = 0.05  # share of x's acceleration seen on y
START_S = 1234.5  # printer time: Klipper's records do not start at 0


def chirp_switches(
    f_start: float,
    f_end: float,
    accel_per_hz: float = 60.0,
    hz_per_sec: float = 1.0,
    sweeping_accel: float = 0.0,
    sweeping_period: float = 1.2,
) -> tuple[Array, Array, float]:
    """Klipper's pulse chirp as (switch times from 0, the level from each, the end): a quarter period at +-accel_per_hz
    f, f rising hz_per_sec per second, with the sweeping overlay (SweepingVibrationsTestGenerator) of
    +-``sweeping_accel``: flips at P sqrt(2)/8, then P (sqrt(2)/8 + 1/4) later, then every P/2."""
    edges, levels = [0.0], []
    f, sign = f_start, 1.0
    while f <= f_end + 1e-6:
        quarter = 1.0 / (4.0 * f)
        a = accel_per_hz * f
        edges += [edges[-1] + quarter, edges[-1] + 2 * quarter]
        levels += [sign * a, -sign * a]
        f += hz_per_sec / (2.0 * f)
        sign = -sign
    times, level, end = np.asarray(edges[:-1]), np.asarray(levels, float), edges[-1]
    if sweeping_accel:
        first = sweeping_period * math.sqrt(2.0) / 8.0
        flips = [first, 2 * first + sweeping_period / 4.0]
        while flips[-1] + sweeping_period / 2.0 < end:
            flips.append(flips[-1] + sweeping_period / 2.0)
        merged = np.sort(np.concatenate([times, flips]))
        vibration = level[np.searchsorted(times, merged, side="right") - 1]
        overlay = sweeping_accel * (-1.0) ** np.arange(1, len(flips) + 1)
        level = vibration + np.concatenate([[sweeping_accel], overlay])[np.searchsorted(flips, merged, side="right")]
        times = merged
    return times, level, end


def chirp(rate_hz: float, f_start: float, f_end: float, accel_per_hz: float = 60.0, hz_per_sec: float = 1.0) -> Array:
    """Klipper's pulse chirp (chirp_switches, no overlay) sampled at ``rate_hz``: each sample holds the level at its
    time."""
    times, level, end = chirp_switches(f_start, f_end, accel_per_hz, hz_per_sec)
    t = np.arange(int(end * rate_hz)) / rate_hz
    return level[np.searchsorted(times, t, side="right") - 1]


def knock(rate_hz: float, duration_s: float, accel_mm_s2: float = 20_000.0, width_s: float = 0.004) -> Array:
    """A short acceleration pulse out and back (+a, -a, each ``width_s``) at 0.1 s, then rest."""
    t = np.arange(int(duration_s * rate_hz)) / rate_hz
    out = np.zeros_like(t)
    out[(t >= 0.1) & (t < 0.1 + width_s)] = accel_mm_s2
    out[(t >= 0.1 + width_s) & (t < 0.1 + 2 * width_s)] = -accel_mm_s2
    return out


def toolhead(command: Array, rate_hz: float, modes: tuple[tuple[float, float, float], ...]) -> Array:
    """The toolhead's acceleration for the held command (exact at the samples)."""
    out = np.zeros_like(command)
    for f, zeta, share in modes:
        w = 2 * math.pi * f
        a = np.array([[0.0, 1.0], [-w * w, -2 * zeta * w]])
        b = np.array([[0.0], [1.0]])
        c = np.array([[w * w, 2 * zeta * w]])
        # y'' + 2 zeta w y' + w^2 y = u, output w^2 y + 2 zeta w y': the base-excited mode's acceleration
        ad, bd, cd, dd, _ = cont2discrete((a, b, c, np.zeros((1, 1))), 1.0 / rate_hz, method="zoh")
        numerator, denominator = ss2tf(ad, bd, cd, dd)
        out += share * lfilter(numerator[0], denominator, command)
    return out


def raw_record(
    command: Array,
    rng: np.random.Generator,
    modes: tuple[tuple[float, float, float], ...] = AXIS,
    noise_mm_s2: float = NOISE_MM_S2,
    rate_hz: float = RATE_HZ,
) -> Array:
    """(samples, 4): time, accel_x, accel_y, accel_z as Klipper measures them (before printing)."""
    x = toolhead(command, rate_hz, modes)
    n = x.size
    t = START_S + np.arange(n) / rate_hz
    noise = rng.normal(0.0, noise_mm_s2, (3, n))
    return np.column_stack([t, x + noise[0], SKEW * x + noise[1], GRAVITY_MM_S2 + noise[2]])


def raw_csv(table: Array) -> str:
    """Klipper's accelerometer CSV (adxl345.py write_to_file): ``#time,accel_x,accel_y,accel_z``, ``%.6f``."""
    body = "\n".join(f"{t:.6f},{x:.6f},{y:.6f},{z:.6f}" for t, x, y, z in table)
    return "#time,accel_x,accel_y,accel_z\n" + body + "\n"


def psd_csv(frequency_hz: Array, psd_axes: Array, max_freq_hz: float = 200.0, shapers: str = "") -> str:
    """Klipper's resonance CSV (save_calibration_data): ``freq,psd_x,psd_y,psd_z,psd_xyz``, ``%.1f`` and ``%.3e``,
    rows below ``max_freq_hz``; ``shapers`` (e.g. ``",shapers:,zv(42.8)"``) appended to the header with an empty
    cell and a 0.5 under them on every row (the cells are not read)."""
    rows = []
    cells = ",," + ",".join(["0.5"] * shapers.count("(")) if shapers else ""
    for k, f in enumerate(frequency_hz):
        if f >= max_freq_hz:
            break
        x, y, z = psd_axes[:, k]
        rows.append(f"{f:.1f},{x:.3e},{y:.3e},{z:.3e},{x + y + z:.3e}{cells}")
    return "freq,psd_x,psd_y,psd_z,psd_xyz" + shapers + "\n" + "\n".join(rows) + "\n"


def rrf_csv(table: Array, rate_hz: float, overflows: int = 0) -> str:
    """RepRapFirmware's accelerometer CSV (M956, Accelerometers.cpp): ``Sample,X,Y,Z``, samples numbered from 0,
    accelerations in g to 3 decimals (10-bit resolution), and the last line ``Rate <samples/s>, overflows <n>``."""
    g = table[:, 1:] / GRAVITY_MM_S2
    body = "\n".join(f"{k},{x:.3f},{y:.3f},{z:.3f}" for k, (x, y, z) in enumerate(g))
    return f"Sample,X,Y,Z\n{body}\nRate {round(rate_hz)}, overflows {overflows}\n"


Modes = tuple[tuple[float, float, float], ...]
KNOCK_END_S = 0.108  # knock()'s end: 0.1 s + 2 x 4 ms
MATCH = 0.05  # an identified mode within this (relative) of a true one is its estimate


def estimate_of(fitted: Sequence[IdentifiedMode], f_hz: float) -> IdentifiedMode | None:
    """The identified mode nearest the true ``f_hz`` if within MATCH of it (its estimate), else None (missed)."""
    near = min(fitted, key=lambda m: abs(m.natural_frequency_hz - f_hz), default=None)
    return near if near is not None and abs(near.natural_frequency_hz - f_hz) <= MATCH * f_hz else None


def draw_modes(rng: np.random.Generator) -> Modes:
    """One or two modes (f Hz, zeta, share), as issue 27's acceptance draws them: the first at 20-120 Hz, the second
    (half the axes) 1.3-2.5 times higher up to 200 Hz, damping ratios 0.02-0.15."""
    f1, z1 = float(rng.uniform(20.0, 120.0)), float(rng.uniform(0.02, 0.15))
    if rng.random() < 0.5:
        return ((f1, z1, 1.0),)
    share = float(rng.uniform(0.2, 0.5))
    f2, z2 = min(f1 * float(rng.uniform(1.3, 2.5)), 200.0), float(rng.uniform(0.02, 0.15))
    return ((f1, z1, 1.0 - share), (f2, z2, share))


def knock_case(seed: int, fmt: str) -> tuple[Modes, float, str]:
    """Seeded knock record ``seed`` (a 2 x 4 ms knock at 0.1 s, 1 s at RATE_HZ, noise std 0-30 % of the free decay's
    peak) printed as Klipper's (``klipper_raw``) or RepRapFirmware's (``rrf_accelerometer``) accelerometer CSV:
    (the true modes, the noise's share of the decay's peak, the CSV text)."""
    rng = np.random.default_rng(7000 + seed)
    modes = draw_modes(rng)
    command = knock(RATE_HZ, 1.0)
    peak = float(np.max(np.abs(toolhead(command, RATE_HZ, modes)[int(KNOCK_END_S * RATE_HZ) :])))
    share = float(rng.uniform(0.0, 0.3))
    table = raw_record(command, rng, modes, noise_mm_s2=max(share * peak, 1e-9))
    text = raw_csv(np.round(table, 6)) if fmt == "klipper_raw" else rrf_csv(table, RATE_HZ)
    return modes, share, text


SWEEP_MAX_HZ = 200.0  # FREQ_END of the seeded sweeps: every drawn mode (up to 200 Hz) is swept through
SWEEPING_ACCEL = 400.0  # Klipper's sweeping_accel default


def held_response(switches: tuple[Array, Array, float], modes: Modes = AXIS, rate_hz: float = RATE_HZ) -> Array:
    """The toolhead's acceleration for a command given by its switches (chirp_switches), exact at the samples for
    switches between them (models.held_input, checked against an oversampled hold in
    tests/models/test_held_input.py)."""
    from models.held_input import base_excited_response

    times, level, end = switches
    n = int(end * rate_hz)
    return sum(
        (share * base_excited_response(f, zeta, rate_hz, times, level, n) for f, zeta, share in modes), np.zeros(n)
    )


def with_noise(x: Array, rng: np.random.Generator, noise_mm_s2: float = NOISE_MM_S2, rate_hz: float = RATE_HZ) -> Array:
    """raw_record's table for the toolhead's acceleration ``x``."""
    noise = rng.normal(0.0, max(noise_mm_s2, 1e-9), (3, x.size))
    t = START_S + np.arange(x.size) / rate_hz
    return np.column_stack([t, x + noise[0], SKEW * x + noise[1], GRAVITY_MM_S2 + noise[2]])


def held_record(
    switches: tuple[Array, Array, float],
    rng: np.random.Generator,
    modes: Modes = AXIS,
    noise_mm_s2: float = NOISE_MM_S2,
    rate_hz: float = RATE_HZ,
) -> Array:
    """raw_record's table for a command given by its switches (held_response)."""
    return with_noise(held_response(switches, modes, rate_hz), rng, noise_mm_s2, rate_hz)


def sweep_table(seed: int) -> tuple[Modes, float, Array]:
    """Seeded resonance test ``seed``: Klipper's test from 5 Hz to SWEEP_MAX_HZ at 1 Hz/s with its sweeping overlay
    (held_response), at RATE_HZ, noise std 0-30 % of the response's peak: (the true modes, the noise's share, the
    record as raw_record's table)."""
    rng = np.random.default_rng(9000 + seed)
    modes = draw_modes(rng)
    x = held_response(chirp_switches(5.0, SWEEP_MAX_HZ, sweeping_accel=SWEEPING_ACCEL), modes)
    noise_share = float(rng.uniform(0.0, 0.3))
    return modes, noise_share, with_noise(x, rng, max(noise_share * float(np.max(np.abs(x))), 1e-9))


def sweep_case(seed: int, fmt: str) -> tuple[Modes, float, str]:
    """sweep_table(seed) as the raw record (``klipper_raw``) or as Klipper's resonance CSV of its PSD
    (``klipper_psd``): (the true modes, the noise's share, the CSV text)."""
    from optim.families.input_shaped.calibration import klipper_psd

    modes, noise_share, table = sweep_table(seed)
    if fmt == "klipper_raw":
        return modes, noise_share, raw_csv(np.round(table, 6))
    frequency, psd = klipper_psd(table[:, 0], table[:, 1:].T)
    return modes, noise_share, psd_csv(frequency, psd)
