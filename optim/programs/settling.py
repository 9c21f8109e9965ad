"""When the load of an axis whose plant changes during its moves settles at each stop, on its true plant.

An axis with a plant table is designed for effective modes (optim.programs.varying): its command leaves the true,
time-varying plant still at the stop, but the same command on the plant at the stop, time-invariant (the metrics'
simulation, optim.programs.run), rings for a second or more: its settling time there says nothing of the machine.
Here the settling is that of models.metrics.settling, on the cycle's integration of the true plant
(optim.programs.cycle): the earliest time after which |load - target| stays within the band (the position
tolerance times the move) and the vibration envelope within the window (the problem's ``vibration_window``),
checked at the samples during the move and in closed form after its end, where the plant no longer changes (the
mode at the stop; the free vibration from the true state there). The envelope during the move is the LTI one with
the mode's parameters at each instant: the free amplitude of the deflection less its quasi-static part,
e_qs = -a / w^2 + 2 zeta j / w^3 (exact for a held jerk on a fixed mode), plus |e_qs|.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from models.varying_mode import free_amplitude

Array = NDArray[np.float64]


@dataclass(frozen=True)
class TrueMotion:
    """One axis over the cycle on its true plant, at the samples: the motor's profile (position, velocity,
    acceleration, jerk), the deflection e = load - motor and its rate, and the mode at each sample."""

    time_s: Array
    profile: Array
    deflection: Array
    rate: Array
    omega_rad_s: Array
    zeta: Array
    envelope: Array  # the vibration envelope at each sample (``envelope``): once for every move

    @classmethod
    def of(cls, time_s: Array, profile: Array, deflection: Array, rate: Array, omega: Array, zeta: Array) -> TrueMotion:
        return cls(time_s, profile, deflection, rate, omega, zeta, envelope(profile, deflection, rate, omega, zeta))


@dataclass(frozen=True)
class StopCriteria:
    """A move's settling band (load units) and vibration window (None: no window), and the mode at its stop."""

    band: float
    window: float | None
    omega_rad_s: float
    zeta: float


def envelope(profile: Array, deflection: Array, rate: Array, w: Array, zeta: Array) -> Array:
    """The vibration envelope at each sample (see the module)."""
    accel, jerk = profile[2], profile[3]
    quasi = -accel / w**2 + 2.0 * zeta * jerk / w**3
    quasi_rate = -jerk / w**2
    free = free_amplitude(deflection - quasi, rate - quasi_rate, w, zeta)
    return np.asarray(free + np.abs(quasi), dtype=float)


def settled_s(
    motion: TrueMotion, start_s: float, end_s: float, target: float, residual: float, criteria: StopCriteria
) -> float | None:
    """From ``start_s`` until the load stays settled about ``target`` (the move ends at ``end_s``, where its free
    vibration's amplitude is ``residual``); None if an undamped mode rings above the band for ever."""
    t = motion.time_s
    first, end = np.searchsorted(t, [start_s, end_s])  # the move's samples (at end_s the profile is the next move's
    during = slice(int(first), int(end))  # start: from there on, the closed form)
    outside = np.abs(motion.profile[0][during] + motion.deflection[during] - target) > criteria.band
    if criteria.window is not None:
        outside |= motion.envelope[during] > criteria.window
    decay = criteria.zeta * criteria.omega_rad_s
    after = 0.0
    for bound in (criteria.band, criteria.window):
        if bound is not None and residual > bound:
            if decay <= 0.0:
                return None
            after = max(after, math.log(residual / bound) / decay)
    if after > 0.0:
        return end_s + after - start_s
    last = np.flatnonzero(outside)
    if not last.size:
        return 0.0
    return float(t[min(int(first) + int(last[-1]) + 1, t.size - 1)]) - start_s
