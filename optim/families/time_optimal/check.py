"""The band check on a dense grid of frequencies (and damping ratios), for any piecewise-constant command.

|F_0| of the acceleration at each (w, zeta) against the band's bound c = V_max / 100 x the rigid
reference's residual envelope / the mode's amplitude gain (weights.amplitude_gain), so that
amplitude / envelope <= V_max / 100 there. Used as the cutting-plane oracle of the search (the worst
violating points become LP cuts) and on the final command.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from models.errors import InvalidParameter
from models.sensitivity import residual_envelope
from optim.families.time_optimal.lp import Cut
from optim.families.time_optimal.types import Band, Spec
from optim.families.time_optimal.weights import amplitude_gain, mode_poles

Array = NDArray[np.float64]
DENSE_POINTS = 1500
CHECK_MARGIN = 1e-6  # the search's check asks |F_0| <= (1 - this) bound: the independent check then passes
INITIAL_POINTS = 9
# Moments (complex128) per block of worst_ratios: 16 MiB a temporary, about six of them alive at once.
MOMENT_BLOCK_ELEMENTS = 1 << 20
RESTART = 32  # worst_ratios' running product starts again from an exponential every this many points of a row


@dataclass(frozen=True)
class BandGrid:
    """A band's (w, zeta) points, their poles and bounds on |F_0|."""

    band: Band
    omega: Array
    zeta: Array
    poles: NDArray[np.complex128]
    bound: Array
    row_length: int  # points per damping ratio (a row of the grid), its frequencies evenly spaced

    def cuts(self, index: NDArray[np.intp]) -> list[Cut]:
        return [Cut(complex(self.poles[i]), float(self.bound[i])) for i in index]


def dense_points(band: Band, duration_s: float, per_radian: float = 20.0, cap: int = 20_000) -> int:
    """Frequencies for a dense check of ``band``: at least DENSE_POINTS, and about ``per_radian`` per radian of
    the residual's phase across it (the phase of F_0 turns by about T dw), capped."""
    span = (band.high_rad_s - band.low_rad_s) * duration_s
    return int(min(cap, max(DENSE_POINTS, math.ceil(span * per_radian) + 1)))


def band_grid(spec: Spec, band: Band, points: int) -> BandGrid:
    omega1 = np.linspace(band.low_rad_s, band.high_rad_s, points)
    zetas = np.asarray(band.damping_ratios, dtype=float)
    omega, zeta = (a.ravel() for a in np.meshgrid(omega1, zetas))
    poles = mode_poles(omega, zeta)
    derivative = 0 if spec.rest_to_rest else 1
    envelope = residual_envelope(spec.reference, omega, zeta, derivative)
    gain = amplitude_gain(poles, omega, zeta, derivative)
    bound = band.max_percentage_vibration / 100.0 * envelope / gain
    if not np.all(np.isfinite(bound) & (bound > 0.0)):  # the LP's band rows are divided by it
        raise InvalidParameter(
            "robustness.max_percentage_vibration",
            band.max_percentage_vibration,
            "the band's bound is not a positive finite amplitude in double precision at every frequency of the band "
            "(a bound or a band too far from the move's scale)",
        )
    return BandGrid(band, omega, zeta, poles, bound, points)


def worst_ratios(spec: Spec, grid: BandGrid, start: Array, end: Array, level: Array, total_s: float) -> Array:
    """|F_0| / bound at every point of ``grid`` for the command holding ``level`` on [start, end).

    F_0 of the acceleration is sum_k c_k exp(lambda s_k) / lambda over the command's breakpoints (s_k = T - t_k,
    c_k the level's jump there: weights.exponential_moment summed over the pieces; / lambda^2 with a held jerk, as
    lp.acceleration_moment). Along a row of the grid (one damping ratio) the poles are evenly spaced, lambda_j =
    lambda_0 + j delta, so exp(lambda_j s) = exp(lambda_0 s) exp(delta s)^j: a running product, started again from
    an exponential every RESTART points, instead of an exponential per point and piece (4-5 times faster). The
    product's round-off, about RESTART eps of each term, is of the order of the exponentials' own: over a whole row
    of 20,000 points it reached 1.6e-5 of a ratio at V = 1e-6 % (review), beyond CHECK_MARGIN. Computed in blocks of
    at most ``MOMENT_BLOCK_ELEMENTS`` terms: the whole (points x pieces) matrix reached 380 MiB in a worker (20,000
    band points x 600 pieces, issue 23's fuzz run). The pieces are merged into ``runs`` first."""
    times, jumps = breakpoints(*runs(start, end, level))
    age = total_s - times
    ratios: Array = np.empty(grid.bound.size)
    per_row = grid.row_length
    rows = max(RESTART, MOMENT_BLOCK_ELEMENTS // max(1, age.size) // RESTART * RESTART)
    for row_start in range(0, grid.bound.size, per_row):
        poles = grid.poles[row_start : row_start + per_row]
        delta = (poles[-1] - poles[0]) / (poles.size - 1) if poles.size > 1 else 0.0
        growth = np.exp(delta * age)
        for first in range(0, poles.size, rows):  # blocks of whole runs of RESTART points: bounded memory
            count = min(rows, poles.size - first)
            runs_of = -(-count // RESTART)
            terms = np.empty((runs_of, RESTART, age.size), dtype=complex)
            terms[:, 0] = np.exp(np.outer(poles[first : first + count : RESTART], age))
            terms[:, 1:] = growth
            np.cumprod(terms, axis=1, out=terms)
            lam = poles[first : first + count]
            f = terms.reshape(-1, age.size)[:count] @ jumps / (lam if spec.order == 2 else lam * lam)
            block = slice(row_start + first, row_start + first + count)
            ratios[block] = np.abs(f) / grid.bound[block]
    return ratios


def breakpoints(start: Array, end: Array, level: Array) -> tuple[Array, Array]:
    """The times where a command holding ``level`` on [start, end) changes level, and its jumps there (a piece's
    end and the next one's start at the same time are one breakpoint)."""
    found = np.unique(np.concatenate([start, end]), return_inverse=True)
    times: Array = found[0]
    jumps = np.asarray(np.bincount(found[1], np.concatenate([level, -level]), times.size), dtype=float)
    return times, jumps


def runs(start: Array, end: Array, level: Array) -> tuple[Array, Array, Array]:
    """The pieces merged into runs of one level, the runs at 0 dropped: the same command (F_0 is linear in the
    level of each piece and additive over adjacent pieces), in fewer pieces."""
    joined = np.flatnonzero((level[1:] != level[:-1]) | (start[1:] != end[:-1])) + 1
    first = np.concatenate(([0], joined))
    last = np.concatenate((joined, [level.size])) - 1
    held = level[first] != 0.0
    return start[first][held], end[last][held], level[first][held]


def violations(ratios: Array, rows: int = 1, count: int = 40, near: float = 0.995) -> NDArray[np.intp]:
    """Where to add cuts when the check fails (some ratio > 1): every local maximum above ``near`` (the ones
    about to fail next round too) along each of the ``rows`` damping ratios, the worst ``count`` of them; none
    when every ratio is <= 1."""
    if not np.any(ratios > 1.0):
        return np.zeros(0, dtype=np.intp)
    grid = ratios.reshape(rows, -1)
    padded = np.pad(grid, ((0, 0), (1, 1)), constant_values=-np.inf)
    local = (grid > near) & (grid >= padded[:, :-2]) & (grid >= padded[:, 2:])
    peaks = np.flatnonzero(local.ravel())
    order = np.argsort(ratios[peaks])[::-1]
    out: NDArray[np.intp] = peaks[order[:count]]
    return out
