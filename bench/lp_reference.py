"""An independent minimum-time LP on a fixed grid (issue 25's reference: "never longer than an 800-step LP search by
more than 0.05 %"), sharing no code with optim: dense matrices built here from the closed forms, scipy's HiGHS.

On N equal steps of h = T / N the held derivative u_k (acceleration, or jerk with a jerk limit) is constant and
|u_k| <= its limit. Every constraint is linear in u:
- each lower derivative at time t is sum_k u_k [(t - t_k)_+^r - (t - t_k+1)_+^r] / r! (r = order difference);
- velocity within V at every node (and at every step's middle with a held jerk), acceleration within A at every
  node with a held jerk (exact: it is linear in between);
- at T: position D, velocity 0, acceleration 0 (held jerk);
- zero residual of each mode lambda: int_0^T a(t) e^(lambda (T - t)) dt = 0, by the closed forms
  int_0^s e^(lambda x) dx = (e^(lambda s) - 1) / lambda (held acceleration) and
  int_0^s (s - x) e^(lambda x) dx = (e^(lambda s) - 1 - lambda s) / lambda^2 (held jerk).
Feasibility is monotone in T on this grid family only approximately (the grid moves with T), so the minimum is
bracketed by bisection on T to a relative 1e-6, the feasible end reported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linprog

Array = NDArray[np.float64]


def _lower(times: Array, starts: Array, ends: Array, r: int) -> Array:
    """[times, steps]: the r-th integral of a unit held value on each step, at each time."""
    t = times[:, None]
    return (np.maximum(t - starts, 0.0) ** r - np.maximum(t - ends, 0.0) ** r) / math.factorial(r)


def _moment(lam: complex, total: float, starts: Array, ends: Array, order: int) -> NDArray[np.complex128]:
    """int_0^T a(t) e^(lambda (T - t)) dt of a unit held value on each step (order 2: acceleration, 3: jerk)."""

    def big(s: Array) -> NDArray[np.complex128]:
        if order == 2:
            out: NDArray[np.complex128] = (np.exp(lam * s) - 1.0) / lam
        else:
            out = (np.exp(lam * s) - 1.0 - lam * s) / lam**2
        return out

    return big(np.maximum(total - starts, 0.0)) - big(np.maximum(total - ends, 0.0))


@dataclass(frozen=True)
class GridMove:
    """A rest-to-rest move of ``move`` > 0 with zero residual at ``poles``, within the limits."""

    move: float
    poles: tuple[complex, ...]
    max_velocity: float | None
    max_acceleration: float
    max_jerk: float | None

    def feasible(self, total: float, steps: int) -> bool:
        """Whether HiGHS finds a command of ``steps`` held steps lasting ``total``."""
        order = 3 if self.max_jerk is not None else 2
        limit = self.max_jerk if self.max_jerk is not None else self.max_acceleration
        h = total / steps
        starts, ends = np.arange(steps) * h, np.arange(1, steps + 1) * h
        a_ub: list[Array] = []
        b_ub: list[Array] = []
        if self.max_velocity is not None:
            points = np.concatenate([ends, ends - h / 2]) if order == 3 else ends
            rows = _lower(points, starts, ends, order - 1)
            a_ub += [rows, -rows]
            b_ub += [np.full(points.size, self.max_velocity)] * 2
        if order == 3:
            rows = _lower(ends, starts, ends, 1)
            a_ub += [rows, -rows]
            b_ub += [np.full(ends.size, self.max_acceleration)] * 2
        end = np.array([total])
        a_eq = [_lower(end, starts, ends, order), _lower(end, starts, ends, order - 1)]
        b_eq = [self.move, 0.0]
        if order == 3:
            a_eq.append(_lower(end, starts, ends, 1))
            b_eq.append(0.0)
        for lam in self.poles:
            row = _moment(lam, total, starts, ends, order)
            scale = float(np.max(np.abs(row)))
            a_eq += [row.real[None, :] / scale, row.imag[None, :] / scale]
            b_eq += [0.0, 0.0]
        result = linprog(
            np.zeros(steps),
            A_ub=np.vstack(a_ub) if a_ub else None,
            b_ub=np.concatenate(b_ub) if b_ub else None,
            A_eq=np.vstack(a_eq),
            b_eq=np.array(b_eq),
            bounds=[(-limit, limit)] * steps,
            method="highs",
        )
        return bool(result.status == 0)

    def minimum_s(self, low: float, high: float, steps: int, rtol: float = 1e-6) -> float | None:
        """The least feasible duration in (low, high] on ``steps`` steps, by bisection; None if ``high`` is not."""
        if not self.feasible(high, steps):
            return None
        while high - low > rtol * high:
            mid = 0.5 * (low + high)
            if self.feasible(mid, steps):
                high = mid
            else:
                low = mid
        return high
