"""The data of models.simulation's exact response: a transfer function in partial fractions (``ModalForm``) and
each pole's free response at the breakpoints (``FreeResponse``), shared by the simulation and its checks."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class ModalForm:
    """G(s) = sum_m taylor[m] s^m near 0, and sum over poles of weights * residues / (s - pole).

    One entry per real pole or per complex pair (the pole with Im > 0, weight 2). ``pole_taylor[j, m]``: the
    Taylor coefficients at 0 of pole j's term per unit residue, -1 / pole^(m+1) (None), or a sampled loop's
    (models.servo_sampled), whose terms are not r / (s - pole).
    """

    taylor: NDArray[np.float64]
    poles: NDArray[np.complex128]
    residues: NDArray[np.complex128]
    weights: NDArray[np.float64]
    pole_taylor: NDArray[np.complex128] | None = None

    def pole_term(self, order: int) -> NDArray[np.complex128]:
        """Each pole's Taylor coefficient of ``order`` per unit residue."""
        if self.pole_taylor is not None:
            column: NDArray[np.complex128] = self.pole_taylor[:, order]
            return column
        term: NDArray[np.complex128] = -(self.poles ** -(order + 1))
        return term

    @property
    def oscillatory(self) -> NDArray[np.bool_]:
        pairs: NDArray[np.bool_] = self.weights == 2.0
        return pairs


@dataclass(frozen=True)
class FreeResponse:
    """h_k of one pole at every breakpoint, stored as what computed it.

    Either ``values`` (h itself) or, for a complex pole on a uniform grid driven by one order of jumps,
    the real sequence s of the second-order recurrence s_k = 2 Re(z) s_{k-1} - |z|^2 s_{k-2} + u_k
    (``scipy.signal.lfilter`` on real numbers), from which h_k = gain (s_k - conj(z) s_{k-1}): the
    denominator (1 - z q^-1)(1 - conj(z) q^-1) is the complex first-order recurrence times its conjugate.
    """

    values: NDArray[np.complex128] | None = None
    s: NDArray[np.float64] | None = None
    s_before: float = 0.0  # s_{-1}
    gain: complex = 0.0
    decay: complex = 0.0  # z = exp(pole h)

    def combination(self, c: complex) -> tuple[float, float]:
        """(alpha, beta) with Re(c h_k) = alpha s_k - beta s_{k-1} (the s representation only)."""
        ca = c * self.gain
        return ca.real, (ca * self.decay.conjugate()).real

    def at(self, index: int) -> complex:
        if self.values is not None:
            return complex(self.values[index])
        assert self.s is not None
        previous = float(self.s[index - 1]) if index > 0 else self.s_before
        return self.gain * (float(self.s[index]) - self.decay.conjugate() * previous)

    def full(self) -> NDArray[np.complex128]:
        if self.values is not None:
            return self.values
        assert self.s is not None
        shifted = np.empty_like(self.s)
        shifted[0] = self.s_before
        shifted[1:] = self.s[:-1]
        h: NDArray[np.complex128] = self.gain * (self.s - self.decay.conjugate() * shifted)
        return h

    @cached_property
    def bound(self) -> float:
        """An upper bound of max_k |h_k|; for the s representation also the scale of its round-off."""
        if self.values is not None:
            return float(np.max(np.abs(self.values))) if self.values.size else 0.0
        assert self.s is not None
        largest = max(float(self.s.max()), -float(self.s.min()), abs(self.s_before))
        return abs(self.gain) * (1.0 + abs(self.decay)) * largest


def partial_fraction_taylor(
    polynomial: tuple[float, ...], residues: NDArray[np.complex128], poles: NDArray[np.complex128], count: int
) -> NDArray[np.float64]:
    """The first ``count`` Taylor coefficients at 0 of P0 + P1 s + P2 s^2 + sum_j rho_j / (s - lambda_j) over every
    pole: g_m = P_m - Re sum_j rho_j / lambda_j^(m+1)."""
    orders = np.arange(count)
    taylor = np.zeros(count)
    size = min(count, len(polynomial))
    taylor[:size] = polynomial[:size]
    taylor -= np.real(np.sum(residues[:, None] / poles[:, None] ** (orders[None, :] + 1), axis=0))
    return taylor
