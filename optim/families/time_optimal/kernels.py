"""Compiled kernels of the refinement's constraint functions (optim.families.time_optimal.refine), by numba.

A refined structure's constraints are sums over its arcs of a kernel of the time since each arc's start and end:
the motor's state, tau_+^r / r! (the r-th integral of a unit step), and the residual moments,
G_n(tau) = int_0^tau s^n e^(lambda s) ds. Newton and SLSQP evaluate them, with their Jacobians, a few hundred
times a design on a dozen arcs: as numpy expressions each evaluation cost 20-40 numpy calls (60-90 us, mostly call
overhead); compiled, one call (a few us). Their Jacobians use the arcs' prefix sums, O(points x arcs) instead of
the dense (points, arcs, arcs) tensors of the numpy form.

Both kernels are checked against the numpy form of their definitions (tests/optim/test_time_optimal_kernels.py).
Compiled at first use and cached on disk (numba's ``cache=True``: __pycache__, or NUMBA_CACHE_DIR).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

Array = NDArray[np.float64]
CArray = NDArray[np.complex128]


@njit(cache=True)
def _ramp(t: float, r: int) -> float:
    """tau_+^r / r! (the r-th integral of a unit step at 0); 1 for tau > 0 and 0 else when r = 0."""
    if t <= 0.0:
        return 0.0
    return t**r / math.gamma(r + 1.0)


@njit(cache=True)
def state_terms(times: Array, d: Array, lv: Array, r: int, jac: bool) -> tuple[Array, Array, Array]:
    """At each point p (time t_p = times[p] . d): sum_j lv_j (R(t_p - s_j) - R(t_p - e_j)), R(tau) = tau_+^r / r!,
    s_j and e_j the arcs' start and end (prefix sums of d); its Jacobian in d (zeros without ``jac``) and the
    per-arc differences (its Jacobian in lv)."""
    points, count = times.shape
    start = np.zeros(count)
    for j in range(1, count):
        start[j] = start[j - 1] + d[j - 1]
    value = np.zeros(points)
    diff = np.zeros((points, count))
    jac_d = np.zeros((points, count))
    rise = np.zeros(count)
    fall = np.zeros(count)
    for p in range(points):
        t = 0.0
        for i in range(count):
            t += times[p, i] * d[i]
        total = 0.0
        for j in range(count):
            t1 = t - start[j]
            t2 = t1 - d[j]
            diff[p, j] = _ramp(t1, r) - _ramp(t2, r)
            total += lv[j] * diff[p, j]
            if jac:
                rise[j] = lv[j] * _ramp(t1, r - 1)
                fall[j] = lv[j] * _ramp(t2, r - 1)
        value[p] = total
        if jac:
            # d tau1_j / d d_i = times[p, i] - [i < j], d tau2_j / d d_i = times[p, i] - [i <= j]
            net = 0.0
            for j in range(count):
                net += rise[j] - fall[j]
            after = 0.0  # sum_{j > i} rise_j
            from_here = 0.0  # sum_{j >= i} fall_j
            for i in range(count - 1, -1, -1):
                from_here += fall[i]
                jac_d[p, i] = times[p, i] * net - after + from_here
                after += rise[i]
    return value, jac_d, diff


@njit(cache=True)
def moment_terms(poles: CArray, n: int, d: Array, lv: Array, jac: bool) -> tuple[CArray, CArray, CArray]:
    """F_n at the end for each pole (rows): sum_j lv_j (G_n(T - s_j) - G_n(T - e_j)),
    G_n(tau) = e^(lambda tau) sum_k (-1)^k n! / (n - k)! tau^(n - k) / lambda^(k + 1) (so that G_n' = tau^n
    e^(lambda tau)); its Jacobian in d and the per-arc differences (its Jacobian in lv)."""
    count = d.size
    rows = poles.size
    value = np.zeros(rows, dtype=np.complex128)
    diff = np.zeros((rows, count), dtype=np.complex128)
    jac_d = np.zeros((rows, count), dtype=np.complex128)
    after = np.zeros(count + 1)  # after[j] = T - s_j (the suffix sums), after[count] = 0
    for j in range(count - 1, -1, -1):
        after[j] = after[j + 1] + d[j]
    n_fact = math.gamma(n + 1.0)
    for m in range(rows):
        lam = poles[m]
        big = np.zeros(count + 1, dtype=np.complex128)  # G_n(after[j])
        slope = np.zeros(count + 1, dtype=np.complex128)  # G_n'(after[j]) = after^n e^(lambda after)
        for j in range(count + 1):
            tau = after[j]
            acc = 0.0 + 0.0j
            for k in range(n + 1):
                acc += (-1.0) ** k * n_fact / math.gamma(n - k + 1.0) * tau ** (n - k) / lam ** (k + 1)
            grow = np.exp(lam * tau)
            big[j] = grow * acc
            slope[j] = tau**n * grow
        total = 0.0 + 0.0j
        for j in range(count):
            diff[m, j] = big[j] - big[j + 1]
            total += lv[j] * diff[m, j]
        value[m] = total
        if jac:
            # d(T - s_j)/d d_i = [i >= j], d(T - e_j)/d d_i = [i > j]
            rise = 0.0 + 0.0j
            fall = 0.0 + 0.0j
            for i in range(count):
                rise += lv[i] * slope[i]
                jac_d[m, i] = rise - fall
                fall += lv[i] * slope[i + 1]
    return value, jac_d, diff


@njit(cache=True)
def _drift(state: Array, m: int, t: float) -> float:
    """The start state's share of the m-th derivative at time t: sum_(k >= m) state_k t^(k - m) / (k - m)!."""
    out = 0.0
    for k in range(m, state.size):
        if state[k] != 0.0:
            out += state[k] * t ** (k - m) / math.gamma(k - m + 1.0)
    return out


@njit(cache=True)
def _unpack(z: Array, count: int, t0: float, levels: Array, free: NDArray[np.int64]) -> tuple[Array, Array]:
    """The durations (z's first ``count``, times t0, negatives as 0) and the levels (the free ones from z)."""
    d = np.maximum(z[:count], 0.0) * t0
    lv = levels.copy()
    for f in range(free.size):
        lv[free[f]] = z[count + f]
    return d, lv


@njit(cache=True)
def end_system(
    z: Array,
    count: int,
    t0: float,
    levels: Array,
    free: NDArray[np.int64],
    unit: float,
    orders: NDArray[np.int64],
    targets: Array,
    scales: Array,
    state: Array,
    poles: CArray,
    derivative_order: int,
    moment_scales: Array,
    jac: bool,
) -> tuple[Array, Array]:
    """The equalities of a structure in z = (d / t0, free levels), scaled, and their Jacobian in z: the end state
    (unit x state_terms + the start's drift - target, over ``scales``, for each derivative in ``orders``), then for
    each n <= derivative_order the real and the imaginary parts of F_n at every pole (over ``moment_scales[n]``)."""
    d, lv = _unpack(z, count, t0, levels, free)
    q = state.size
    rows = orders.size + 2 * (derivative_order + 1) * poles.size
    values = np.zeros(rows)
    out = np.zeros((rows, count + free.size))
    total = 0.0
    for i in range(count):
        total += d[i]
    ends = np.ones((1, count))
    for r in range(orders.size):
        m = orders[r]
        v, jd, diff = state_terms(ends, d, lv, q - m, jac)
        values[r] = (unit * v[0] + _drift(state, m, total) - targets[r]) / scales[r]
        if jac:  # the start's share depends on T = sum d: d/dd_i = its (m + 1)-th derivative's share
            slope = _drift(state, m + 1, total) if m + 1 < q else 0.0
            for i in range(count):
                out[r, i] = (unit * jd[0, i] + slope) * t0 / scales[r]
            for f in range(free.size):
                out[r, count + f] = unit * diff[0, free[f]] / scales[r]
    row = orders.size
    for n in range(derivative_order + 1):
        if poles.size == 0:
            break
        f_n, f_jac, f_diff = moment_terms(poles, n, d, lv, jac)
        for p in range(poles.size):
            scale = moment_scales[n, p]
            values[row + p] = f_n[p].real / scale
            values[row + poles.size + p] = f_n[p].imag / scale
            if jac:
                for i in range(count):
                    out[row + p, i] = f_jac[p, i].real * t0 / scale
                    out[row + poles.size + p, i] = f_jac[p, i].imag * t0 / scale
                for f in range(free.size):
                    out[row + p, count + f] = f_diff[p, free[f]].real / scale
                    out[row + poles.size + p, count + f] = f_diff[p, free[f]].imag / scale
        row += 2 * poles.size
    return values, out


@njit(cache=True)
def bound_system(
    z: Array,
    count: int,
    t0: float,
    levels: Array,
    free: NDArray[np.int64],
    unit: float,
    state: Array,
    m: int,
    limit: float,
    times: Array,
    jac: bool,
) -> tuple[Array, Array]:
    """The m-th derivative within +-limit at the points ``times`` . d, as 1 - x / limit >= 0 (every point), then
    1 + x / limit >= 0, and their Jacobian in z."""
    d, lv = _unpack(z, count, t0, levels, free)
    q = state.size
    points = times.shape[0]
    v, jd, diff = state_terms(times, d, lv, q - m, jac)
    values = np.zeros(2 * points)
    out = np.zeros((2 * points, count + free.size))
    for p in range(points):
        t = 0.0
        for i in range(count):
            t += times[p, i] * d[i]
        x = unit * v[p] + _drift(state, m, t)
        values[p] = 1.0 - x / limit
        values[points + p] = 1.0 + x / limit
        if jac:
            slope = _drift(state, m + 1, t) if m + 1 < q else 0.0
            for i in range(count):
                g = (unit * jd[p, i] + slope * times[p, i]) * t0 / limit
                out[p, i] = -g
                out[points + p, i] = g
            for f in range(free.size):
                g = unit * diff[p, free[f]] / limit
                out[p, count + f] = -g
                out[points + p, count + f] = g
    return values, out
