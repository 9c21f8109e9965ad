"""Closed-form weights of a piecewise-constant command: what each constant piece contributes.

The command's highest derivative u (the acceleration, or with a jerk limit the jerk; order q = 2 or 3)
is constant on pieces [a_i, b_i]. Everything the time-optimal problem constrains is linear in those
constants, with exact weights:

- the motor's derivative of order m < q at time t: sum_i u_i ((t - a_i)_+^r - (t - b_i)_+^r) / r!,
  r = q - m (repeated integration of a box);
- the residual of a mode with pole lambda at the end T, and its derivatives in lambda (Singh and
  Vadali 1993; the frequency-domain view of Dhanda, Vaughan and Singhose 2009, "Vibration reduction
  using near time-optimal commands"): F_n = int u(t) s^n exp(lambda s) dt, s = T - t, whose piece
  weights are G_n(T - a_i) - G_n(T - b_i) with the antiderivative
  G_n(s) = exp(lambda s) sum_k (-1)^k n!/(n-k)! s^(n-k) / lambda^(k+1).

F_0 = 0 (the Laplace transform of u vanishing at the pole) is zero residual for a command that ends
at rest in every derivative below q; F_0 = F_1 = 0 also zeroes the derivative in frequency (ZVD-like).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
CArray = NDArray[np.complex128]


def integrated_box(t: Array, start: Array, end: Array, r: int) -> Array:
    """((t - start)_+^r - (t - end)_+^r) / r!: the r-fold integral at ``t`` of a unit box on [start, end]
    (rows: times, columns: pieces)."""
    if r == 0:  # the box itself, right-continuous
        box: Array = ((t[:, None] >= start[None, :]) & (t[:, None] < end[None, :])).astype(float)
        return box
    lead = np.maximum(t[:, None] - start[None, :], 0.0)
    tail = np.maximum(t[:, None] - end[None, :], 0.0)
    out: Array = (lead**r - tail**r) / math.factorial(r)
    return out


def exponential_moment(poles: CArray, start: Array, end: Array, total_s: float, n: int) -> CArray:
    """int_start^end (T - t)^n exp(lambda (T - t)) dt for every pole (rows) and piece (columns)."""
    lam = poles[:, None]
    s_hi = total_s - start[None, :]
    s_lo = total_s - end[None, :]
    if n == 0:  # exp(lam s_lo) (exp(lam h) - 1) / lam, without cancellation on short pieces
        h = s_hi - s_lo
        out0: CArray = np.exp(lam * s_lo) * np.expm1(lam * h) / lam
        return out0

    def antiderivative(s: Array) -> CArray:
        acc = np.zeros(np.broadcast(lam, s).shape, dtype=complex)
        for k in range(n + 1):
            acc = acc + (-1) ** k * math.factorial(n) / math.factorial(n - k) * s ** (n - k) / lam ** (k + 1)
        result: CArray = np.exp(lam * s) * acc
        return result

    out: CArray = antiderivative(s_hi) - antiderivative(s_lo)
    return out


def mode_poles(natural_frequency_rad_s: Array, damping_ratio: Array) -> CArray:
    """The upper poles -zeta w + i w sqrt(1 - zeta^2)."""
    w, z = np.broadcast_arrays(np.asarray(natural_frequency_rad_s, float), np.asarray(damping_ratio, float))
    poles: CArray = -z * w + 1j * w * np.sqrt(1.0 - z * z)
    return poles


def amplitude_gain(poles: CArray, natural_frequency_rad_s: Array, damping_ratio: Array, derivative: int) -> Array:
    """|2 r lambda^derivative| / |lambda|^2: the free oscillation's amplitude per unit |F_0| of the
    acceleration on the unit-gain mode (2 zeta w s + w^2)/(s^2 + 2 zeta w s + w^2), r its residue at lambda
    (as models.sensitivity): position (derivative 0) or velocity (1) amplitude at the command's end."""
    w, z = natural_frequency_rad_s, damping_ratio
    residue = (2 * z * w * poles + w * w) / (2 * poles + 2 * z * w)
    gain: Array = np.abs(2.0 * residue * poles**derivative) / np.abs(poles) ** 2
    return gain
