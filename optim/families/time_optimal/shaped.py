"""The shaped rigid optimum, a feasible command no answer may be longer than: the rigid time-optimal move
(Ruckig, models.rigid_motion) convolved with a ZV shaper per cancelled mode (ZV^(n+1) for derivative order n;
Singer and Seering 1990), and for a band a robust shaper over it.

A shaper's impulses are positive and sum to 1, so the shaped velocity, acceleration and jerk are convex
combinations of shifted copies of the rigid move's and stay within its limits, and the end state is the rigid
move's. ZV^(n+1) zeroes the residual and its first n frequency derivatives at the mode. The held derivative
(jerk, or acceleration without a jerk limit) of the shaped move is piecewise constant: it is a command of the
arc form the refinement starts from (its levels that are no bang or coast are free).
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
from numpy.typing import NDArray

from models.plant_base import Mode
from models.rigid_motion import RigidMove, rigid_move
from models.shapers import ImpulseSequence, convolve, zv_family
from optim.families.time_optimal.types import Arc, Band, Spec

Array = NDArray[np.float64]
MAX_BAND_SHAPERS = 4  # ZVs spread over a band, at most: each adds a half period to the command
ROUND_S = 15  # breakpoints closer than 1e-15 s are one
# The rigid move is planned this much inside each limit: Ruckig's profile sits exactly on them, and the shaped
# command's peaks came out 1.2e-13 above (round-off of the scaling and the convolution): a 200 stays within.
ROUND_OFF = 1e-12
IDENTITY = ImpulseSequence(np.array([1.0]), np.array([0.0]))


def nominal_shaper(spec: Spec) -> ImpulseSequence:
    """ZV^(n+1) at every zero-residual pole (models.shapers.zv_family, eq. 11)."""
    shaper = IDENTITY
    for pole in spec.zero_poles:
        shaper = convolve(shaper, zv_family(Mode.from_pole(pole), spec.derivative_order))
    return shaper


def band_shapers(band: Band) -> Iterator[ImpulseSequence]:
    """Robust shapers over a band, shortest first: k = 1..MAX_BAND_SHAPERS ZVs at the band's k quantiles of
    equal log-width (k = 1: its geometric centre), each at the band's middle damping ratio; the caller keeps
    the first that its dense check passes."""
    zetas = sorted(band.damping_ratios)
    zeta = min(zetas[len(zetas) // 2], 0.99)
    lo, hi = math.log(band.low_rad_s), math.log(band.high_rad_s)
    for k in range(1, MAX_BAND_SHAPERS + 1):
        shaper = IDENTITY
        for i in range(k):
            shaper = convolve(shaper, zv_family(Mode(math.exp(lo + (hi - lo) * (i + 0.5) / k), zeta), 0))
        yield shaper


def rigid_of(spec: Spec, shaper: ImpulseSequence = IDENTITY) -> RigidMove | None:
    """The rigid optimum within the spec's limits that ``shaper`` turns into the spec's move, or None where shaping
    it does not bound the problem (a torque limit: the shaped move's torque is not the rigid move's; no
    acceleration or jerk limit; a start or end acceleration, which the shaped move would not keep).

    A move between velocities v0 and vf is the rigid move continued at v0 before and at vf after: the shaper
    averages that motion, so the shaped move starts at v0 and ends at vf with the shaper's mean delay tbar =
    sum A_i t_i spent at v0 and its last time t_n - tbar at vf; the rigid move covers D - v0 tbar - vf (t_n - tbar)."""
    if spec.torque is not None or (spec.max_acceleration is None and spec.max_jerk is None):
        return None
    if spec.start_acceleration or spec.end_acceleration:
        return None
    inside = [
        None if limit is None else limit * (1.0 - ROUND_OFF)
        for limit in (spec.max_velocity, spec.max_acceleration, spec.max_jerk)
    ]
    if inside[0] is not None:  # an end at max_velocity itself stays inside Ruckig's limits
        inside[0] = max(inside[0], abs(spec.start_velocity), abs(spec.end_velocity))
    mean_s = float(shaper.amplitudes @ shaper.times_s)
    last_s = float(shaper.times_s[-1])
    move = spec.move - spec.start_velocity * mean_s - spec.end_velocity * (last_s - mean_s)
    try:
        return rigid_move(
            move,
            spec.rest_to_rest,
            *inside,
            current_velocity=spec.start_velocity,
            target_velocity=spec.end_velocity,
        )
    except ValueError:  # limits too far apart for Ruckig: no shaped candidate (the grid search answers)
        return None


def shaped_arcs(rigid: RigidMove, shaper: ImpulseSequence) -> tuple[Arc, ...]:
    """The rigid move convolved with the shaper, as arcs of the held derivative (absolute levels)."""
    return _convolved(rigid.edges_s, rigid.levels, shaper)


def shaped_command(arcs: tuple[Arc, ...], shaper: ImpulseSequence) -> tuple[Arc, ...]:
    """A command (arcs of the held derivative) convolved with the shaper: its residual stays zero where it was (the
    residual at a pole is the command's times the shaper's transform there) and it meets every limit it met."""
    edges = np.array([0.0, *np.cumsum([a.duration_s for a in arcs]).tolist()])
    return _convolved(edges, np.array([a.level for a in arcs]), shaper)


def _convolved(edges: Array, levels: Array, shaper: ImpulseSequence) -> tuple[Arc, ...]:
    """The piecewise-constant levels between ``edges`` convolved with the shaper's impulses, as arcs."""
    times, amplitudes = shaper.times_s, shaper.amplitudes
    breaks = np.unique(np.round((times[:, None] + edges[None, :]).ravel(), ROUND_S))
    mids = 0.5 * (breaks[:-1] + breaks[1:])
    index = np.searchsorted(edges, mids[None, :] - times[:, None], side="right") - 1  # (impulses, intervals)
    inside = (index >= 0) & (index < levels.size)
    shaped = amplitudes @ np.where(inside, levels[np.clip(index, 0, levels.size - 1)], 0.0)
    durations = np.diff(breaks)
    keep = durations > 0.0
    return tuple(
        Arc(float(s), float(d), float(v))
        for s, d, v in zip(breaks[:-1][keep], durations[keep], shaped[keep], strict=True)
    )


def as_start(spec: Spec, arcs: tuple[Arc, ...]) -> tuple[list[float], list[float], list[bool]]:
    """(durations, levels in the unit, free) of arcs, in optim.families.time_optimal.arcs.structure's form."""
    levels = [a.level / spec.scale for a in arcs]
    free = [not any(abs(v - level) < 1e-12 for level in (-1.0, 0.0, 1.0)) for v in levels]
    return [a.duration_s for a in arcs], levels, free


def shapers(spec: Spec) -> list[ImpulseSequence]:
    """The shapers tried on the rigid optimum, shortest first: ZV^(n+1) at every zero-residual pole, and with
    bands the same times a robust shaper over every band (band_shapers)."""
    base = nominal_shaper(spec)
    if not spec.bands:
        return [base]
    out = [base] if spec.zero_poles else []
    for per_band in zip(*(band_shapers(b) for b in spec.bands), strict=True):
        shaper = base
        for extra in per_band:
            shaper = convolve(shaper, extra)
        out.append(shaper)
    return out
