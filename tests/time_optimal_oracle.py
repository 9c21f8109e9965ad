"""Independent reference: the minimum-time rest-to-rest command of a rigid motor that leaves one
undamped mode still.

The plant is the 'mode' kind with zero damping: the load follows the motor through
w^2 / (s^2 + w^2). The motor acceleration is bounded by ``a`` (and its velocity by ``v``); the move is
``D``. Nothing here imports ``optim.families.time_optimal``: the answer comes from the structure alone.

Structure (Singh & Vadali 1993, "Robust time-optimal control: frequency domain approach", J. Guid.
Control Dyn. 16(2); Pao & Singhose 1995, "On the equivalence of minimum time input shaping with
traditional time-optimal control"): bang-bang, the acceleration antisymmetric about T/2, with three
switches: +a for t1, -a for t2, +a for t2, -a for t1 (T = 2 t1 + 2 t2).

Equations (e = load - motor obeys e'' + w^2 e = -a(t), so the residual amplitude after T is
|A(i w)| / w with A(s) = int_0^T a(t) e^{-s t} dt):

- v(T) = 0 holds by antisymmetry;
- p(T) = a (t1^2 + 2 t1 t2 - t2^2) = D;
- A(i w) = 0: by antisymmetry A(i w) = -2i e^{-i w T/2} int_0^{T/2} a(T/2 + tau) sin(w tau) dtau, one real
  equation: 1 - 2 cos(w t2) + cos(w (t1 + t2)) = 0.

With t1 = -t2 + sqrt(2 t2^2 + D/a) from the position, T = 2 sqrt(2 t2^2 + D/a) increases with t2, so the
fastest command of this structure is the smallest root t2 >= 0 of the residual equation, bracketed by a
fine scan and refined by brentq.

Optimality is then checked, not assumed: by the maximum principle a time-optimal bang-bang control
switches where sigma(t) = c0 + c1 t + c2 cos(w t) + c3 sin(w t) (the costate of the double integrator
and of the mode) changes sign. ``pmp_check`` finds the (one-dimensional) c that vanishes at the three
switch times and verifies sigma changes sign there and nowhere else, with the arcs' signs. For this
normal linear time-invariant system an extremal that reaches the target is time-optimal (its end state
lies on the boundary of the reachable set, which grows strictly with time), so a passed check proves the
minimum.

Range: no coast. When the structure's peak velocity a t1 exceeds ``v`` the velocity limit makes a coast
arc whose time-optimal structure is not derived here; ``minimum_time`` raises ``OutOfRange`` (and also
when the PMP check fails, which would mean a different switch structure). For those moves
``velocity_limited_upper_bound`` gives a feasible zero-residual command, not proven optimal: the faster of
a trapezoid whose cruise (at most ``v``) puts the ramps a whole number of periods apart
(``coast_upper_bound``) and the best antisymmetric command +a, -a, +a, coast at ``v``, mirrored
(``coast_structure_upper_bound``). A time-optimal answer slower than it is not optimal.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import quad
from scipy.optimize import brentq


class OutOfRange(ValueError):
    """The case lies outside what this oracle solves exactly."""


@dataclass(frozen=True)
class Bang:
    """A rest-to-rest acceleration command: arc durations and their levels (piecewise constant)."""

    durations_s: tuple[float, ...]
    levels: tuple[float, ...]

    @property
    def duration_s(self) -> float:
        return float(sum(self.durations_s))

    @property
    def switch_times_s(self) -> tuple[float, ...]:
        """Start times of every arc after the first, then the end: (t_1, ..., t_n = T)."""
        return tuple(float(x) for x in np.cumsum(self.durations_s))

    def command(self) -> tuple[list[float], list[float]]:
        """(times, levels): the acceleration is levels[k] on [times[k], times[k+1]); times[0] = 0, times[-1] = T."""
        return [0.0, *self.switch_times_s], list(self.levels)


def rigid_minimum_time(a: float, v: float | None, d: float) -> float:
    """Rigid time-optimal rest-to-rest: bang-bang 2 sqrt(D/a), or the trapezoid D/v + v/a when sqrt(a D) > v."""
    d = abs(d)
    if v is None or math.sqrt(a * d) <= v:
        return 2.0 * math.sqrt(d / a)
    return d / v + v / a


def _residual_equation(t2: float, w: float, a: float, d: float) -> float:
    t1 = -t2 + math.sqrt(2.0 * t2 * t2 + d / a)
    return 1.0 - 2.0 * math.cos(w * t2) + math.cos(w * (t1 + t2))


def four_arc(w: float, a: float, d: float, scan_points: int = 20_000) -> Bang:
    """The fastest symmetric three-switch command (+a t1, -a t2, +a t2, -a t1) with zero residual at w."""
    d = abs(d)
    f0 = _residual_equation(0.0, w, a, d)
    if abs(f0) < 1e-14:  # the rigid bang-bang already leaves no residual (w sqrt(D/a) = 2 pi k)
        t1 = math.sqrt(d / a)
        return Bang((t1, t1), (a, -a))
    # f(0) = cos(w sqrt(D/a)) - 1 < 0 and f(pi/w) = 3 + cos(.) > 0: the smallest root lies in (0, pi/w).
    grid = np.linspace(0.0, math.pi / w, scan_points + 1)
    t1 = -grid + np.sqrt(2.0 * grid * grid + d / a)
    values = 1.0 - 2.0 * np.cos(w * grid) + np.cos(w * (t1 + grid))
    change = np.nonzero(np.sign(values[1:]) != np.sign(values[:-1]))[0]
    if change.size == 0:
        raise OutOfRange("no root of the residual equation below half a period")
    k = int(change[0])
    t2 = brentq(_residual_equation, grid[k], grid[k + 1], args=(w, a, d), xtol=1e-16, rtol=4 * np.finfo(float).eps)
    t1 = -t2 + math.sqrt(2.0 * t2 * t2 + d / a)
    return Bang((t1, t2, t2, t1), (a, -a, a, -a))


def switching_function(bang: Bang, w: float) -> np.ndarray:
    """Coefficients c of sigma(t) = c0 + c1 t + c2 cos(w t) + c3 sin(w t) vanishing at the interior switches."""
    switches = np.array(bang.switch_times_s[:-1])
    rows = np.column_stack([np.ones_like(switches), switches, np.cos(w * switches), np.sin(w * switches)])
    _, _, vt = np.linalg.svd(rows)
    return vt[-1]


def pmp_check(bang: Bang, w: float, points: int = 200_001) -> bool:
    """Whether a switching function of the maximum principle has the command's arcs as its sign pattern."""
    c = switching_function(bang, w)
    t = np.linspace(0.0, bang.duration_s, points)
    sigma = c[0] + c[1] * t + c[2] * np.cos(w * t) + c[3] * np.sin(w * t)
    edges = np.array([0.0, *bang.switch_times_s])
    scale = np.max(np.abs(sigma))
    expected = None
    for k, level in enumerate(bang.levels):
        lo, hi = edges[k], edges[k + 1]
        margin = 1e-6 * bang.duration_s
        inside = (t > lo + margin) & (t < hi - margin)
        if not np.any(inside):
            continue
        s = sigma[inside]
        if np.any(np.abs(s) < 1e-12 * scale) or not (np.all(s > 0) or np.all(s < 0)):
            return False
        sign = float(np.sign(s[0]) * np.sign(level))
        if expected is None:
            expected = sign
        elif sign != expected:
            return False
    return True


def minimum_time_command(w: float, a: float, v: float | None, d: float) -> Bang:
    """The exact minimum-time zero-residual command (signed like d); OutOfRange where not derived here."""
    bang = four_arc(w, a, d)
    peak = a * bang.durations_s[0]
    if v is not None and peak > v * (1 + 1e-12):
        raise OutOfRange(f"the velocity limit {v:g} is active (peak {peak:g}): a coast arc, not solved here")
    if len(bang.durations_s) > 2 and not pmp_check(bang, w):  # two arcs: the rigid minimum itself
        raise OutOfRange("the three-switch structure fails the maximum principle here")
    sign = 1.0 if d >= 0 else -1.0
    return Bang(bang.durations_s, tuple(sign * x for x in bang.levels))


def minimum_time(w: float, a: float, v: float | None, d: float) -> float:
    return minimum_time_command(w, a, v, d).duration_s


def coast_upper_bound(w: float, a: float, v: float, d: float) -> float:
    """A feasible zero-residual trapezoid (cruise v_c <= v, accel/decel at a, accel start to decel start a whole
    number of periods, so the two ramps' residuals cancel): an upper bound on the minimum time, not the minimum."""
    d = abs(d)
    period = 2 * math.pi / w
    best = math.inf
    k = max(1, math.ceil(d / v / period))
    for kk in range(k, k + 50):
        span = kk * period  # time between the ramps' starts; D = v_c span
        vc = d / span
        ramp = vc / a
        if vc <= v and ramp <= span:
            best = min(best, span + ramp)
    return best


def _coast_half(w: float, a: float, v: float, d: float, u: float, t2: np.ndarray) -> tuple[np.ndarray, ...]:
    """The coast structure's residual equation g, its time T and coast tc at (u = t3 - t2, t2); see
    ``coast_structure_upper_bound``."""
    t3 = t2 + u
    t1 = v / a - u
    v2 = a * (t1 - t2)
    p_acc = a * t1 * t1 / 2 + a * t1 * t2 - a * t2 * t2 / 2 + v2 * t3 + a * t3 * t3 / 2
    tc = (d - 2 * p_acc) / v
    c = tc / 2
    taus = [c, c + t3, c + t3 + t2, c + t3 + t2 + t1]
    cos = [np.cos(w * x) for x in taus]
    g = -cos[0] + 2 * cos[1] - 2 * cos[2] + cos[3]
    return g, 2 * (t1 + t2 + t3) + tc, tc


def coast_structure_upper_bound(w: float, a: float, v: float, d: float, points: int = 801) -> Bang | None:
    """The fastest zero-residual command of the antisymmetric coast structure +a t1, -a t2, +a t3, coast at v for
    tc, -a t3, +a t2, -a t1 (velocity a (t1 - t2 + t3) = v at the coast, t2 <= t3 so it never exceeds v), by a scan
    of u = t3 - t2 in [0, v/a] and of t2 in [0, one period], brentq on the residual equation and a bounded refinement
    of u. Feasible, so an upper bound on the minimum time; its optimality is not proven (the velocity limit is a
    state constraint the check of ``pmp_check`` does not cover). None when no such command exists."""
    d = abs(d)
    period = 2 * math.pi / w
    t2_grid = np.linspace(0.0, period, 4001)

    def best_at(u: float) -> tuple[float, float] | None:
        g, _, tc = _coast_half(w, a, v, d, u, t2_grid)
        ok = tc >= 0
        best: tuple[float, float] | None = None
        change = np.nonzero((np.sign(g[1:]) != np.sign(g[:-1])) & ok[1:] & ok[:-1])[0]
        for k in change:
            root = brentq(lambda x: float(_coast_half(w, a, v, d, u, np.array([x]))[0][0]), t2_grid[k], t2_grid[k + 1])
            t = float(_coast_half(w, a, v, d, u, np.array([root]))[1][0])
            if best is None or t < best[0]:
                best = (t, root)
        return best

    us = np.linspace(0.0, v / a, points)
    found = [(best_at(float(u)), float(u)) for u in us]
    found_ok = [(b, u) for b, u in found if b is not None]
    if not found_ok:
        return None
    (t_best, t2_best), u_best = min(found_ok, key=lambda item: item[0][0])
    step = us[1] - us[0]
    for _ in range(40):  # golden-section-like shrink around the best grid point
        step /= 2
        for u in (u_best - step, u_best + step):
            if 0 <= u <= v / a:
                b = best_at(u)
                if b is not None and b[0] < t_best:
                    t_best, t2_best, u_best = b[0], b[1], u
    t2, t3, t1 = t2_best, t2_best + u_best, v / a - u_best
    tc = float(_coast_half(w, a, v, d, u_best, np.array([t2]))[2][0])
    arcs = [(t1, a), (t2, -a), (t3, a), (tc, 0.0), (t3, -a), (t2, a), (t1, -a)]
    arcs = [(h, lv) for h, lv in arcs if h > 0]
    return Bang(tuple(h for h, _ in arcs), tuple(lv for _, lv in arcs))


def velocity_limited_upper_bound(w: float, a: float, v: float, d: float) -> float:
    """An upper bound on the minimum time when the velocity limit is active (see the module docstring)."""
    structured = coast_structure_upper_bound(w, a, v, d)
    return min(coast_upper_bound(w, a, v, d), math.inf if structured is None else structured.duration_s)


def residual_by_quadrature(times: list[float], levels: list[float], w: float) -> float:
    """|int a(t) e^{i w t} dt| / w by scipy quad on every arc: the residual amplitude (load units)."""
    re = im = 0.0
    for k, level in enumerate(levels):
        lo, hi = times[k], times[k + 1]
        re += level * quad(lambda t: math.cos(w * t), lo, hi, epsabs=1e-14, epsrel=1e-12, limit=500)[0]
        im += level * quad(lambda t: math.sin(w * t), lo, hi, epsabs=1e-14, epsrel=1e-12, limit=500)[0]
    return math.hypot(re, im) / w


def position_at_end(times: list[float], levels: list[float]) -> tuple[float, float]:
    """(p(T), v(T)) of the acceleration command from rest."""
    p = vel = 0.0
    for k, level in enumerate(levels):
        h = times[k + 1] - times[k]
        p += vel * h + 0.5 * level * h * h
        vel += level * h
    return p, vel


KNOWN = {"frequency_hz": 40.0, "a": 10.0, "v": 5.0, "d": 0.12, "duration_s": 0.2197077}


def self_test() -> None:
    """The known answer (40 Hz, a = 10, v = 5, D = 0.12: 219.7077 ms, arcs 104.03 / 5.83 / 5.83 / 104.03 ms)
    and its residual by direct quadrature."""
    w = 2 * math.pi * KNOWN["frequency_hz"]
    bang = minimum_time_command(w, KNOWN["a"], KNOWN["v"], KNOWN["d"])
    if abs(bang.duration_s / KNOWN["duration_s"] - 1) > 1e-4:
        raise AssertionError(f"minimum time {bang.duration_s!r} != {KNOWN['duration_s']}")
    expected_ms = (104.03, 5.83, 5.83, 104.03)
    if any(abs(1e3 * got - want) > 0.006 for got, want in zip(bang.durations_s, expected_ms, strict=True)):
        raise AssertionError(f"arcs {bang.durations_s!r} != {expected_ms} ms")
    times, levels = bang.command()
    p, vel = position_at_end(times, levels)
    if abs(p - KNOWN["d"]) > 1e-12 or abs(vel) > 1e-12:
        raise AssertionError(f"end state p = {p!r}, v = {vel!r}")
    residual = residual_by_quadrature(times, levels, w)
    if residual > 1e-9 * KNOWN["d"]:
        raise AssertionError(f"residual {residual!r}")


if __name__ == "__main__":
    self_test()
    w = 2 * math.pi * KNOWN["frequency_hz"]
    b = minimum_time_command(w, KNOWN["a"], KNOWN["v"], KNOWN["d"])
    print(f"{1e3 * b.duration_s:.4f} ms, arcs {[round(1e3 * x, 4) for x in b.durations_s]} ms")
