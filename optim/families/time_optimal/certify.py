"""A proof that a command is the minimum-time one: Pontryagin's switching function, written as weak duality of the
move's linear programme in function space (Dhanda, Vaughan and Singhose 2009 give its grid form).

With the held derivative u = x^(q) / U in [-1, 1] (q = 2: the acceleration, U = max_acceleration; q = 3: the jerk,
U = max_jerk), a rest-to-rest move from rest reaches D(u) = U int k(T - s) u(s) ds, k(tau) = tau^(q-1) / (q-1)!,
subject to the end state (U int tau^j u = 0, j < q - 1) and the residual moments (U int tau^n e^(p tau) u = 0 for
every zero-residual pole p and n <= derivative order: the same conditions as the residual of the moved load once the
end state holds), and to the limits on the derivatives below q. The limit one order below q (the velocity when
q = 2, the acceleration when q = 3) is a first-order state constraint: its measure mu enters as mu([s, T]); the
velocity when q = 3 is a second-order one: its measure nu enters as int_[s, T] (t - s) dnu(t). For any multipliers
theta and any signed measures (of the active bound's sign where the bound is active),

    D(u) <= L1 |mu| + L2 |nu| + U int_0^T |sigma(s)| ds,
    sigma(s) = phi(T - s) - mu([s, T]) - int_[s, T] (t - s) dnu(t),
    phi(tau) = k(tau) - theta . (tau^j, Re and Im of tau^n e^(p tau)).

A command with u = sign(sigma) on its bang arcs, sigma = 0 on its constrained arcs (u = 0 there: a first-order arc
at +-L1, or a coast at +-max_velocity with zero acceleration when q = 3) and the measures supported on them with the
right signs reaches the bound: no command of its duration goes further. Between constrained arcs sigma is phi less an
affine function of s (a constant for mu, a line for nu); sigma = 0 along a constrained arc fixes the measure's
density there (mu: phi'(T - s) plus the line's slope; nu: phi''(T - s)), and a coast's ends may carry atoms of nu
(they bend sigma without a jump: the one at the entry is an unknown of the junction system, the one at the exit
follows). Where the velocity touches its limit at one instant inside a bang arc (the acceleration crossing 0 at
v = +-V), nu may have an atom there too: one more unknown, no junction (sigma keeps the arc's sign through it;
optim.families.time_optimal.touch_points), tried where the certificate without it fails. The kernels depend on
T - s only, so the same multipliers, shifted with the end, bound every shorter duration strictly below D (a rest
prefix is feasible and loses |sigma| on the first arc): the command is the minimum-time one.

``certificate`` finds theta and the entry atoms from the junctions (sigma = 0 at every switch and every constrained
arc's exit, by least squares) and checks the signs on CHECK_PER_PERIOD points per period of the fastest mode on every
arc. A command it does not certify may still be optimal (the caller's search decides then).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from optim.families.time_optimal.touch_points import (
    BANG,
    FIRST,
    SECOND,
    STATE_TOLERANCE,
    TOUCH,
    arc_states,
    touches,
)
from optim.families.time_optimal.types import Arc, Spec

__all__ = ["BANG", "FIRST", "SECOND", "TOUCH", "arc_states", "touches"]  # (re-exported)

Array = NDArray[np.float64]
CHECK_PER_PERIOD = 64  # sign checks per period of the fastest zero-residual mode, on every arc (and at each local
# minimum of level * sigma between them, by its parabola: sigma is smooth at that scale)
MIN_CHECKS = 16  # per arc, at least
MAX_CHECKS = 200_000  # a command needing more checks is not certified here (its search answers)
LEVEL_TOLERANCE = 1e-9  # of the unit: a level this close to -1, 0 or 1 is that level
JUNCTION_TOLERANCE = 1e-6  # of k(T): the junction conditions' residual for a consistent theta (a refined
# structure's switching times are exact to about this: its duration is flat in them at the optimum)
SIGN_TOLERANCE = 1e-6  # of max |sigma| (or of the density's scale): wrong-signed values next to a switch, from
# switching times exact to about JUNCTION_TOLERANCE (they shift sigma's zero by that much: second order in distance)


@dataclass(frozen=True)
class Certificate:
    """The multipliers that prove the command optimal (theta, in ``_basis``'s columns; the coasts' atoms of nu, at
    (time, mass)), and how many points checked their signs."""

    theta: Array
    checked_points: int
    atoms: tuple[tuple[float, float], ...] = ()

    def describe(self) -> str:
        return (
            "the switching function (Pontryagin; weak duality of the move's linear programme) certifies it the "
            f"minimum-time command: no shorter one exists (signs checked on {self.checked_points} points)"
        )


def kernel(q: int, tau: Array, derivative: int = 0) -> Array:
    """k(tau) = tau^(q-1) / (q-1)! (the distance's kernel) or its ``derivative``-th derivative."""
    power = q - 1 - derivative
    if power < 0:
        return np.zeros_like(tau)
    return tau**power / math.factorial(power)


def _basis(spec: Spec, tau: Array, derivative: int = 0) -> Array:
    """The columns of phi's unknown part at ``tau`` (tau^j for j < q - 1, then Re and Im of tau^n e^(p tau) for
    every pole and n), or their ``derivative``-th derivative in tau (0, 1 or 2)."""
    out = np.zeros((tau.size, _width(spec)))
    for j in range(derivative, spec.order - 1):
        out[:, j] = math.perm(j, derivative) * tau ** (j - derivative)
    column = spec.order - 1
    for pole in spec.zero_poles:
        wave = np.exp(pole * tau)
        for n in range(spec.derivative_order + 1):
            # d^r/dtau^r (tau^n e^(p tau)) = sum_i C(r, i) n!/(n-i)! tau^(n-i) p^(r-i) e^(p tau)
            value = sum(
                math.comb(derivative, i) * math.perm(n, i) * tau ** (n - i) * pole ** (derivative - i)
                for i in range(min(n, derivative) + 1)
            )
            out[:, column], out[:, column + 1] = (value * wave).real, (value * wave).imag
            column += 2
    return out


def phi_parts(spec: Spec, tau: Array, derivative: int = 0) -> tuple[Array, Array]:
    """phi^(derivative)(tau) = k^(derivative)(tau) - basis . theta as (k^(derivative)(tau), the basis's rows): the
    switching function of any theta at the points ``tau`` (optim.families.time_optimal.shooting's system)."""
    return kernel(spec.order, tau, derivative), _basis(spec, tau, derivative)


def _phi(spec: Spec, tau: Array, step: Array, theta: Array, derivative: int = 0) -> Array:
    """phi^(derivative)(tau) = kernel - _basis . theta, compiled point by point (certify_kernels.phi_values: the check
    points' sigma and densities without the basis matrix, a third of a certificate's time; the same values to
    round-off, tests/optim/test_time_optimal_kernels.py). ``step``: tau's even spacing where it has one (_samples),
    else 0."""
    from optim.families.time_optimal.certify_kernels import phi_values  # (numba: in the process that refines)

    poles = np.asarray(spec.zero_poles, dtype=complex)
    tau = np.ascontiguousarray(tau)
    values: Array = phi_values(tau, step, theta, spec.order, poles, spec.derivative_order, derivative)
    return values


def _width(spec: Spec) -> int:
    """theta's size: the end state's q - 1 conditions, then Re and Im of each pole's moments up to the order."""
    return spec.order - 1 + 2 * len(spec.zero_poles) * (spec.derivative_order + 1)


def certificate_applies(spec: Spec) -> bool:
    return spec.rest_to_rest and not spec.in_motion and not spec.bands and spec.torque is None


def _levels(spec: Spec, arcs: tuple[Arc, ...]) -> Array | None:
    """The arcs' levels in the unit, snapped to -1, 0, 1; None if one is on none of them."""
    levels = np.array([a.level for a in arcs]) / spec.scale
    snapped = np.round(levels)
    if np.any(np.abs(levels - snapped) > LEVEL_TOLERANCE) or np.any(np.abs(snapped) > 1):
        return None
    return snapped


def _near(value: float, target: float, limit: float) -> bool:
    return abs(value - target) <= STATE_TOLERANCE * limit


def _kinds(spec: Spec, durations: Array, levels: Array, touched: NDArray[np.intp]) -> tuple[Array, Array] | None:
    """(kind, sign) of every arc: BANG with its level, FIRST at +-the limit one order below q, SECOND (q = 3) a coast
    at +-max_velocity; None if a rest is on no limit (a singular arc no constraint explains: not certifiable)."""
    below, velocity = arc_states(spec, durations, levels)
    kind = touched.astype(np.float64)  # (as the signs: the kinds are small integers)
    sign = np.where(touched == TOUCH, np.sign(velocity), levels)
    for k in np.flatnonzero((levels == 0.0) & (touched == BANG)):
        constrained = _constrained(spec, float(below[k]), float(velocity[k]))
        if constrained is None:
            return None
        kind[k], sign[k] = constrained
    return kind, sign


def _constrained(spec: Spec, below: float, velocity: float) -> tuple[int, float] | None:
    """(kind, sign) of a rest (level 0) that starts with ``below`` (one order below q) and ``velocity``: FIRST at
    +-that limit, SECOND (q = 3) a coast at +-max_velocity with zero acceleration; None if it is on no limit."""
    first = spec.max_velocity if spec.order == 2 else spec.max_acceleration
    if first is not None and _near(abs(below), first, first):
        return FIRST, math.copysign(1.0, below)
    coasting = spec.order == 3 and spec.max_velocity is not None
    if coasting and _near(below, 0.0, spec.max_acceleration or spec.scale):
        assert spec.max_velocity is not None
        if _near(abs(velocity), spec.max_velocity, spec.max_velocity):
            return SECOND, math.copysign(1.0, velocity)
    return None


def constraints(spec: Spec, durations: Array, levels: Array) -> list[tuple[int, float] | None]:
    """Per arc (``levels`` in the unit): (kind, sign) of a rest on a limit (FIRST or SECOND, as ``_kinds``); None for
    bang and fractional arcs and for a rest on no limit."""
    below, velocity = arc_states(spec, durations, levels)
    return [
        _constrained(spec, float(b), float(v)) if abs(level) <= LEVEL_TOLERANCE else None
        for b, v, level in zip(below, velocity, levels, strict=True)
    ]


def on_a_limit(spec: Spec, durations: Array, levels: Array) -> NDArray[np.bool_]:
    """Per arc (``levels`` in the unit): whether it is a rest on a limit (a constrained arc of ``_kinds``)."""
    return np.array([c is not None for c in constraints(spec, durations, levels)], dtype=bool)


Linear = tuple[Array, float]  # coefficients over the unknowns (theta, then the coasts' entry atoms), constant


def _phis(spec: Spec, width: int, tau: Array, derivative: int = 0) -> list[Linear]:
    """phi^(derivative)(tau) at each of ``tau`` as linear functions of the unknowns (one _basis call for all)."""
    rows = np.zeros((tau.size, width))
    basis = _basis(spec, tau, derivative)
    rows[:, : basis.shape[1]] = -basis
    constants = kernel(spec.order, tau, derivative)
    return [(rows[i], float(constants[i])) for i in range(tau.size)]


def _sweep(
    spec: Spec, starts: Array, ends: Array, kind: Array
) -> tuple[list[tuple[Linear, Linear]], list[Linear], list[tuple[int, float, Linear]]]:
    """From the end back: each arc's line (alpha + beta s) that sigma = phi(T - s) less it on a bang arc (on a
    constrained arc: the line after it), the junction conditions (linear functions that must vanish) and the coasts'
    atoms (coast, time, mass)."""
    total = float(ends[-1])
    atomic = (kind == SECOND) | (kind == TOUCH)  # arcs with an unknown atom of nu
    width = _width(spec) + int(np.sum(atomic))
    at_starts = _phis(spec, width, total - starts)  # phi(T - s1) of every arc
    zero: Linear = (np.zeros(width), 0.0)
    if np.all(kind == BANG):  # no rest on a limit: every line is 0, a switch sigma = phi = 0 at each arc's start
        return [(zero, zero)] * kind.size, [at_starts[k] for k in range(kind.size - 1, 0, -1)], []
    slopes = _phis(spec, width, total - np.concatenate([starts, ends]), 1)  # phi'(T - s1), then phi'(T - s2)
    alpha, beta = zero, zero
    lines: list[tuple[Linear, Linear]] = [(zero, zero)] * kind.size
    conditions: list[Linear] = []
    atoms: list[tuple[int, float, Linear]] = []
    column = width - int(np.sum(atomic))
    for k in range(kind.size - 1, -1, -1):
        s1, s2 = float(starts[k]), float(ends[k])
        lines[k] = (alpha, beta)
        phi = at_starts[k]
        if kind[k] == TOUCH:  # an atom m of nu at s1, no junction: sigma less m (s1 - s) before it (alpha + m s1,
            unknown = np.zeros(width)  # beta - m)
            unknown[column] = 1.0
            column += 1
            atoms.append((k, s1, (unknown, 0.0)))
            alpha, beta = (alpha[0] + s1 * unknown, alpha[1]), (beta[0] - unknown, beta[1])
            continue
        if kind[k] == BANG:
            if k > 0 and kind[k - 1] != TOUCH:  # sigma = 0 where this arc begins: a switch, or the exit of the
                # constrained arc before it (a touch's bang arc goes on through it)
                conditions.append((phi[0] - alpha[0] - s1 * beta[0], phi[1] - alpha[1] - s1 * beta[1]))
            continue
        if kind[k] == SECOND:  # nu's exit atom: phi'(T - s2) + beta after; the entry's, an unknown
            slope = slopes[kind.size + k]
            atoms.append((k, s2, (slope[0] + beta[0], slope[1] + beta[1])))
            entry = slopes[k]
            unknown = np.zeros(width)
            unknown[column] = 1.0
            column += 1
            atoms.append((k, s1, (unknown, 0.0)))
            beta = (-entry[0] - unknown, -entry[1])
        # the line before the arc meets phi at its entry (sigma = 0 there), with the slope just found
        alpha = (phi[0] - s1 * beta[0], phi[1] - s1 * beta[1])
    return lines, conditions, atoms


def _samples(spec: Spec, durations: Array, starts: Array, ends: Array) -> tuple[Array, NDArray[np.intp], Array] | None:
    """The check points s (each arc's evenly spaced, ends included), their arcs, and each point's step in T - s from
    the point before on its arc (0 for an arc's first point: certify_kernels.phi_values' products); None beyond
    MAX_CHECKS."""
    fastest = max(abs(p.imag) for p in spec.zero_poles) if spec.zero_poles else 0.0
    spacing = 2 * math.pi / fastest / CHECK_PER_PERIOD if fastest > 0 else float(ends[-1])
    counts = np.maximum(MIN_CHECKS, np.ceil(durations / spacing)).astype(np.int64)
    if int(np.sum(counts)) > MAX_CHECKS:
        return None
    from optim.families.time_optimal.certify_kernels import check_points  # (numba: in the process that refines)

    s, arc, step = check_points(starts, ends, counts)  # np.linspace's own arithmetic, bit for bit
    return s, arc, step


def _wrong_signed(values: Array, scale: float) -> bool:
    return bool(np.any(values < -SIGN_TOLERANCE * (scale or 1.0)))


def _unknowns(conditions: list[Linear], total: float, q: int) -> Array | None:
    """The unknowns (theta, the entry atoms) that make every junction condition vanish, by least squares with
    scaled columns; None if the residual exceeds JUNCTION_TOLERANCE of k(T) (no multipliers fit the junctions)."""
    rows = np.array([c[0] for c in conditions])
    rhs = -np.array([c[1] for c in conditions])
    scale = np.max(np.abs(rows), axis=0) + 1e-300
    z: Array = np.linalg.lstsq(rows / scale, rhs, rcond=None)[0] / scale
    return None if np.max(np.abs(rows @ z - rhs)) > JUNCTION_TOLERANCE * float(kernel(q, np.array([total]))[0]) else z


@dataclass(frozen=True)
class _Switching:
    """sigma on the check points of a command whose junctions some multipliers fit (``_switching``)."""

    levels: Array  # each arc's level in the unit
    kind: Array
    sign: Array
    s: Array  # the check points (s, time from the start) and the arc of each
    arc: NDArray[np.intp]
    step: Array  # each point's step in T - s from the one before on its arc (0: its first)
    z: Array  # theta, then the entry atoms
    theta: Array
    beta: Array  # each arc's line's slope
    sigma: Array
    atoms: list[tuple[int, float, Linear]]
    total: float
    origin: NDArray[np.intp]  # each arc's index among the command's (``touches`` splits some)

    def agreement(self) -> tuple[Array, float]:
        """level x sigma at each check point (+inf off the bang arcs: >= 0 where they agree) and max |sigma| on them
        (the scale of a wrong sign)."""
        bang = self.kind[self.arc] == BANG
        size = float(np.max(np.abs(self.sigma[bang]), initial=0.0))
        return np.where(bang, self.levels[self.arc] * self.sigma, np.inf), size

    def slope(self, spec: Spec) -> Array:
        """phi'(T - s) at each check point."""
        return _phi(spec, self.total - self.s, self.step, self.theta, 1)

    def density(self, spec: Spec) -> tuple[Array, float]:
        """mu's density times the arc's sign at each check point (+inf off the first-order constrained arcs: >= 0
        where it has the right sign) and max |phi'(T - s)| (its scale)."""
        slope = self.slope(spec)
        first = self.kind[self.arc] == FIRST
        values = np.where(first, self.sign[self.arc] * (slope + self.beta[self.arc]), np.inf)
        return values, float(np.max(np.abs(slope)))

    def curvature(self, spec: Spec) -> tuple[Array, float]:
        """nu's density phi''(T - s) times the coast's sign at each check point (+inf off the coasts: >= 0 where it
        has the right sign) and max |phi''(T - s)| (its scale)."""
        bend = _phi(spec, self.total - self.s, self.step, self.theta, 2)
        second = self.kind[self.arc] == SECOND
        return np.where(second, self.sign[self.arc] * bend, np.inf), float(np.max(np.abs(bend)))


_last: tuple[Spec, tuple[Arc, ...], bool, _Switching | None] | None = None  # _switching's latest answer


def _switching(spec: Spec, arcs: tuple[Arc, ...], with_atoms: bool = False) -> _Switching | None:
    """_switching_of, remembered for the latest (spec, arcs, with_atoms): a chain asks wrong_sign where certificate
    has just failed, on the same command."""
    global _last
    last = _last
    if last is not None and last[0] is spec and last[2] == with_atoms and last[1] == arcs:
        return last[3]
    found = _switching_of(spec, arcs, with_atoms)
    _last = (spec, arcs, with_atoms, found)
    return found


def _switching_of(spec: Spec, arcs: tuple[Arc, ...], with_atoms: bool) -> _Switching | None:
    """sigma of ``arcs`` with the multipliers that fit its junctions (``with_atoms``: with an atom of nu at each
    touch point, ``touches``); None where the certificate does not apply, a level or a rest is off every limit, or
    no multipliers fit."""
    if not certificate_applies(spec) or not arcs:
        return None
    levels = _levels(spec, arcs)
    if levels is None:
        return None
    durations, levels, origin, touched = touches(spec, np.array([a.duration_s for a in arcs]), levels, with_atoms)
    kinds = _kinds(spec, durations, levels, touched)
    if kinds is None:
        return None
    kind, sign = kinds
    ends = np.cumsum(durations)
    starts = ends - durations
    total = float(ends[-1])
    sampled = _samples(spec, durations, starts, ends)
    lines, conditions, atoms = _sweep(spec, starts, ends, kind)
    z = None if sampled is None or not conditions else _unknowns(conditions, total, spec.order)
    if sampled is None or z is None:
        return None
    s, arc, step = sampled
    theta = z[: _width(spec)]
    alpha = np.array([line[0][0] @ z + line[0][1] for line in lines])
    beta = np.array([line[1][0] @ z + line[1][1] for line in lines])
    sigma = _phi(spec, total - s, step, theta) - alpha[arc] - beta[arc] * s
    return _Switching(levels, kind, sign, s, arc, step, z, theta, beta, sigma, atoms, total, origin)


def certificate(spec: Spec, arcs: tuple[Arc, ...]) -> Certificate | None:
    """The proof that ``arcs`` (merged, meeting the end conditions and the limits: the caller checks) are the
    minimum-time command of ``spec``, or None where this check does not apply or does not prove it. Tried without
    atoms at touch points first, then, where the velocity touches its limit, with them (``touches``)."""
    w = _switching(spec, arcs)
    proof = None if w is None else _proof(spec, w)
    if proof is not None or not _touches_any(spec, arcs):
        return proof
    w = _switching(spec, arcs, with_atoms=True)
    return None if w is None else _proof(spec, w)


def _touches_any(spec: Spec, arcs: tuple[Arc, ...]) -> bool:
    """Whether the velocity touches its limit inside a bang arc of ``arcs`` (``touches``)."""
    levels = _levels(spec, arcs)
    if levels is None:
        return False
    durations = np.array([a.duration_s for a in arcs])
    return bool(touches(spec, durations, levels, True)[0].size > durations.size)


def _proof(spec: Spec, w: _Switching) -> Certificate | None:
    """The certificate of the multipliers ``w`` found, if every sign agrees (see ``certificate``)."""
    from optim.families.time_optimal.certify_kernels import bang_disagrees, density_disagrees  # (numba: as _phi)

    sign, s, theta = w.sign, w.s, w.theta
    if bang_disagrees(w.sigma, w.arc, w.kind == BANG, w.levels, SIGN_TOLERANCE):  # agreement, with its minima
        return None
    first = w.kind == FIRST
    slope_size = 0.0  # mu's density: phi'(T - s) + beta, of the arc's sign (only where a first-order arc or an
    if np.any(first) or w.atoms:  # atom needs it)
        slope = w.slope(spec)
        if density_disagrees(slope, w.arc, first, sign, w.beta, SIGN_TOLERANCE):
            return None
        slope_size = float(np.max(np.abs(slope)))
    if np.any(w.kind == SECOND) and _wrong_signed(*w.curvature(spec)):  # nu's density phi''(T - s), of the coast's
        return None  # sign (and its atoms, next)
    masses = [(k, t, float(m[0] @ w.z + m[1])) for k, t, m in w.atoms]
    if _wrong_signed(np.array([sign[k] * m for k, _, m in masses]), slope_size):
        return None
    return Certificate(theta, int(s.size), tuple((t, m) for _, t, m in masses))


def wrong_sign(spec: Spec, arcs: tuple[Arc, ...]) -> tuple[int, float, float] | None:
    """Where the multipliers that fit a command's junctions most contradict it: (the arc, the first and the last
    check point of its wrong-signed run there), the place a notch would shorten it. A bang arc where sigma has the
    other sign first (a notch of the other level); else a first-order constrained arc where mu's density has the
    wrong sign (a notch off the limit: with a held jerk, the acceleration leaves +-max_acceleration there); else a
    coast at +-max_velocity (held jerk) where nu's density has the wrong sign (a dip in the velocity). None if all
    agree everywhere or no multipliers fit."""
    w = _switching(spec, arcs)
    if w is None:
        return None
    checks = (w.agreement, lambda: w.density(spec), lambda: w.curvature(spec))  # each computed only if needed
    for check in checks:
        agreement, size = check()
        if _wrong_signed(agreement, size):
            break
    else:
        return None
    worst = int(np.argmin(agreement))
    k = int(w.arc[worst])
    right = (w.arc != k) | (agreement >= -SIGN_TOLERANCE * (size or 1.0))  # not wrong on arc k
    before, after = np.flatnonzero(right[:worst]), np.flatnonzero(right[worst:])
    lo = int(before[-1]) + 1 if before.size else 0  # the run of wrong points around the worst
    hi = worst + int(after[0]) - 1 if after.size else right.size - 1
    return int(w.origin[k]), float(w.s[lo]), float(w.s[hi])  # (the arc among the command's: a touch splits one)
