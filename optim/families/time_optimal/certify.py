"""A proof that a held-acceleration command is the minimum-time one: Pontryagin's switching function, written as
weak duality of the move's linear programme in function space (Dhanda, Vaughan and Singhose 2009 give its grid
form).

For a rest-to-rest move from rest with u = a / A in [-1, 1], the position reached at T is
D(u) = A int (T - s) u(s) ds, subject to the end velocity A int u = 0, the residual moments
A int (T - s)^n e^(p (T - s)) u(s) ds = 0 (every zero-residual pole p, n <= derivative order) and |v(t)| <= V. For any
multipliers theta and any signed measure mu on the velocity constraint (mu >= 0 where v = +V, <= 0 where v = -V),

    D(u) <= V |mu|([0, T]) + A int_0^T |sigma(s)| ds,  sigma(s) = phi(T - s) - mu([s, T]),
    phi(tau) = tau - theta_0 - sum_i theta_i R_i(tau)   (R_i: the real and imaginary parts of tau^n e^(p tau)).

A command with u = sign(sigma) on its bang arcs, sigma = 0 on its coasts at +-V (there mu has the density
phi'(T - s), of the coast's sign) and mu nowhere else reaches that bound: no command of the same duration goes
further. The kernels depend on T - s only, so the same multipliers, shifted with the end, bound every shorter
duration strictly below D: the command is the minimum-time one (and the reachable distance only grows with the
duration, since a rest prefix keeps every end condition).

``certificate`` finds theta from the junctions (sigma = 0 at every switch and every coast's exit; a coast's
entry holds by construction) and checks the signs on CHECK_PER_PERIOD points per period of the fastest mode on
every arc. A command it does not certify may still be optimal (the caller's search decides then).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from optim.families.time_optimal.types import Arc, Spec

Array = NDArray[np.float64]
CHECK_PER_PERIOD = 64  # sign checks per period of the fastest zero-residual mode, on every arc (and at each local
# minimum of level * sigma between them, by its parabola: sigma is smooth at that scale)
MIN_CHECKS = 16  # per arc, at least
MAX_CHECKS = 200_000  # a command needing more checks is not certified here (its search answers)
LEVEL_TOLERANCE = 1e-9  # of the unit: a level this close to -1, 0 or 1 is that level
JUNCTION_TOLERANCE = 1e-6  # of the duration: the junction conditions' residual for a consistent theta (a refined
# structure's switching times are exact to about this: its duration is flat in them at the optimum)
SIGN_TOLERANCE = 1e-6  # of max |sigma|: wrong-signed values next to a switch, from switching times exact to about
# JUNCTION_TOLERANCE (they shift sigma's zero by that much: the distance lost is second order, below 1e-12)


@dataclass(frozen=True)
class Certificate:
    """The multipliers that prove the command optimal, and how many points checked their signs."""

    theta: Array
    checked_points: int

    def describe(self) -> str:
        return (
            "the switching function (Pontryagin; weak duality of the move's linear programme) certifies it the "
            f"minimum-time command: no shorter one exists (signs checked on {self.checked_points} points)"
        )


def _basis(spec: Spec, tau: Array) -> tuple[Array, Array]:
    """The columns of phi's unknown part at ``tau`` (1, then Re and Im of tau^n e^(p tau) for every pole and n), and
    their derivatives in tau."""
    columns = [np.ones_like(tau)]
    slopes = [np.zeros_like(tau)]
    for pole in spec.zero_poles:
        wave = np.exp(pole * tau)
        for n in range(spec.derivative_order + 1):
            power = tau**n
            value = power * wave
            slope = (n * tau ** (n - 1) if n else 0.0) * wave + pole * value
            columns += [value.real, value.imag]
            slopes += [slope.real, slope.imag]
    return np.column_stack(columns), np.column_stack(slopes)


def _applies(spec: Spec) -> bool:
    return spec.order == 2 and spec.rest_to_rest and not spec.in_motion and not spec.bands and spec.torque is None


def _levels(spec: Spec, arcs: tuple[Arc, ...]) -> Array | None:
    """The arcs' levels in the unit, snapped to -1, 0, 1; None if one is on none of them."""
    levels = np.array([a.level for a in arcs]) / spec.scale
    snapped = np.round(levels)
    if np.any(np.abs(levels - snapped) > LEVEL_TOLERANCE) or np.any(np.abs(snapped) > 1):
        return None
    return snapped


def _coast_signs(spec: Spec, arcs: tuple[Arc, ...], levels: Array) -> Array | None:
    """+-1 on every coast (level 0) at +-max_velocity, 0 on the bang arcs; None if a coast is below the limit (a
    singular arc no velocity constraint explains: not certifiable)."""
    durations = np.array([a.duration_s for a in arcs])
    velocity = spec.scale * np.concatenate(([0.0], np.cumsum(levels * durations)[:-1]))  # at each arc's start
    signs = np.zeros(levels.size)
    for k in np.flatnonzero(levels == 0.0):
        limit = spec.max_velocity
        if limit is None or abs(abs(velocity[k]) - limit) > 1e-9 * limit:
            return None
        signs[k] = math.copysign(1.0, velocity[k])
    return signs


def _conditions(spec: Spec, ends: Array, total: float, levels: Array) -> tuple[Array, Array]:
    """Rows A theta = b: sigma = 0 at every junction but a coast's entry. Before a coast sigma is phi(T - s) less
    phi at that coast's entry (mu's mass from there on), after the last coast phi(T - s) itself."""
    pairs: list[tuple[float, float | None]] = []  # phi(tau1) = phi(tau2) (or 0 when tau2 is None)
    for k in range(levels.size - 1):
        if levels[k + 1] == 0.0:
            continue  # entering a coast: sigma = 0 there by mu's construction
        later = [j for j in range(k + 1, levels.size) if levels[j] == 0.0]
        entry = None if not later else total - ends[later[0] - 1]
        pairs.append((total - ends[k], entry))
    width = 1 + 2 * len(spec.zero_poles) * (spec.derivative_order + 1)
    if not pairs:
        return np.zeros((0, width)), np.zeros(0)
    tau1 = np.array([a for a, _ in pairs])
    tau2 = np.array([0.0 if b is None else b for _, b in pairs])  # 0 where unpaired: masked out below
    paired = np.array([b is not None for _, b in pairs])
    rows = _basis(spec, tau1)[0] - paired[:, None] * _basis(spec, tau2)[0]
    return rows, tau1 - np.where(paired, tau2, 0.0)


def _with_minima(values: Array, arc: NDArray[np.intp]) -> Array:
    """``values`` and, at each interior local minimum of their samples on one arc, the vertex of the parabola
    through it and its neighbours (a dip between two samples)."""
    mid = values[1:-1]
    same = (arc[:-2] == arc[1:-1]) & (arc[1:-1] == arc[2:])
    left, right = values[:-2], values[2:]
    dip = same & (mid <= left) & (mid <= right) & np.isfinite(mid)
    curvature = left[dip] - 2 * mid[dip] + right[dip]
    with np.errstate(divide="ignore", invalid="ignore"):
        vertex = mid[dip] - (right[dip] - left[dip]) ** 2 / (8 * curvature)
    vertex = np.where(curvature > 0, vertex, mid[dip])
    return np.concatenate([values, vertex])


def certificate(spec: Spec, arcs: tuple[Arc, ...]) -> Certificate | None:
    """The proof that ``arcs`` (merged, meeting the end conditions and the limits: the caller checks) are the
    minimum-time command of ``spec``, or None where this check does not apply or does not prove it."""
    if not _applies(spec) or not arcs:
        return None
    levels = _levels(spec, arcs)
    if levels is None:
        return None
    signs = _coast_signs(spec, arcs, levels)
    if signs is None:
        return None
    durations = np.array([a.duration_s for a in arcs])
    ends = np.cumsum(durations)
    total = float(ends[-1])
    starts = ends - durations
    fastest = max(abs(p.imag) for p in spec.zero_poles) if spec.zero_poles else 0.0
    spacing = 2 * math.pi / fastest / CHECK_PER_PERIOD if fastest > 0 else total
    counts = np.maximum(MIN_CHECKS, np.ceil(durations / spacing)).astype(int)
    if int(np.sum(counts)) > MAX_CHECKS:
        return None
    rows, rhs = _conditions(spec, ends, total, levels)
    if rows.shape[0] == 0:
        return None
    scale = np.max(np.abs(rows), axis=0) + 1e-300
    theta = np.linalg.lstsq(rows / scale, rhs, rcond=None)[0] / scale
    if np.max(np.abs(rows @ theta - rhs)) > JUNCTION_TOLERANCE * total:
        return None
    # sigma on every arc's check points: phi(T - s) less mu's mass from s on
    s = np.concatenate([np.linspace(a, b, n) for a, b, n in zip(starts, ends, counts, strict=True)])
    arc = np.repeat(np.arange(levels.size), counts)
    tau = total - s
    basis, slopes = _basis(spec, tau)
    phi = tau - basis @ theta
    entries = np.full(levels.size, np.nan)  # phi at the next coast's entry, for each arc before it
    following = math.nan
    for k in range(levels.size - 1, -1, -1):
        if levels[k] == 0.0:
            following = float(total - starts[k] - _basis(spec, np.array([total - starts[k]]))[0][0] @ theta)
        entries[k] = following
    mass = np.where(np.isnan(entries[arc]), 0.0, entries[arc])
    sigma = phi - mass
    bang = levels[arc] != 0.0
    size = float(np.max(np.abs(sigma[bang]), initial=0.0)) or 1.0
    signed = np.where(bang, levels[arc] * sigma, np.inf)
    if float(np.min(_with_minima(signed, arc))) < -SIGN_TOLERANCE * size:
        return None
    density = 1.0 - slopes @ theta  # phi'(T - s): mu's density on a coast, of the coast's sign
    coast = ~bang
    if np.any(signs[arc][coast] * density[coast] < -SIGN_TOLERANCE * (float(np.max(np.abs(density))) or 1.0)):
        return None
    return Certificate(theta, int(s.size))
