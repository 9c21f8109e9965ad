"""Compiled kernels of the refinement's constraint functions (optim.families.time_optimal.refine), by numba.

A refined structure's constraints are sums over its arcs of a kernel of the time since each arc's start and end:
the motor's state, tau_+^r / r! (the r-th integral of a unit step), and the residual moments,
G_n(tau) = int_0^tau s^n e^(lambda s) ds. Newton and SLSQP evaluate them, with their Jacobians, a few hundred
times a design on a dozen arcs: as numpy expressions each evaluation cost 20-40 numpy calls (60-90 us, mostly call
overhead); compiled, one call (a few us). Their Jacobians use the arcs' prefix sums, O(points x arcs) instead of
the dense (points, arcs, arcs) tensors of the numpy form. ``polish`` runs the refinement's whole Newton (the
predicted structures' damped one, and the polish after SLSQP) in one call: in Python each step cost a few kernel
calls and a least-squares solve (0.3-1.3 ms a predicted structure; compiled, 0.05-0.3 ms). The certificate's own
kernels are in optim.families.time_optimal.certify_kernels.

The kernels are checked against the numpy form of their definitions, ``polish`` against the numpy Newton it
replaces and Singh and Vadali's switching times (tests/optim/test_time_optimal_kernels.py). Compiled at first use
and cached on disk (numba's ``cache=True``: __pycache__, or NUMBA_CACHE_DIR).
"""

from __future__ import annotations

import math
from typing import Any

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
    power, factorial = 1.0, 1.0
    for i in range(1, r + 1):  # products, not gamma (a third of a bound system's time): for r <= 3 the same bits as
        power *= t  # the t**r / gamma(r + 1) this replaced (numba's integer power multiplies; r! is exact)
        factorial *= i
    return power / factorial


@njit(cache=True)
def state_terms(times: Array, d: Array, lv: Array, r: int, jac: bool) -> tuple[Array, Array, Array]:
    """At each point p (time t_p = times[p] . d): sum_j lv_j (R(t_p - s_j) - R(t_p - e_j)), R(tau) = tau_+^r / r!,
    s_j and e_j the arcs' start and end (prefix sums of d); its Jacobian in d and the per-arc differences (its
    Jacobian in lv), both with no rows without ``jac``."""
    points, count = times.shape
    start = np.zeros(count)
    for j in range(1, count):
        start[j] = start[j - 1] + d[j - 1]
    value = np.zeros(points)
    rows = points if jac else 0  # (without ``jac`` only the values: SLSQP's line search asks them alone)
    diff = np.zeros((rows, count))
    jac_d = np.zeros((rows, count))
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
            difference = _ramp(t1, r) - _ramp(t2, r)
            total += lv[j] * difference
            if jac:
                diff[p, j] = difference
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


# A structure's data after z, as end_system, bound_system and polish take them: (count, t0, levels, free, unit,
# orders, targets, scales, state, poles, derivative_order, moment_scales); and the rows polish holds: (bound_m,
# bound_limit, times_a, times_b, active, movable): the derivative, limit and check points of each bound (at most
# two), which of their rows are active, and which entries of z move.
Structure = tuple[Any, ...]
Rows = tuple[NDArray[np.int64], Array, Array, Array, NDArray[np.bool_], NDArray[np.int64]]


@njit(cache=True)
def end_system(z: Array, structure: Structure, jac: bool) -> tuple[Array, Array]:
    """The equalities of a structure in z = (d / t0, free levels), scaled, and their Jacobian in z: the end state
    (unit x state_terms + the start's drift - target, over ``scales``, for each derivative in ``orders``), then for
    each n <= derivative_order the real and the imaginary parts of F_n at every pole (over ``moment_scales[n]``)
    (the Jacobian: no rows without ``jac``)."""
    count, t0, levels, free, unit, orders, targets, scales, state, poles, derivative_order, moment_scales = structure
    d, lv = _unpack(z, count, t0, levels, free)
    q = state.size
    rows = orders.size + 2 * (derivative_order + 1) * poles.size
    values = np.zeros(rows)
    out = np.zeros((rows if jac else 0, count + free.size))
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
def bound_system(z: Array, structure: Structure, m: int, limit: float, times: Array, jac: bool) -> tuple[Array, Array]:
    """The m-th derivative within +-limit at the points ``times`` . d, as 1 - x / limit >= 0 (every point), then
    1 + x / limit >= 0, and their Jacobian in z (no rows without ``jac``)."""
    count, t0, levels, free, unit, _, _, _, state, _, _, _ = structure
    d, lv = _unpack(z, count, t0, levels, free)
    q = state.size
    points = times.shape[0]
    v, jd, diff = state_terms(times, d, lv, q - m, jac)
    values = np.zeros(2 * points)
    out = np.zeros((2 * points if jac else 0, count + free.size))
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


@njit(cache=True)
def peak_system(z: Array, structure: Structure, limit: float, jac: bool) -> tuple[Array, Array]:
    """With a held jerk, each arc's velocity where the acceleration crosses 0 inside it (refine's velocity_peaks:
    v* = v_k + a_k tau + j_k tau^2 / 2 at tau = clip(-a_k / j_k, 0, d_k)), as 1 - v* / limit >= 0 (every arc), then
    1 + v* / limit >= 0, and their Jacobian in z: d v_k / d d_m = a_m + j_m (s_k - s_m) and d a_k / d d_m = j_m
    (m < k), plus a_k + j_k d_k on d_k where tau = d_k; in a free level m < k, u d_m (s_k - s_m - d_m / 2) and
    u d_m, and u tau^2 / 2 in its own."""
    count, t0, levels, free, unit, _, _, _, state, _, _, _ = structure
    d, lv = _unpack(z, count, t0, levels, free)
    jerk = lv * unit
    start = np.zeros(count)
    a = np.zeros(count)
    v = np.zeros(count)
    a[0], v[0] = state[2], state[1]
    for k in range(1, count):
        start[k] = start[k - 1] + d[k - 1]
        a[k] = a[k - 1] + jerk[k - 1] * d[k - 1]
        v[k] = v[k - 1] + a[k - 1] * d[k - 1] + jerk[k - 1] * d[k - 1] ** 2 / 2
    values = np.zeros(2 * count)
    out = np.zeros((2 * count if jac else 0, count + free.size))
    for k in range(count):
        tau, at_end = 0.0, False
        if jerk[k] != 0.0:
            crossing = -a[k] / jerk[k]
            tau = min(max(crossing, 0.0), d[k])
            at_end = crossing >= d[k]
        peak = v[k] + a[k] * tau + jerk[k] * tau * tau / 2
        values[k] = 1.0 - peak / limit
        values[count + k] = 1.0 + peak / limit
        if not jac:
            continue
        for m in range(k):
            g = (a[m] + jerk[m] * (start[k] - start[m]) + tau * jerk[m]) * t0 / limit
            out[k, m] = -g
            out[count + k, m] = g
        if at_end:
            g = (a[k] + jerk[k] * d[k]) * t0 / limit
            out[k, k] = -g
            out[count + k, k] = g
        for f in range(free.size):
            m = free[f]
            g = 0.0
            if m < k:
                g = unit * d[m] * (start[k] - start[m] - d[m] / 2 + tau) / limit
            elif m == k:
                g = unit * tau * tau / 2 / limit
            out[k, count + f] = -g
            out[count + k, count + f] = g
    return values, out


@njit(cache=True)
def inequality_system(
    z: Array,
    structure: Structure,
    bound_m: NDArray[np.int64],
    bound_limit: Array,
    times_a: Array,
    times_b: Array,
    peaks: bool,
    peak_limit: float,
    jac: bool,
) -> tuple[Array, Array]:
    """The refinement's inequalities in one call: bound_system's rows for each bound in turn (its check points
    ``times_a``, then ``times_b``), then with ``peaks`` peak_system's, and their Jacobian in z (no rows without
    ``jac``): the same values as the kernels' one by one, concatenated."""
    count, free = structure[0], structure[3]
    rows = 2 * count if peaks else 0
    for b in range(bound_m.size):
        rows += 2 * (times_a if b == 0 else times_b).shape[0]
    values = np.zeros(rows)
    out = np.zeros((rows if jac else 0, count + free.size))
    row = 0
    for b in range(bound_m.size + (1 if peaks else 0)):
        if b < bound_m.size:
            part, part_jac = bound_system(z, structure, bound_m[b], bound_limit[b], times_a if b == 0 else times_b, jac)
        else:
            part, part_jac = peak_system(z, structure, peak_limit, jac)
        values[row : row + part.size] = part
        if jac:
            out[row : row + part.size] = part_jac
        row += part.size
    return values, out


@njit(cache=True)
def _square_system(v: Array, structure: Structure, rows: Rows) -> tuple[Array, Array]:
    """end_system's rows and bound_system's active rows (over the bounds in turn) at v, their Jacobian in the
    movable columns of z."""
    bound_m, bound_limit, times_a, times_b, active, movable = rows
    values, jac = end_system(v, structure, True)
    height = values.size + int(np.sum(active))
    out_v = np.zeros(height)
    out_j = np.zeros((height, movable.size))
    out_v[: values.size] = values
    for c in range(movable.size):
        out_j[: values.size, c] = jac[:, movable[c]]
    row, seen = values.size, 0
    for b in range(bound_m.size):
        times = times_a if b == 0 else times_b
        more, more_jac = bound_system(v, structure, bound_m[b], bound_limit[b], times, True)
        for i in range(more.size):
            if active[seen + i]:
                out_v[row] = more[i]
                for c in range(movable.size):
                    out_j[row, c] = more_jac[i, movable[c]]
                row += 1
        seen += more.size
    return out_v, out_j


@njit(cache=True)
def polish(
    z: Array,
    structure: Structure,
    rows: Rows,
    iterations: int,
    stall: bool,
    stall_after: int,
    halvings: int,
    converged: float,
) -> tuple[Array, bool]:
    """Newton with minimal-norm steps (least squares, LAPACK's gelsd as numpy's) on the equalities and the active
    inequalities in the movable variables of z (``rows``; optim.families.time_optimal.refine._polish, whose rules it
    follows step for step): (z, True) once the residual is below ``converged``, else (z, False)."""
    count, movable = structure[0], rows[5]
    z = z.copy()
    g, jac = _square_system(z, structure, rows)
    rcond = np.finfo(np.float64).eps * max(jac.shape[0], jac.shape[1])
    previous = np.inf
    for k in range(iterations):
        size = np.max(np.abs(g))
        if size < 1e-14:
            return z, True
        if stall and k >= stall_after and size > 0.5 * previous:
            return z, size < converged
        previous = size
        step = np.linalg.lstsq(jac, g, rcond=rcond)[0]
        if stall:  # damped: the step halved until the residual falls and no duration is < 0
            improved = False
            trial = z.copy()
            for _ in range(halvings):
                trial = z.copy()
                for c in range(movable.size):
                    trial[movable[c]] -= step[c]
                if np.all(trial[:count] >= -1e-12):
                    trial[:count] = np.maximum(trial[:count], 0.0)
                    g, jac = _square_system(trial, structure, rows)
                    if np.max(np.abs(g)) < size:
                        improved = True
                        break
                step = 0.5 * step
            if not improved:
                return z, size < converged
            z = trial
        else:
            for c in range(movable.size):
                z[movable[c]] -= step[c]
            if np.any(z[:count] < -1e-12):
                return z, False
            z[:count] = np.maximum(z[:count], 0.0)
            g, jac = _square_system(z, structure, rows)
    return z, np.max(np.abs(g)) < converged
