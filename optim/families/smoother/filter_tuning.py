"""Tuning a smoother to a vibration mode (Biagiotti, Melchiorri and Moriello 2020, Secs. III-IV).

A filter cancels a mode with pole sigma_p + j Omega when its zeros reach it. S and S_sigma have zeros at
sigma +- j (2m+1) pi/T for m >= 1 (the first pair is cancelled by the filter's own poles), so
T = (2m+1) pi/Omega, m >= 1, with sigma = -zeta omega_n for S_sigma (eqs. 11, 13, 15 as corrected in
PAPER-NOTES: eqs. 13 and 15 allow T = 3 k pi/Omega, which is wrong for even k). M and M_sigma have zeros
at sigma +- j 2 k pi/T: T = 2 k pi/Omega. The undamped filters cancel a damped mode only approximately.
Whether a filter cancels a mode is read from |F(p)|, the percent residual vibration of Sec. IV / 100.
"""

from __future__ import annotations

import math

import numpy as np

from models.errors import InvalidParameter
from models.plants import Mode
from models.smoothers import DAMPED, SINUSOIDAL, Chain, FilterKind, Smoother, residual_fraction

__all__ = [
    "VIBRATION_FREE_TOLERANCE",
    "cancels",
    "same_time_ratio",
    "tuned_duration_s",
    "tuned_filter",
    "vibration_free_durations_s",
]

VIBRATION_FREE_TOLERANCE = 1e-6  # |F(p)| below this: the filter's zero sits on the mode


def tuned_duration_s(kind: FilterKind, mode: Mode, multiple: int = 1) -> float:
    """The shortest duration (multiple = 1) whose zeros reach the mode's damped frequency Omega:
    (2m+1) pi/Omega with m = multiple for S and S_sigma (eqs. 11, 13 corrected), 2 k pi/Omega with
    k = multiple for M and M_sigma."""
    if multiple < 1:
        raise InvalidParameter("multiple", multiple, "must be >= 1")
    omega = mode.damped_frequency_rad_s
    if kind in SINUSOIDAL:
        return (2 * multiple + 1) * math.pi / omega
    return 2 * multiple * math.pi / omega


def tuned_filter(kind: FilterKind, mode: Mode, duration_s: float | None = None) -> Smoother:
    """A filter tuned to the mode: its duration (unless given) and, for S_sigma and M_sigma, the decay
    rate sigma = -zeta omega_n (eq. 11)."""
    duration = tuned_duration_s(kind, mode) if duration_s is None else duration_s
    decay = mode.decay_rate_1_s if kind in DAMPED else 0.0
    return Smoother(kind, duration, decay)


def cancels(smoother: Smoother, mode: Mode, tolerance: float = VIBRATION_FREE_TOLERANCE) -> bool:
    """Whether a zero of the filter sits on the mode's pole: |F(p)| <= tolerance (the residual as a
    fraction of the unfiltered one, at the same time after the end)."""
    return same_time_ratio(Chain((smoother,)), mode) <= tolerance


def same_time_ratio(chain: Chain, mode: Mode) -> float:
    """|F(p)|: the residual envelope with the chain over the unfiltered one at the same time after the
    end (the percent residual vibration of Sec. IV, / 100); inf where it overflows (very long chains)."""
    with np.errstate(over="ignore", invalid="ignore"):
        value = residual_fraction(chain, mode.pole) * np.exp(-mode.pole.real * chain.total_duration_s)
    return float(value) if np.isfinite(value) else math.inf


def vibration_free_durations_s(kind: FilterKind, mode: Mode, count: int = 3) -> list[float]:
    """The ``count`` shortest durations of a filter of this kind that cancel the mode exactly.

    S_sigma: 3, 5, 7, ... pi/Omega (never an even multiple); M_sigma: 2, 4, 6, ... pi/Omega. The
    undamped S and M cancel only an undamped mode: none are offered when zeta > 0.
    """
    if kind not in DAMPED and mode.damping_ratio > 0.0:
        return []
    return [tuned_duration_s(kind, mode, k) for k in range(1, count + 1)]
