"""Independent references for the input-shaper tests.

They share nothing with models.shapers or optim.families.input_shaped.shapers:

- ``v_by_simulation``: the percentage vibration V of Sec. 3.1 measured by two exact simulations of
  a mode plant (models.simulation): the residual amplitude left when the shaped velocity step ends
  (at t_n) over the residual amplitude of the plain step when it is applied. That is the paper's
  V = exp(-zeta w t_n) sqrt(C^2 + S^2) (and Singhose's): the exp factor turns sqrt(C^2 + S^2), the
  ratio of amplitudes at the same time, into a comparison with the unshaped step at the end of the
  shaped one.
- ``klipper_*``: the shapers of Klipper's klippy/extras/shaper_defs.py (Klipper3d/klipper), as
  users see them, transcribed here. Their EI, 2-hump and 3-hump EI are Singhose's polynomial fits
  in the damping ratio (EI also in the tolerance).
- ``discrete_rate_limiter``: the drive's limiter as a drive implements it, one small time step at
  a time (y += clip(u - y, -a dt, a dt)); its error is of order a dt.
"""

from __future__ import annotations

import math

import numpy as np

from models.commands import PiecewiseCommand
from models.metrics import metrics
from models.plants import ModePlant
from models.simulation import simulate


def v_by_simulation(amplitudes, times_s, natural_frequency_rad_s: float, damping_ratio: float) -> float:
    a = np.asarray(amplitudes, dtype=float)
    t = np.asarray(times_s, dtype=float)
    plant = ModePlant(natural_frequency_rad_s / (2 * math.pi), damping_ratio)
    staircase = PiecewiseCommand.from_samples(
        np.append(t, t[-1] + 1.0), np.append(np.cumsum(a), a.sum()), 1, hold="zero"
    )
    single = PiecewiseCommand.from_samples(np.array([0.0, 1.0]), np.array([1.0, 1.0]), 1, hold="zero")
    shaped = metrics(simulate(plant, staircase)).residual_velocity_amplitude
    plain = metrics(simulate(plant, single)).residual_velocity_amplitude
    return shaped / plain


def klipper_mzv(frequency_hz: float, zeta: float):
    df = math.sqrt(1 - zeta**2)
    k = math.exp(-0.75 * zeta * math.pi / df)
    t_d = 1 / (frequency_hz * df)
    a1 = 1 - 1 / math.sqrt(2)
    return [a1, (math.sqrt(2) - 1) * k, a1 * k * k], [0.0, 0.375 * t_d, 0.75 * t_d]


def klipper_ei(frequency_hz: float, zeta: float, v_tol: float):
    df = math.sqrt(1 - zeta**2)
    t_d = 1 / (frequency_hz * df)
    dr = zeta
    a1 = (0.24968 + 0.24961 * v_tol) + ((0.80008 + 1.23328 * v_tol) + (0.49599 + 3.17316 * v_tol) * dr) * dr
    a3 = (0.25149 + 0.21474 * v_tol) + ((-0.83249 + 1.41498 * v_tol) + (0.85181 - 4.90094 * v_tol) * dr) * dr
    a2 = 1 - a1 - a3
    t2 = (
        0.4999
        + (
            ((0.46159 + 8.57843 * v_tol) * v_tol)
            + (((4.26169 - 108.644 * v_tol) * v_tol) + ((1.75601 + 336.989 * v_tol) * v_tol) * dr) * dr
        )
        * dr
    )
    return [a1, a2, a3], [0.0, t2 * t_d, t_d]


_HUMP_FITS = {
    2: (
        [
            [0, 0, 0, 0],
            [0.49890, 0.16270, -0.54262, 6.16180],
            [0.99748, 0.18382, -1.58270, 8.17120],
            [1.49920, -0.09297, -0.28338, 1.85710],
        ],
        [
            [0.16054, 0.76699, 2.26560, -1.22750],
            [0.33911, 0.45081, -2.58080, 1.73650],
            [0.34089, -0.61533, -0.68765, 0.42261],
            [0.15997, -0.60246, 1.00280, -0.93145],
        ],
    ),
    3: (
        [
            [0, 0, 0, 0],
            [0.49974, 0.23834, 0.44559, 12.4720],
            [0.99849, 0.29808, -2.36460, 23.3990],
            [1.49870, 0.10306, -2.01390, 17.0320],
            [1.99960, -0.28231, 0.61536, 5.40450],
        ],
        [
            [0.11275, 0.76632, 3.29160, -1.44380],
            [0.23698, 0.61164, -2.57850, 4.85220],
            [0.30008, -0.19062, -2.14560, 0.13744],
            [0.23775, -0.73297, 0.46885, -2.08650],
            [0.11244, -0.45439, 0.96382, -1.46000],
        ],
    ),
}


def klipper_hump_ei(humps: int, frequency_hz: float, zeta: float):
    """Klipper's 2-hump / 3-hump EI (5 % tolerance): cubic fits in zeta, times in natural periods."""
    t_coef, a_coef = _HUMP_FITS[humps]
    times = [sum(c * zeta**p for p, c in enumerate(row)) / frequency_hz for row in t_coef]
    amps = [sum(c * zeta**p for p, c in enumerate(row)) for row in a_coef]
    return amps, times


def discrete_rate_limiter(u: np.ndarray, dt: float, limit: float) -> np.ndarray:
    y = np.empty_like(u)
    current = 0.0
    step = limit * dt
    for k, target in enumerate(u):  # the drive's own loop, sample by sample (reference only)
        current += min(max(target - current, -step), step)
        y[k] = current
    return y
