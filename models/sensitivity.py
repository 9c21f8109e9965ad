"""Robustness of a command: residual vibration when the real mode differs from the estimate.

For a single mode G(s) = (2 zeta w s + w^2)/(s^2 + 2 zeta w s + w^2) the free response left when
the command ends is sum_k exp(lambda (t_e - t_k)) J_k (see models.simulation), so the residual
of any piecewise-polynomial command at any (w, zeta) is one dot product over its breakpoints:
no simulation per frequency. ``residual`` holds fractions of the move (0.05 = 5 %), ``amplitude`` the
load's residual amplitude itself; ``residual_envelope`` bounds a command's residual by the sum of what
each of its breakpoints excites (the denominator of the percentage vibration).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from models.commands import PiecewiseCommand
from models.errors import InvalidParameter

_CHUNK_ELEMENTS = 262_144  # bounds the (frequencies x breakpoints) matrices: 4 MiB each (complex), ~30 MiB in all
_ROUNDOFF = 4 * np.finfo(float).eps
_BAND_RTOL = 1e-9
RELIABLE_FRACTION = 1e-6  # a residual whose round-off could exceed this fraction of the move is refused


@dataclass(frozen=True)
class Sensitivity:
    frequency_ratio: NDArray[np.float64]
    damping_ratio: NDArray[np.float64]  # one per row of residual
    residual: NDArray[np.float64]  # shape (damping ratios, frequency ratios), fraction of the move
    quantity: str  # "position" (rest-to-rest) or "velocity" (rest-to-velocity)
    amplitude: NDArray[np.float64]  # the same, in the load's units (position, or velocity)


def _free_sums(
    command: PiecewiseCommand, natural_frequency_rad_s: ArrayLike, damping_ratio: ArrayLike, derivative: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """For each (w, zeta): |sum_k F_k| and sum_k |F_k|, where F_k is the free response (position if
    derivative = 0, velocity if 1) the command's jumps at breakpoint k leave at the command's end,
    on the mode plant."""
    w = np.asarray(natural_frequency_rad_s, dtype=float).ravel()
    z = np.asarray(damping_ratio, dtype=float).ravel()
    w, z = np.broadcast_arrays(w, z)
    poles = -z * w + 1j * w * np.sqrt(1.0 - z * z)
    # Residue of (2 zeta w s + w^2)/(s^2 + 2 zeta w s + w^2) at the upper pole.
    residues = (2 * z * w * poles + w * w) / (2 * poles + 2 * z * w)
    end = command.end_index()
    jumps = command.jumps()[:, : end + 1]
    keep = np.flatnonzero(np.any(jumps != 0.0, axis=0))
    jumps = jumps[:, keep]
    age = command.time_s[end] - command.time_s[keep]
    total = np.empty(w.size)
    magnitudes = np.empty(w.size)
    rows = max(1, _CHUNK_ELEMENTS // max(1, keep.size))
    for start in range(0, w.size, rows):  # chunks of frequencies, bounded memory
        lam = poles[start : start + rows, None]
        drive = sum(jumps[m][None, :] / lam ** (m + 1) for m in range(jumps.shape[0]))
        terms = np.exp(lam * age[None, :]) * drive
        gain = np.abs(2.0 * residues[start : start + rows] * poles[start : start + rows] ** derivative)
        total[start : start + rows] = gain * np.abs(np.sum(terms, axis=1))
        magnitudes[start : start + rows] = gain * np.sum(np.abs(terms), axis=1)
    return total, magnitudes


def mode_residuals(
    command: PiecewiseCommand, natural_frequency_rad_s: ArrayLike, damping_ratio: ArrayLike, derivative: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Amplitude of the load's free oscillation (position if derivative = 0, velocity if 1)
    when the command ends, for each (w, zeta) pair, on the mode plant; and a bound on its
    round-off error."""
    total, magnitudes = _free_sums(command, natural_frequency_rad_s, damping_ratio, derivative)
    # The sum cancels terms far larger than itself when the mode is slow next to the command
    # (the 1/lambda^(m+1) factors): its round-off is about eps times the sum of magnitudes.
    return total, _ROUNDOFF * magnitudes


def residual_envelope(
    command: PiecewiseCommand, natural_frequency_rad_s: ArrayLike, damping_ratio: ArrayLike, derivative: int
) -> NDArray[np.float64]:
    """sum_k |F_k|: the residual the command's breakpoints would leave if none cancelled another. For
    acceleration steps delta a_k it is sum_k |delta a_k| exp(-sigma (T - t_k)) / (w w_d) (4 a / w^2 for an
    undamped bang-bang move), for a step of height D it is D w / w_d (the mode's zero, |2 zeta w lambda +
    w^2| = w^2, changes no magnitude)."""
    return _free_sums(command, natural_frequency_rad_s, damping_ratio, derivative)[1]


def move_scale(command: PiecewiseCommand, position: bool | None = None) -> tuple[str, float]:
    """What the residual is measured against: the displacement, or the final speed if the
    command ends moving (then the velocity residual is the one that matters). ``position`` True: the
    displacement whatever the end (a position move that ends in motion, issue 25's final_state)."""
    end = command.end_index()
    if position:
        return "position", abs(float(command.derivatives[0, end] - command.derivatives[0, 0]))
    final_velocity = float(command.derivatives[1, end]) if command.degree >= 1 else 0.0
    peak = float(np.max(np.abs(command.derivatives[1]))) if command.degree >= 1 else 0.0
    if abs(final_velocity) > 1e-9 * peak:  # round-off of a stop is no final speed
        return "velocity", abs(final_velocity)
    return "position", abs(float(command.derivatives[0, end] - command.derivatives[0, 0]))


def sensitivity(
    command: PiecewiseCommand,
    natural_frequency_rad_s: float,
    frequency_ratios: ArrayLike,
    damping_ratios: ArrayLike,
    position: bool | None = None,
) -> Sensitivity:
    """Residual (fraction of the move) versus w/w_e for each damping ratio (``position``: see move_scale)."""
    quantity, scale = move_scale(command, position)
    ratios = np.asarray(frequency_ratios, dtype=float)
    zetas = np.atleast_1d(np.asarray(damping_ratios, dtype=float))
    w = np.repeat(ratios[None, :] * natural_frequency_rad_s, zetas.size, axis=0)
    z = np.repeat(zetas[:, None], ratios.size, axis=1)
    amplitudes, error = mode_residuals(command, w.ravel(), z.ravel(), 0 if quantity == "position" else 1)
    scale = scale if scale > 0 else 1.0
    bad = ~np.isfinite(amplitudes) | (error > RELIABLE_FRACTION * scale)
    if np.any(bad):
        worst = float(np.max(ratios[np.any(bad.reshape(zetas.size, ratios.size), axis=0)]))
        raise InvalidParameter(
            "sensitivity",
            worst,
            f"at frequency ratios up to {worst:.3g} the mode is so slow next to the command that the residual "
            f"cannot be computed to {RELIABLE_FRACTION:g} of the move; evaluate higher ratios",
        )
    amplitude = amplitudes.reshape(zetas.size, ratios.size)
    return Sensitivity(ratios, zetas, amplitude / scale, quantity, amplitude)


def band_below(
    ratios: ArrayLike, residual: ArrayLike, threshold: float = 0.05, centre: float = 1.0
) -> tuple[float | None, float | None] | None:
    """The interval of frequency ratios around ``centre`` where the residual stays <= threshold,
    with linearly interpolated ends; an end is None where the band reaches the end of the
    evaluated ratios (it extends beyond them). None if the residual exceeds it at the centre."""
    r = np.asarray(ratios, dtype=float)
    v = np.asarray(residual, dtype=float)
    inside = threshold * (1.0 + _BAND_RTOL)  # a design at the threshold (EI at its nominal) is inside
    order = np.argsort(r)
    r, v = r[order], v[order]
    i = int(np.clip(np.searchsorted(r, centre), 1, r.size - 1))
    k = i - 1 if abs(r[i - 1] - centre) <= abs(r[i] - centre) else i
    if v[k] > inside:
        return None
    above = np.flatnonzero(v > inside)
    left, right = above[above < k], above[above > k]
    lo = int(left[-1]) + 1 if left.size else 0
    hi = int(right[0]) - 1 if right.size else r.size - 1

    def cross(a: int, b: int) -> float:
        return float(r[a] + (threshold - v[a]) * (r[b] - r[a]) / (v[b] - v[a]))

    low = cross(lo - 1, lo) if lo > 0 else None
    high = cross(hi, hi + 1) if hi < r.size - 1 else None
    return low, high
