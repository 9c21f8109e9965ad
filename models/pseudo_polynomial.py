"""Pseudo-polynomial motion commands (Incerti, eqs. 8-23).

phi(t) = Phi [1 - sum_{i=0..n} C_i (1 - t/T)^gamma_i]   (eq. 17)

with n + 1 exponents gamma_i. At t = T the law equals Phi with its first n derivatives null as long
as every gamma_i > n; the coefficients C_i make the first n derivatives null at t = 0 too: they
solve Z c = (1, 0, ..., 0) with Z[k, i] = P(gamma_i, k) (eqs. 21-23), P the falling factorial
(eq. 19). Integer exponents n+1, ..., 2n+1 give the classical polynomials: (3, 4, 5) is the
quintic 10 s^3 - 15 s^4 + 6 s^5 of Table II.

The formulas are written with plain arithmetic so that the optimiser can call them on CasADi
expressions (``falling_factorial``, ``boundary_matrix``, ``derivative_terms``).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from models.commands import PiecewiseCommand
from models.errors import InvalidParameter


def falling_factorial(gamma: Any, k: int) -> Any:
    """P(gamma, k) = gamma (gamma - 1) ... (gamma - k + 1); P(gamma, 0) = 1 (eq. 19)."""
    out: Any = 1.0
    for r in range(k):
        out = out * (gamma - r)
    return out


def boundary_matrix(exponents: Sequence[Any]) -> list[list[Any]]:
    """Z of eq. (23): row k holds P(gamma_i, k), k = 0..n, for n + 1 exponents."""
    n = len(exponents) - 1
    return [[falling_factorial(g, k) for g in exponents] for k in range(n + 1)]


def coefficients(exponents: Sequence[float]) -> NDArray[np.float64]:
    """C solving Z c = (1, 0, ..., 0) (eq. 22)."""
    z = np.array(boundary_matrix([float(g) for g in exponents]), dtype=float)
    rhs = np.zeros(len(exponents))
    rhs[0] = 1.0
    c: NDArray[np.float64] = np.linalg.solve(z, rhs)
    return c


def coefficients_order_2(g0: float, g1: float, g2: float) -> tuple[float, float, float]:
    """The closed form of eq. (16) for three exponents."""
    return (
        g1 * g2 / ((g2 - g0) * (g1 - g0)),
        g0 * g2 / ((g1 - g0) * (g1 - g2)),
        g0 * g1 / ((g0 - g2) * (g1 - g2)),
    )


def check_exponents(exponents: Sequence[float], order: int, field_name: str = "initial_exponents") -> tuple[float, ...]:
    """Exponents usable for an order-n law: n + 1 finite values above n, pairwise distinct."""
    values = tuple(float(g) for g in exponents)
    if len(values) != order + 1:
        raise InvalidParameter(field_name, list(values), f"order {order} needs {order + 1} exponents")
    for i, g in enumerate(values):
        if not math.isfinite(g) or g <= order:
            raise InvalidParameter(
                f"{field_name}[{i}]",
                g,
                f"every exponent must exceed the order {order} (eqs. 17-20: the end conditions)",
            )
    ordered = sorted(values)
    if min(b - a for a, b in itertools.pairwise(ordered)) < 1e-6 * ordered[-1]:
        raise InvalidParameter(field_name, list(values), "exponents must be distinct (eq. 22 is singular otherwise)")
    return values


def derivative_terms(exponents: Sequence[Any], coefs: Sequence[Any], k: int) -> list[tuple[Any, Any]]:
    """(weight_i, power_i) with phi^(k)(t) = (-1)^(k+1) Phi/T^k sum_i weight_i u^power_i, u = 1 - t/T
    (eq. 18; for k = 0 the law is Phi (1 - sum_i C_i u^gamma_i))."""
    return [(falling_factorial(g, k) * c, g - k) for g, c in zip(exponents, coefs, strict=True)]


@dataclass(frozen=True)
class PseudoPolynomial:
    """A rest-to-rest move of ``displacement`` in ``duration_s`` with the given exponents."""

    displacement: float
    duration_s: float
    exponents: tuple[float, ...]
    coefficients: tuple[float, ...] = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "exponents", tuple(float(g) for g in self.exponents))
        object.__setattr__(self, "coefficients", tuple(float(c) for c in coefficients(self.exponents)))

    @property
    def order(self) -> int:
        return len(self.exponents) - 1

    def derivative(self, k: int, time_s: ArrayLike, *, left_at_end: bool = False) -> NDArray[np.float64]:
        """phi^(k)(t), k = 0..3, vectorised; rest at 0 before t = 0 and at Phi after t = T.

        At t = T the jerk may jump (to 0 after the move); ``left_at_end`` gives its value from
        the left there instead.
        """
        t = np.asarray(time_s, dtype=float)
        T, phi = self.duration_s, self.displacement
        u = np.clip(1.0 - t / T, 0.0, 1.0)
        inside = (t >= 0.0) & ((t <= T) if left_at_end else (t < T))
        total = np.zeros_like(u)
        for weight, power in derivative_terms(self.exponents, self.coefficients, k):
            total += weight * np.where(inside, u, 1.0) ** power
        if k == 0:
            out = phi * (1.0 - total)
            return np.where(t >= T, phi, np.where(t < 0.0, 0.0, out))
        out = (-1.0) ** (k + 1) * phi / T**k * total
        return np.where(inside, out, 0.0)

    def command(self, sample_period_s: float, horizon_s: float) -> PiecewiseCommand:
        """The law sampled every ``sample_period_s`` (t = T on the grid) until ``horizon_s``, as a
        drive's cam table runs it: the velocity follows the cubic Hermite curve through the
        sampled velocities and accelerations, integrated exactly. Velocity and acceleration then
        equal the law at every sample (so the motor stops exactly at T) and the position is
        within O(h^4); the jerk is that curve's, within O(h^2) of the law's. (Holding the
        acceleration instead would need the jerk, which is nearly singular at T when the lowest
        exponent is just above n + 1.)"""
        T, h = self.duration_s, sample_period_s
        moving = h * np.arange(math.floor(T / h) + 1)
        t = np.append(moving[moving < T * (1.0 - 1e-12)], T)
        move = PiecewiseCommand.from_samples(t, self.derivative(1, t), 1, hold="cubic", slopes=self.derivative(2, t))
        return move.resampled(h, end_s=max(horizon_s, T))

    def samples(self, time_s: ArrayLike) -> dict[str, NDArray[np.float64]]:
        """The law's exact values at the given times (jerk: right-hand value, 0 from T on)."""
        t = np.asarray(time_s, dtype=float)
        return {
            "time_s": t,
            "position": self.derivative(0, t),
            "velocity": self.derivative(1, t),
            "acceleration": self.derivative(2, t),
            "jerk": self.derivative(3, t),
        }
