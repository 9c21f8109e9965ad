"""Compiled kernels of the certificate (optim.families.time_optimal.certify), by numba.

The certificate checks the sign of the switching function and of the measures' densities on check points laid
evenly on every arc, 64 per period of the fastest mode: thousands to a hundred thousand points a certificate, a
certificate per converged structure (five or six a held-jerk design). ``check_points`` lays them (np.linspace's
arithmetic, bit for bit), ``phi_values`` evaluates the switching function and its derivatives point by point
(instead of a basis matrix of thousands of rows; its exponentials as products along each arc), ``bang_disagrees``
and ``density_disagrees`` make the two sign checks in one pass each. Checked against np.linspace, certify's matrix
form, central differences and the numpy form of the checks (tests/optim/test_time_optimal_kernels.py). Compiled at
first use and cached on disk (numba's ``cache=True``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

Array = NDArray[np.float64]
CArray = NDArray[np.complex128]


@njit(cache=True)
def check_points(starts: Array, ends: Array, counts: NDArray[np.int64]) -> tuple[Array, NDArray[np.int64], Array]:
    """The certificate's check points (optim.families.time_optimal.certify._samples): ``counts[k]`` evenly spaced on
    each arc, its ends included, as np.linspace lays them (i x step + start, the last point the end exactly); the arc
    of each; and each point's step in T - s from the one before on its arc (0 for an arc's first point)."""
    total = 0
    for k in range(counts.size):
        total += counts[k]
    s = np.empty(total)
    arc = np.empty(total, dtype=np.int64)
    step = np.empty(total)
    p = 0
    for k in range(counts.size):
        spacing = (ends[k] - starts[k]) / (counts[k] - 1)
        for i in range(counts[k]):
            s[p] = i * spacing + starts[k]
            arc[p] = k
            step[p] = -spacing if i > 0 else 0.0
            p += 1
        s[p - 1] = ends[k]
    return s, arc, step


@njit(cache=True)
def bang_disagrees(sigma: Array, arc: NDArray[np.int64], bang: NDArray[np.bool_], levels: Array, tol: float) -> bool:
    """Whether level x sigma is below -tol x max |sigma| (over the bang arcs; 1 if 0) at a check point of a bang arc,
    or at the vertex of the parabola through an interior local minimum and its two neighbours on the same arc: the
    certificate's first sign check in one pass (certify._Switching.agreement and certify._wrong_signed, with each
    dip's vertex; tests/optim/test_time_optimal_kernels.py keeps the numpy form it replaced). A sigma that is not
    finite there disagrees (the numpy form let NaN pass)."""
    size = 0.0
    for p in range(sigma.size):
        if bang[arc[p]]:
            if not np.isfinite(sigma[p]):
                return True  # (no sign to check: nothing proven)
            size = max(size, abs(sigma[p]))
    limit = -tol * (size if size != 0.0 else 1.0)
    for p in range(sigma.size):
        if bang[arc[p]] and levels[arc[p]] * sigma[p] < limit:
            return True
    for p in range(1, sigma.size - 1):
        k = arc[p]
        if not bang[k] or arc[p - 1] != k or arc[p + 1] != k:
            continue
        left, mid, right = levels[k] * sigma[p - 1], levels[k] * sigma[p], levels[k] * sigma[p + 1]
        if mid <= left and mid <= right:
            curvature = left - 2 * mid + right
            vertex = mid - (right - left) ** 2 / (8 * curvature) if curvature > 0 else mid
            if vertex < limit:
                return True
    return False


@njit(cache=True)
def density_disagrees(
    slope: Array, arc: NDArray[np.int64], first: NDArray[np.bool_], sign: Array, beta: Array, tol: float
) -> bool:
    """Whether sign x (phi' + beta) is below -tol x max |phi'| (over every point; 1 if 0) at a check point of a
    first-order constrained arc: the certificate's second sign check (certify._Switching.density and
    certify._wrong_signed in one pass). A slope that is not finite disagrees."""
    size = 0.0
    for p in range(slope.size):
        if not np.isfinite(slope[p]):
            return True  # (no sign to check: nothing proven)
        size = max(size, abs(slope[p]))
    limit = -tol * (size if size != 0.0 else 1.0)
    for p in range(slope.size):
        k = arc[p]
        if first[k] and sign[k] * (slope[p] + beta[k]) < limit:
            return True
    return False


# phi_values' exponentials: a point ``step`` after the one before (an arc's evenly spaced checks) takes e^(p tau)
# from that point's times e^(p step), computed once per step; exactly every EXACT_EVERY points and where step is 0.
# The step is the progression's own (certify._samples'): the products differ from exp(p tau) of the rounded points
# by |p| x an ulp of tau and their own round-off, ~1e-16 each (tests/optim/test_time_optimal_kernels.py: 2e-13 of
# the largest term on 12,500 points of a 150 Hz mode).
EXACT_EVERY = 32


@njit(cache=True)
def phi_values(
    tau: Array, step: Array, theta: Array, q: int, poles: CArray, derivative_order: int, derivative: int
) -> Array:
    """phi^(derivative)(tau) = k^(derivative)(tau) - theta . (the same derivative of tau^j for j < q - 1, then Re and
    Im of tau^n e^(p tau) for every pole and n <= derivative_order), point by point: the certificate's switching
    function and its densities on the check points (optim.families.time_optimal.certify._basis's columns times
    theta, without the matrix). ``step[p]``: tau[p] - tau[p - 1] where the points are evenly spaced (see
    EXACT_EVERY), else 0."""
    power = q - 1 - derivative  # k(tau) = tau^(q-1) / (q-1)!
    k_scale = 0.0 if power < 0 else 1.0 / math.gamma(power + 1.0)
    # d^r/dtau^r tau^j = j! / (j - r)! tau^(j - r): the polynomial columns' coefficients times theta
    poly = np.zeros(max(q - 1, 1))
    for j in range(derivative, q - 1):
        poly[j] = theta[j] * math.gamma(j + 1.0) / math.gamma(j - derivative + 1.0)
    # d^r/dtau^r (tau^n e^(p tau)) = sum_i C(r, i) n! / (n - i)! p^(r - i) tau^(n - i) e^(p tau): per pole, the
    # coefficient of tau^(n - i) e^(p tau), times theta_re - i theta_im (Re(c d) = theta_re Re d + theta_im Im d)
    terms = derivative_order + 1
    coef = np.zeros((poles.size, terms), dtype=np.complex128)  # [m, e]: of tau^e e^(p tau)
    column = q - 1
    for m in range(poles.size):
        for n in range(terms):
            weight = complex(theta[column], -theta[column + 1])
            for i in range(min(n, derivative) + 1):
                comb = math.gamma(derivative + 1.0) / (math.gamma(i + 1.0) * math.gamma(derivative - i + 1.0))
                perm = math.gamma(n + 1.0) / math.gamma(n - i + 1.0)
                coef[m, n - i] += weight * comb * perm * poles[m] ** (derivative - i)
            column += 2
    out = np.empty(tau.size)
    waves = np.empty(poles.size, dtype=np.complex128)  # e^(p tau) at the current point
    ratios = np.empty(poles.size, dtype=np.complex128)  # e^(p ratio_step)
    ratio_step, run = 0.0, 0
    for p in range(tau.size):
        t = tau[p]
        if p > 0 and step[p] != 0.0 and run < EXACT_EVERY:  # an arc's next evenly spaced point: products
            if step[p] != ratio_step:
                ratio_step = step[p]
                for m in range(poles.size):
                    ratios[m] = np.exp(poles[m] * ratio_step)
            for m in range(poles.size):
                waves[m] *= ratios[m]
            run += 1
        else:
            for m in range(poles.size):
                waves[m] = np.exp(poles[m] * t)
            run = 0
        value = 0.0 if power < 0 else t**power * k_scale
        t_j = 1.0  # tau^(j - derivative)
        for j in range(derivative, q - 1):
            value -= poly[j] * t_j
            t_j *= t
        for m in range(poles.size):
            wave = waves[m]
            t_e = 1.0
            acc = 0.0 + 0.0j
            for e in range(terms):
                acc += coef[m, e] * t_e
                t_e *= t
            value -= (acc * wave).real
        out[p] = value
    return out
