"""Refinement of the grid optimum: the switching times (and any free level) made exact.

The grid solution fixes the arc structure (bang, coast, switch inside a step). With the durations
(and the levels that are not saturated) as the unknowns, the shortest command of that structure is a
small smooth problem: minimise sum d_j subject to the end state and the residual moments (equalities),
the node bounds and the band points (|F_0|^2 <= c^2, true circles). It has a few to a few dozen
unknowns and closed-form constraints, so scipy's SLSQP solves it in milliseconds with no build cost
(a CasADi problem would have to be built for each structure; the constraints, their Jacobians and the Newton are
compiled once for all structures: optim.families.time_optimal.kernels); a Newton polish on the active
constraints then brings the equalities to round-off (from SLSQP's last point also where it stopped at its
iteration cap, after one more run from there: often a shorter command than its start). The caller keeps the
result only if it checks out (limits, dense band) and is shorter than the best so far.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize

from optim.families.time_optimal.lp import Cut
from optim.families.time_optimal.types import Arc, Spec

Array = NDArray[np.float64]
MAX_ITERATIONS = 80  # SLSQP's cap: a structure that needs more is not the optimum's (the grid's is kept)
RESTARTS = 1  # SLSQP stopped at its cap is run again from its last point (a fresh quasi-Newton model)
ITERATION_CAP = 9  # scipy's SLSQP status when it stops at MAX_ITERATIONS
TINY_ARC = 1e-6  # of the duration: a shorter refined arc is tried without
NEWTON_ITERATIONS = 12  # a start near the structure's solution converges quadratically well within this
STALL_AFTER = 4  # Newton iterations after which a residual that no longer halves ends the polish (None)
DAMPING_HALVINGS = 3  # a predicted start's Newton step is halved at most this often before it gives up
CONVERGED = 1e-12  # the scaled residual of a solved structure (round-off: 1e-16 to 1e-13)
ACTIVE = 1e-7  # a scaled inequality within this of its bound is held as an equality by the polish
BROKEN = 1e-10  # a polished command over a velocity peak by more than this (scaled: the family's exact check refuses
# it) is polished again with the broken rows held


@dataclass(frozen=True)
class Refined:
    arcs: tuple[Arc, ...]
    status: str


@functools.lru_cache(maxsize=64)
def _check_times(count: int, mid_arc: bool) -> Array:
    """The check points' times as rows . d over ``count`` arcs: every arc's end but the last (e_b = sum_(i <= b)
    d_i), then with ``mid_arc`` every arc's middle (shared by every structure of that size: never written; not
    flagged read-only, which numba would compile a second time for)."""
    arc_ends = np.tril(np.ones((count, count)))[:-1]
    mid = np.tril(np.ones((count, count)), -1) + 0.5 * np.eye(count)
    out = np.vstack([arc_ends, mid]) if mid_arc else arc_ends
    return out


@dataclass(frozen=True)
class _Fixed:
    """What every structure of one spec shares (the end state's orders and targets, the start state, the poles, the
    limits on check points): computed once per spec, where Newton builds sixteen models a design."""

    state: Array
    orders: NDArray[np.int64]
    targets: Array
    poles: NDArray[np.complex128]
    derivative_order: int
    limits: tuple[tuple[int, float], ...]
    bound_m: NDArray[np.int64]  # the limits' derivatives and values as arrays (kernels.polish's rows)
    bound_limit: Array


_NO_BOUNDS = (np.zeros(0, dtype=np.int64), np.zeros(0))
_NOT_FREE = np.zeros(0, dtype=np.int64)
_last_fixed: tuple[Spec, _Fixed] | None = None  # _fixed's latest answer


def _fixed(spec: Spec) -> _Fixed:
    global _last_fixed
    last = _last_fixed
    if last is not None and last[0] is spec:
        return last[1]
    targets = spec.end_targets()
    orders = np.fromiter(targets, dtype=np.int64)
    poles = np.asarray(spec.zero_poles, dtype=complex)
    below = [(1, spec.max_velocity)] + ([(2, spec.max_acceleration)] if spec.order == 3 else [])
    limits = tuple((m, float(limit)) for m, limit in below if limit is not None)
    fixed = _Fixed(
        state=np.asarray(spec.start_state(), dtype=float),
        orders=orders,
        targets=np.array([targets[m] for m in orders]),
        poles=poles,
        derivative_order=spec.derivative_order if poles.size else -1,
        limits=limits,
        bound_m=np.array([m for m, _ in limits], dtype=np.int64),
        bound_limit=np.array([limit for _, limit in limits], dtype=float),
    )
    _last_fixed = (spec, fixed)
    return fixed


class _Model:
    """The constraint functions of one arc structure and their Jacobians, in scaled variables
    z = (d / T0, free levels)."""

    def __init__(self, spec: Spec, durations: list[float], levels: list[float], free: list[bool], cuts: list[Cut]):
        # numba (~60 MiB) is imported by the first refinement, not by every process that imports the families
        from optim.families.time_optimal.kernels import (
            bound_system,
            end_system,
            inequality_system,
            moment_terms,
            peak_system,
            polish,
        )

        self.end_system: Any = end_system  # (numba's Dispatcher: typed by its arguments at run time)
        self.bound_system: Any = bound_system
        self.inequality_system: Any = inequality_system
        self.peak_system: Any = peak_system
        self.moment_terms: Any = moment_terms
        self.polish_kernel: Any = polish
        self.spec = spec
        self.t0 = sum(durations)
        self.levels = np.asarray(levels, dtype=float)
        durations_s = np.asarray(durations, dtype=float)
        self.count = len(durations)
        self.cuts = cuts
        if any(free):
            self.free = np.flatnonzero(np.asarray(free))
            self.z0 = np.concatenate([durations_s / self.t0, self.levels[self.free]])
        else:  # (Newton's models, sixteen a design: no level is free)
            self.free, self.z0 = _NOT_FREE, durations_s / self.t0
        q, u = spec.order, spec.scale
        fixed = _fixed(spec)
        self.free_at = self.free.astype(np.int64)
        self.state, self.orders, self.targets = fixed.state, fixed.orders, fixed.targets
        eq_scale = [spec.position_scale(self.t0)] + [u * self.t0 ** (q - m) for m in range(1, q)]
        self.eq_scale = np.array([eq_scale[m] for m in self.orders])
        self.poles, self.derivative_order = fixed.poles, fixed.derivative_order
        self.moment_scales = np.ones((self.derivative_order + 1, self.poles.size))  # sum |diff| at z0, fixed
        for n in range(self.derivative_order + 1):
            diff = moment_terms(self.poles, n, durations_s, self.levels, False)[2]
            self.moment_scales[n] = np.abs(diff).sum(axis=1) + 1e-300
        self.bounds = [  # (derivative, limit, the check points' times: rows . d): arc ends, and mid-arc with a jerk
            (m, limit, _check_times(self.count, m == 1 and q == 3)) for m, limit in fixed.limits if self.count >= 2
        ]
        self.structure = (  # (kernels.Structure)
            self.count,
            self.t0,
            self.levels,
            self.free_at,
            spec.scale,
            self.orders,
            self.targets,
            self.eq_scale,
            self.state,
            self.poles,
            self.derivative_order,
            self.moment_scales,
        )
        self.peaks = q == 3 and spec.max_velocity is not None  # velocity_peaks' rows (two per arc)
        self._last: dict[str, tuple[bytes, Array, Array | None]] = {}  # _remembered's
        # the same, for kernels.polish (per spec: _fixed), and no rows for a missing bound
        self.bound_m, self.bound_limit = (fixed.bound_m, fixed.bound_limit) if self.bounds else _NO_BOUNDS
        self.bound_times = [at for _, _, at in self.bounds]
        if len(self.bound_times) < 2:
            self.bound_times += [np.zeros((0, self.count))] * (2 - len(self.bound_times))

    def durations_and_levels(self, z: Array) -> tuple[Array, Array]:
        """The durations (negatives as 0) and the levels, the free ones from z (as kernels._unpack)."""
        d = np.maximum(z[: self.count], 0.0) * self.t0
        lv = self.levels.copy()
        lv[self.free] = z[self.count :]
        return d, lv

    def unpack(self, z: Array) -> tuple[Array, Array, Array]:
        d, lv = self.durations_and_levels(z)
        start = np.concatenate(([0.0], np.cumsum(d)[:-1]))
        return start, start + d, lv

    def _jac(self, jac_d: Any, diff: Any, scale: Any) -> Any:
        """d/dz of value / scale: d = z T0 (durations) and the free levels."""
        if jac_d is None:
            return None
        return np.hstack([jac_d * self.t0, diff[:, self.free]]) / np.asarray(scale).reshape(-1, 1)

    def _parts(self, z: Array, kind: str, want_jac: bool = True) -> tuple[Array, Array]:
        """The equalities (``kind`` "eq") or the inequalities (>= 0 when met), scaled, and their Jacobian in z
        (optim.families.time_optimal.kernels)."""
        spec, u = self.spec, self.spec.scale
        if kind == "eq":
            values, jac = self.end_system(z, self.structure, want_jac)
            return values, (jac if want_jac else np.zeros(0))
        if not self.cuts:  # (the bounds' and the peaks' rows in one compiled call)
            peak_limit = float(spec.max_velocity or 1.0)
            values, jac = self.inequality_system(
                z, self.structure, self.bound_m, self.bound_limit, *self.bound_times, self.peaks, peak_limit, want_jac
            )
            return values, (jac if want_jac else np.zeros(0))
        parts = [self.bound_system(z, self.structure, m, bound, at, want_jac) for m, bound, at in self.bounds]
        values_list = [part[0] for part in parts]
        jacs = [part[1] for part in parts]
        if self.cuts:
            d, lv = self.durations_and_levels(z)
            poles = np.array([c.pole for c in self.cuts])
            bound = np.array([c.bound for c in self.cuts])
            v, jd, diff = self.moment_terms(poles, 0, d, lv, want_jac)
            per = u / poles if spec.order == 3 else np.full(poles.size, complex(u))
            f = per * v
            values_list.append(1.0 - np.abs(f) ** 2 / bound**2)
            if want_jac:
                jac = self._jac(per[:, None] * jd, per[:, None] * diff, 1.0)
                jacs.append(-2.0 * np.real(np.conj(f)[:, None] * jac) / bound[:, None] ** 2)
        if self.peaks:
            peak, peak_jac = self.velocity_peaks(z, want_jac)
            values_list.append(peak)
            jacs.append(peak_jac)
        if not values_list:
            return np.zeros(0), np.zeros((0, z.size))
        return np.concatenate(values_list), (np.vstack(jacs) if want_jac else np.zeros(0))

    def velocity_peaks(self, z: Array, want_jac: bool) -> tuple[Array, Array]:
        """With a held jerk, the velocity where the acceleration crosses 0 inside an arc (its extremum there, which
        the check points at arc ends and middles miss), as 1 -+ v* / max_velocity >= 0 per arc, and the Jacobian in
        z (kernels.peak_system): an arc with no crossing gives an end's velocity (checked anyway); v* is continuous
        in z, smooth where the crossing is inside. Without it SLSQP converged to commands over the limit there (the
        exact check refused them: 7 of bench/programs.py's 48 designs answered the grid's command). (Rows for the
        arcs crossing 0 at the start only lost two of those certificates and a random move's 0.16 %; rows that
        vanish without a crossing, three and a grid answer: a row per arc is kept.)"""
        values, jac = self.peak_system(z, self.structure, float(self.spec.max_velocity or 1.0), want_jac)
        return values, (jac if want_jac else np.zeros(0))

    def _remembered(self, z: Array, kind: str, want_jac: bool) -> tuple[Array, Array]:
        """_parts remembered for the latest z of each kind, the Jacobian computed only when asked: SLSQP asks the
        values at each point of its line search (three a major iteration on bench/programs.py's designs), the
        Jacobian only at the point it accepts (the last one whose values it asked). The values do not depend on
        whether the Jacobian is computed (the same bits: kernels)."""
        key = z.tobytes()
        last = self._last.get(kind)
        if last is None or last[0] != key or (want_jac and last[2] is None):
            values, jac = self._parts(z, kind, want_jac)
            last = (key, values, jac if want_jac else None)
            self._last[kind] = last
        jac_or_none = last[2]
        return last[1].copy(), (np.zeros(0) if jac_or_none is None else jac_or_none.copy())  # (the caller may write)

    def equalities(self, z: Array) -> Array:
        return self._remembered(z, "eq", False)[0]

    def equality_jacobian(self, z: Array) -> Array:
        return self._remembered(z, "eq", True)[1]

    def inequalities(self, z: Array) -> Array:
        """>= 0 when met (scaled)."""
        return self._remembered(z, "ineq", False)[0]

    def inequality_jacobian(self, z: Array) -> Array:
        return self._remembered(z, "ineq", True)[1]


def refine(
    spec: Spec, durations: list[float], levels: list[float], free: list[bool], cuts: list[Cut]
) -> Refined | None:
    """The shortest command of the grid solution's structure, or None if SLSQP does not find one."""
    model = _Model(spec, durations, levels, free, cuts)
    n = model.z0.size
    bounds = [(0.0, None)] * model.count + [(-1.0, 1.0)] * model.free.size
    constraints: list[dict[str, object]] = [{"type": "eq", "fun": model.equalities, "jac": model.equality_jacobian}]
    if model.inequalities(model.z0).size:
        constraints.append({"type": "ineq", "fun": model.inequalities, "jac": model.inequality_jacobian})
    cost = np.concatenate([np.ones(model.count), np.zeros(n - model.count)])

    def run(start: Array) -> Any:
        return minimize(
            lambda z: float(cost @ z),
            start,
            jac=lambda z: cost,
            method="SLSQP",
            bounds=bounds,
            constraints=constraints,
            options={"maxiter": MAX_ITERATIONS, "ftol": 1e-10},
        )

    result = run(model.z0)
    for _ in range(RESTARTS):
        if result.status != ITERATION_CAP:
            break
        result = run(np.asarray(result.x, dtype=float))
    # SLSQP's status 9: its iteration cap. Its last point is often a shorter command than the start, short of
    # converged: the polish brings it onto the equalities or drops it, and the caller checks every limit exactly.
    if not result.success and result.status != ITERATION_CAP:
        return None
    x = np.asarray(result.x, dtype=float)
    z = _polish(model, x)
    if z is not None and model.peaks and float(np.min(model.velocity_peaks(z, False)[0])) < -BROKEN:
        held = _polish(model, x, hold_broken=True)  # over a velocity peak SLSQP left broken (stopped at its cap):
        z = held if held is not None else z  # polished again with the broken rows held
    if z is None:
        return None
    tiny = (z[: model.count] > 0.0) & (z[: model.count] < TINY_ARC)
    if np.any(tiny):  # an arc SLSQP left at a few ns is no arc: drop it if the polish still converges
        trial = z.copy()
        trial[: model.count][tiny] = 0.0
        dropped = _polish(model, trial)
        if dropped is not None and np.sum(dropped[: model.count]) <= np.sum(z[: model.count]) * (1 + 1e-9):
            z = dropped
    arcs = _arcs(spec, model, z)
    how = f"converged in {result.nit} iterations" if result.success else f"stopped at its cap of {MAX_ITERATIONS}"
    return Refined(arcs, f"SLSQP {how}; Newton polish on the active constraints")


def newton(spec: Spec, durations: list[float], levels: list[float]) -> Refined | None:
    """The command of a structure with fixed levels whose durations solve the end conditions and the active
    bounds, by Newton from ``durations`` (no minimisation: a square system where the structure is the optimum's,
    whose certificate the caller checks); None if it does not converge."""
    model = _Model(spec, durations, levels, [False] * len(levels), [])
    z = _polish(model, model.z0.copy(), NEWTON_ITERATIONS, stall=True)
    return None if z is None else Refined(_arcs(spec, model, z), "Newton on the switching times")


def end_conditions(spec: Spec, durations: list[float], levels: list[float]) -> Callable[[Array], tuple[Array, Array]]:
    """The end state's and the residuals' equalities of a structure with fixed levels (scaled as the refinement's)
    and their Jacobian, as functions of the durations d (s)."""
    model = _Model(spec, durations, levels, [False] * len(levels), [])

    def at(d: Array) -> tuple[Array, Array]:
        values, jac = model._parts(d / model.t0, "eq")
        return values, jac / model.t0

    return at


def _arcs(spec: Spec, model: _Model, z: Array) -> tuple[Arc, ...]:
    start, end, lv = model.unpack(z)
    duration = end - start
    keep = duration > 0.0
    rows = zip(start[keep].tolist(), duration[keep].tolist(), (lv[keep] * spec.scale).tolist(), strict=True)
    return tuple(Arc(s, d, level) for s, d, level in rows)  # (Python floats: the same values as float(x))


def _polish(
    model: _Model, z: Array, iterations: int = 20, stall: bool = False, hold_broken: bool = False
) -> Array | None:
    """Newton (minimal-norm steps) on the equalities and the active inequalities, from SLSQP's point (or a predicted
    start: with ``stall``, it gives up once its residual no longer halves); None if it does not converge. Compiled
    (kernels.polish) where the model has no band cuts, else ``_polish_numpy``: the same steps."""
    z = z.copy()
    z[: model.count] = np.where(z[: model.count] < 1e-8, 0.0, z[: model.count])
    levels = z[model.count :]
    on_level = np.zeros(levels.size, dtype=bool)
    for level in (-1.0, 0.0, 1.0) if levels.size else ():  # a free level SLSQP brought to a bound or to 0 is that
        near = np.abs(levels - level) < 1e-6  # level exactly
        levels[near] = level
        on_level |= near
    movable = np.flatnonzero(np.concatenate([z[: model.count] > 0.0, ~on_level]))
    ineq = model.inequalities(z)
    active = ineq < ACTIVE if hold_broken else np.abs(ineq) < ACTIVE  # (hold_broken: the broken rows too)
    peak_active = model.peaks and bool(np.any(active[-2 * model.count :]))  # (rows the compiled polish has not)
    if model.cuts or peak_active or not movable.size:
        return _polish_numpy(model, z, movable, np.flatnonzero(active), iterations, stall)
    rows = (model.bound_m, model.bound_limit, *model.bound_times, active, movable.astype(np.int64))
    z, ok = model.polish_kernel(z, model.structure, rows, iterations, stall, STALL_AFTER, DAMPING_HALVINGS, CONVERGED)
    return z if ok else None


def _polish_numpy(
    model: _Model, z: Array, movable: NDArray[np.intp], active: NDArray[np.intp], iterations: int, stall: bool
) -> Array | None:
    """_polish's Newton in numpy, on the ``active`` inequalities (indices) and the ``movable`` variables."""

    def system(v: Array, want_jac: bool = True) -> tuple[Array, Array]:
        """The equalities and the active inequalities at v, and their Jacobian in the movable variables."""
        values, jacs = model._parts(v, "eq", want_jac)
        if active.size:
            more, more_jac = model._parts(v, "ineq", want_jac)
            values = np.concatenate([values, more[active]])
            jacs = np.vstack([jacs, more_jac[active]]) if want_jac else jacs
        return values, (jacs[:, movable] if want_jac else jacs)

    previous = math.inf
    g, jac = system(z)
    for k in range(iterations):
        size = float(np.max(np.abs(g)))
        if size < 1e-14:
            return z
        if stall and k >= STALL_AFTER and size > 0.5 * previous:  # a predicted start far from its structure's solution
            return z if size < CONVERGED else None  # (or at round-off: the active bounds' is above 1e-14)
        previous = size
        step = np.linalg.lstsq(jac, g, rcond=None)[0]
        if stall:  # a predicted start: damped (the step halved until the residual falls and no duration is < 0)
            for _ in range(DAMPING_HALVINGS):
                trial = z.copy()
                trial[movable] -= step
                if np.all(trial[: model.count] >= -1e-12):
                    trial[: model.count] = np.maximum(trial[: model.count], 0.0)
                    g, jac = system(trial)
                    if np.max(np.abs(g)) < size:
                        break
                step = 0.5 * step
            else:
                return z if size < CONVERGED else None  # no step improves on round-off
            z = trial
        else:
            z[movable] -= step
            if np.any(z[: model.count] < -1e-12):
                return None
            z[: model.count] = np.maximum(z[: model.count], 0.0)
            g, jac = system(z)
    return z if float(np.max(np.abs(g))) < CONVERGED else None
