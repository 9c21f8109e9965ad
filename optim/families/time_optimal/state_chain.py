"""The motor's integrator chain (and the load's response, for the torque) z' = A z + B u, discretised exactly."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import expm

from optim.families.time_optimal.types import Spec

Array = NDArray[np.float64]


@dataclass(frozen=True)
class StateChain:
    """z' = A z + B u: the motor's derivatives (p, v[, a]) and, with a torque, G's two states."""

    a: Array
    b: Array
    scale: Array  # a natural size of each state, so that the LP's rows are balanced
    velocity: int = 1
    acceleration: int | None = None  # the state index of a (order 3)
    torque: tuple[Array, float] | None = None  # (row c, d): tau = c z + d u


def chain(spec: Spec, total_s: float) -> StateChain:
    q, unit = spec.order, spec.scale
    n = q + (2 if spec.torque is not None else 0)
    a = np.zeros((n, n))
    b = np.zeros(n)
    for m in range(q - 1):
        a[m, m + 1] = 1.0
    b[q - 1] = 1.0
    scale = np.array([unit * total_s ** (q - m) for m in range(q)] + [1.0] * (n - q))
    # Each state in units of the size it can reach: its limit where that is smaller (a slow move over a
    # long time would otherwise put the bound below HiGHS's feasibility tolerance in scaled units).
    scale[0] = min(scale[0], spec.position_scale(total_s)) if spec.rest_to_rest else scale[0]
    if spec.max_velocity is not None:
        scale[1] = min(scale[1], spec.max_velocity)
    if q == 3 and spec.max_acceleration is not None:
        scale[2] = min(scale[2], spec.max_acceleration)
    torque = None
    if spec.torque is not None:
        tq = spec.torque
        w2 = abs(tq.pole) ** 2
        two_zw = -2.0 * tq.pole.real
        # g1'' + 2 zeta w g1' + w^2 g1 = a (the motor's acceleration), a_L = w^2 g1 + 2 zeta w g1'
        a[q, q + 1] = 1.0
        a[q + 1, q] = -w2
        a[q + 1, q + 1] = -two_zw
        accel = np.zeros(n)
        if q == 2:
            b[q + 1] = 1.0
            d = tq.motor_inertia_kgm2
        else:
            a[q + 1, 2] = 1.0
            accel[2] = 1.0
            d = 0.0
        row = tq.motor_inertia_kgm2 * accel
        row[q] += tq.load_inertia_kgm2 * w2
        row[q + 1] += tq.load_inertia_kgm2 * two_zw
        a_size = spec.max_acceleration or unit * (total_s if q == 3 else 1.0)
        scale[q:] = [a_size / w2, a_size / math.sqrt(w2)]
        torque = (row, d)
    return StateChain(a, b, scale, 1, 2 if q == 3 else None, torque)


def discretise(c: StateChain, h: float) -> tuple[Array, Array]:
    """Phi = e^(A h), Gamma = int_0^h e^(A s) ds B."""
    n = c.a.shape[0]
    big = np.zeros((n + 1, n + 1))
    big[:n, :n] = c.a * h
    big[:n, n] = c.b * h
    e = expm(big)
    return e[:n, :n], e[:n, n]
