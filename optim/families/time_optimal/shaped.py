"""A feasible start that is never worse than shaping: the rigid time-optimal move convolved with a ZV shaper
per cancelled mode (ZV^(n+1) for derivative order n; Singer and Seering 1990).

The rigid move (bang-bang, or a trapezoidal velocity at max_velocity; a ramp for rest-to-velocity) has
|a| <= A and |v| <= V; a shaper's impulses are positive and sum to 1, so the shaped acceleration and velocity
are convex combinations of shifted copies and stay within both limits, and the end state is the rigid
move's. ZV^(n+1) zeroes the residual and its first n frequency derivatives at the mode. So the shaped
command meets every constraint of a nominal time-optimal problem without torque, jerk or band; the
refinement starts from it (its free levels are the impulses' partial sums) and can only shorten it.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from optim.families.time_optimal.types import Spec

Array = NDArray[np.float64]


def rigid_arcs(spec: Spec) -> tuple[Array, Array]:
    """(breakpoints, levels in units of max_acceleration) of the rigid time-optimal move."""
    accel = spec.max_acceleration
    assert accel is not None
    if not spec.rest_to_rest:
        return np.array([0.0, spec.move / accel]), np.array([1.0])
    ramp = math.sqrt(spec.move / accel)
    if spec.max_velocity is not None and accel * ramp > spec.max_velocity:
        ramp = spec.max_velocity / accel
        cruise = spec.move / spec.max_velocity - ramp
        return np.array([0.0, ramp, ramp + cruise, 2 * ramp + cruise]), np.array([1.0, 0.0, -1.0])
    return np.array([0.0, ramp, 2 * ramp]), np.array([1.0, -1.0])


def zv_impulses(pole: complex) -> tuple[Array, Array]:
    """(times, amplitudes) of the ZV shaper of a mode: 1/(1+K), K/(1+K) half a damped period apart."""
    sigma, omega_d = -pole.real, pole.imag
    k = math.exp(-sigma * math.pi / omega_d)
    return np.array([0.0, math.pi / omega_d]), np.array([1.0, k]) / (1.0 + k)


def shaped_start(spec: Spec) -> tuple[list[float], list[float], list[bool]] | None:
    """(durations, levels, free) of the shaped rigid move, in optim.families.time_optimal.arcs.structure's form, or None
    where it does not apply (a held jerk, a torque limit, a band, no acceleration limit)."""
    if spec.order != 2 or spec.torque is not None or spec.bands or spec.max_acceleration is None:
        return None
    times, amplitudes = np.array([0.0]), np.array([1.0])
    for pole in spec.zero_poles:
        t, a = zv_impulses(pole)
        for _ in range(spec.derivative_order + 1):
            times = (times[:, None] + t[None, :]).ravel()
            amplitudes = (amplitudes[:, None] * a[None, :]).ravel()
    edges, levels = rigid_arcs(spec)
    breaks = np.unique(np.round((times[:, None] + edges[None, :]).ravel(), 15))
    mids = 0.5 * (breaks[:-1] + breaks[1:])
    shifted = mids[None, :] - times[:, None]  # (impulses, intervals)
    index = np.searchsorted(edges, shifted, side="right") - 1
    inside = (index >= 0) & (index < levels.size)
    value = np.where(inside, levels[np.clip(index, 0, levels.size - 1)], 0.0)
    shaped = amplitudes @ value
    durations = np.diff(breaks)
    keep = durations > 0.0
    durations, shaped = durations[keep], shaped[keep]
    free = [not any(abs(v - level) < 1e-12 for level in (-1.0, 0.0, 1.0)) for v in shaped]
    return list(durations), list(shaped), free
