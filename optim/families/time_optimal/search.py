"""The minimum-time search: bisection on the grid, cutting planes for the bands, exact refinement, certificate.

1. On a grid of ``STEPS`` steps over an upper guess (doubled until feasible, up to max_duration_s),
   feasibility is monotone in the number of steps (a feasible command padded with rest stays
   feasible: its residual at the end only decays), so bisection finds the grid's shortest command.
   Bands enter as cutting planes: each LP holds the band at the points found so far, the dense check
   (optim.families.time_optimal.check) adds the worst violating points until it passes.
2. The grid optimum's structure is refined to exact switching times (optim.families.time_optimal.refine), kept
   only if it meets every constraint on the dense check and is shorter; a probe on a finer grid looks for
   a better structure (see ``solve``). With a torque limit or a band, the grid optimum on a 4x finer grid
   is the answer (within one of its steps of that grid's optimum).
3. ``lower_bound_s``: the largest duration whose relaxed LP (optim.families.time_optimal.lp.relaxed_lp) HiGHS
   proves infeasible, found by bisection, or the rigid kinematic floor: no command at all (not only on
   the grid) that short meets the constraints.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from models.errors import Infeasible, SolverFailed
from optim.families.time_optimal.arcs import SNAP, arcs_of, merged, structure
from optim.families.time_optimal.check import (
    CHECK_MARGIN,
    INITIAL_POINTS,
    band_grid,
    dense_points,
    violations,
    worst_ratios,
)
from optim.families.time_optimal.lp import MARGIN, Cut, LpCounter, grid_lp, pieces, relaxed_lp
from optim.families.time_optimal.refine import refine
from optim.families.time_optimal.shaped import shaped_start
from optim.families.time_optimal.types import Arc, Band, GridSolution, Solution, Spec
from optim.families.time_optimal.weights import exponential_moment, integrated_box

Array = NDArray[np.float64]
FALLBACK_FINER = 4  # without a refinement, the grid optimum is sought again on steps this much shorter
PROBES = 3
PROBE_FINER = 4  # the probe's grid is this much finer than the search's
STEPS = 96  # steps over the search's upper duration
CUT_ROUNDS = 12
RELAXED_STEPS = 250
BOUND_BISECTIONS = 2
PHASE_STEP = 0.15  # rad
MAX_INITIAL_POINTS = 200
MAX_ARCS = 16  # a grid solution with more arcs is not refined (it chatters: another start is tried)


class _Search:
    def __init__(self, spec: Spec) -> None:
        self.spec = spec
        self.counter = LpCounter(time_limit_s=spec.lp_time_limit_s)
        self.dense = [band_grid(spec, b, dense_points(b, spec.upper_guess_s)) for b in spec.bands]
        self.cuts: list[Cut] = []
        for b in spec.bands:
            points = initial_points(b, spec.upper_guess_s)
            self.cuts += band_grid(spec, b, points).cuts(np.arange(points * len(b.damping_ratios)))

    def feasible(self, steps: int, dt: float, weights: Array | None = None) -> Array | None:
        """A grid command of ``steps`` steps meeting every constraint (bands on the dense check), or None."""
        for _ in range(CUT_ROUNDS):
            x = grid_lp(self.spec, steps, dt, self.cuts, self.counter, weights)
            if x is None:
                return None
            start, end = pieces(steps, dt)
            added = self.add_cuts(start, end, self.spec.scale * x, steps * dt)
            if not added:
                return x
        return None  # the band still fails the dense check: not shown feasible at this length

    def add_cuts(self, start: Array, end: Array, level: Array, total: float) -> bool:
        added = False
        for grid in self.dense:
            ratios = worst_ratios(self.spec, grid, start, end, level, total)
            worst = violations(ratios / (1.0 - CHECK_MARGIN), len(grid.band.damping_ratios))
            if worst.size:
                self.cuts += grid.cuts(worst)
                added = True
        return added

    def grid_optimum(self) -> GridSolution:
        spec = self.spec
        upper = max(spec.upper_guess_s, spec.floor_s * 1.01)
        while True:
            dt = upper / STEPS
            x = self.feasible(STEPS, dt)
            if x is not None:
                break
            if upper >= spec.max_duration_s:
                self.not_found()
            upper = min(2.0 * upper, spec.max_duration_s)
        coarse = self._narrow(dt, min(math.floor(spec.floor_s / dt), STEPS - 1), STEPS, x)
        hi = coarse.steps
        if hi < STEPS // 2:  # the guess was far too long: search again on steps that fit the duration found
            fine = self.bisect(hi * dt / STEPS, math.floor(spec.floor_s / (hi * dt / STEPS)), STEPS)
            if fine is not None:
                return fine
        return coarse

    def bisect(self, dt: float, lo: int, hi: int) -> GridSolution | None:
        """The least feasible step count in (lo, hi] on steps of dt (None if hi itself is not shown feasible)."""
        best = self.feasible(hi, dt)
        return None if best is None else self._narrow(dt, min(lo, hi - 1), hi, best)

    def _narrow(self, dt: float, lo: int, hi: int, best: Array) -> GridSolution:
        """Bisection between ``lo`` (no command found) and ``hi`` (``best`` feasible) on steps of dt."""
        while hi - lo > 1:
            mid = (lo + hi) // 2
            y = self.feasible(mid, dt)
            if y is None:
                lo = mid
            else:
                hi, best = mid, y
        return GridSolution(dt, hi, best, lo)

    def late_vertex(self, steps: int, dt: float) -> Array | None:
        """The vertex of the weighted-L1 objective sum (0.01 + (k/N)^4) |x_k| on N steps of dt: it acts as early
        as it can (a proxy for a shorter command), another arc structure than a feasibility vertex's."""
        k = np.arange(steps, dtype=float)
        return self.feasible(steps, dt, 0.01 + ((k + 1) / steps) ** 4)

    def not_found(self) -> None:
        spec = self.spec
        if not relaxed_lp(spec, spec.max_duration_s, RELAXED_STEPS, self.cuts, self.counter):
            raise Infeasible(
                f"no command of duration <= max_duration_s = {spec.max_duration_s:.6g} s meets the limits"
                f"{' and the robustness band' if spec.bands else ''} (HiGHS proves a relaxation of every such "
                "command infeasible); relax the band or the limits, or allow a longer max_duration_s",
                "robustness" if spec.bands else "limits",
            )
        raise SolverFailed(
            self.counter.report("not_found"),
            f"no command of duration <= max_duration_s = {spec.max_duration_s:.6g} s was found on the search grid "
            "(infeasibility is not proven); allow a longer max_duration_s",
        )

    def lower_bound(self, found_s: float, spec: Spec | None = None) -> tuple[float, str]:
        """(bound, method): the largest duration proven infeasible, by the relaxed LP or the kinematics. The
        relaxation's gap is a few of its steps: it is probed two steps below the duration found, then halfway
        to the floor, then bisected BOUND_BISECTIONS times between the proven and the unproven (at most 4 LPs).
        ``spec``: the problem it certifies (default the searched one; the caller's original when the search ran
        with a limit tightened)."""
        spec = spec or self.spec
        lo, hi = spec.floor_s, found_s
        method = "kinematic floor (the rigid time-optimal move within the limits)"
        step = found_s / RELAXED_STEPS
        if spec.max_acceleration is None or hi - lo <= 4.0 * step:  # nothing the relaxation could prove
            return lo, method
        proven = "relaxed LP proven infeasible by HiGHS (no command of that duration exists)"
        for probe in (found_s - 2.0 * step, 0.5 * (lo + found_s - 2.0 * step)):
            if relaxed_lp(spec, probe, RELAXED_STEPS, self.cuts, self.counter):
                hi = probe
                continue
            lo, method = probe, proven
            for _ in range(BOUND_BISECTIONS):
                mid = 0.5 * (lo + hi)
                if relaxed_lp(spec, mid, RELAXED_STEPS, self.cuts, self.counter):
                    hi = mid
                else:
                    lo = mid
            break
        return lo, method

    def verified(self, arcs: tuple[Arc, ...]) -> bool:
        """The refined command meets the bands on the dense check (its limits are checked by the caller)."""
        if not self.dense:
            return True
        start = np.array([a.start_s for a in arcs])
        end = start + np.array([a.duration_s for a in arcs])
        level = np.array([a.level for a in arcs])
        total = float(end[-1])
        return all(
            float(np.max(worst_ratios(self.spec, grid, start, end, level, total))) <= 1.0 - CHECK_MARGIN
            for grid in self.dense
        )


def initial_points(band: Band, duration_s: float) -> int:
    """Band points to start with: about one per PHASE_STEP radians of the residual's phase across the band
    (the phase of F_0 turns by about T dw), so that few cutting-plane rounds are needed."""
    span = (band.high_rad_s - band.low_rad_s) * duration_s
    return int(min(MAX_INITIAL_POINTS, max(INITIAL_POINTS, math.ceil(span / PHASE_STEP) + 1)))


def project(spec: Spec, grid: GridSolution) -> Array:
    """The grid values moved (by a least-norm step, ~1e-8 of the unit) onto the equalities exactly."""
    return project_values(spec, grid, grid.values)


def project_values(spec: Spec, grid: GridSolution, values: Array) -> Array:
    """Steps within SNAP of +-1 or 0 set to exactly that level (a bang is a bang), the others moved by a
    least-norm step onto the equalities; without enough free steps, or if that breaks a bound, every step
    is moved instead (by ~1e-8 of the unit)."""
    rows, rhs = equality_system(spec, grid.steps, grid.step_s)
    boxed = spec.order == 3 or spec.max_acceleration is not None
    if not rows.size:
        return values.copy()
    snapped = values.copy()
    for level in (-1.0, 0.0, 1.0):
        snapped[np.abs(values - level) < SNAP] = level
    free = np.flatnonzero(~np.isin(snapped, (-1.0, 0.0, 1.0)))
    if free.size >= 2 * rows.shape[0]:
        x = snapped.copy()
        x[free] += np.linalg.lstsq(rows[:, free], rhs - rows @ snapped, rcond=None)[0]
        if (not boxed or np.max(np.abs(x[free])) <= 1.0 - 0.5 * MARGIN) and _nodes_within(spec, grid, x):
            return x
    return values + np.linalg.lstsq(rows, rhs - rows @ values, rcond=None)[0]


def _nodes_within(spec: Spec, grid: GridSolution, values: Array) -> bool:
    """The velocity (and, with a held jerk, the acceleration) of the grid command within its limits at the
    nodes: snapping moves them by up to SNAP x the unit x the duration, more than the LP's margin."""
    start, end = pieces(grid.steps, grid.step_s)
    nodes = np.arange(1, grid.steps + 1, dtype=float) * grid.step_s
    for m, limit in ((1, spec.max_velocity), (2, spec.max_acceleration if spec.order == 3 else None)):
        if limit is None:
            continue
        peak = float(np.max(np.abs(spec.scale * integrated_box(nodes, start, end, spec.order - m) @ values)))
        if peak > limit * (1.0 - 0.5 * MARGIN):
            return False
    return True


def equality_system(spec: Spec, steps: int, dt: float) -> tuple[Array, Array]:
    """The LP's equalities (end state, residual moments) on the grid's values, each row scaled to max 1."""
    q, unit = spec.order, spec.scale
    start, end = pieces(steps, dt)
    total = steps * dt
    rows: list[Array] = []
    rhs: list[float] = []
    for m, target in spec.end_targets().items():
        row = unit * integrated_box(np.array([total]), start, end, q - m)[0]
        scale = np.max(np.abs(row))
        rows.append(row / scale)
        rhs.append(target / scale)
    for n in range(spec.derivative_order + 1):
        if not spec.zero_poles:
            break
        w = unit * exponential_moment(np.asarray(spec.zero_poles), start, end, total, n)
        for row in w:
            scale = np.max(np.abs(row))
            rows += [row.real / scale, row.imag / scale]
            rhs += [0.0, 0.0]
    return np.vstack(rows) if rows else np.zeros((0, steps)), np.asarray(rhs)


def _clip(spec: Spec, values: Array) -> Array:
    return np.clip(values, -1.0, 1.0) if (spec.order == 3 or spec.max_acceleration is not None) else values


def _refine_best(
    spec: Spec,
    search: _Search,
    starts: list[tuple[Array, float]],
    best: tuple[Arc, ...] | None,
    check_limits: Callable[[tuple[Arc, ...]], bool] | None,
) -> tuple[tuple[Arc, ...] | None, str]:
    """The shortest refined command from the given grid starts that checks out (or ``best``), and how."""
    how = ""
    for start, step in starts:
        parts = structure(start, step)
        if len(parts[0]) > MAX_ARCS:
            continue
        result = refine(spec, *parts, search.cuts)
        if result is None:
            continue
        total = sum(a.duration_s for a in result.arcs)
        shorter = best is None or total < sum(a.duration_s for a in best)
        if shorter and (check_limits is None or check_limits(result.arcs)) and search.verified(result.arcs):
            best, how = merged(result.arcs), result.status
    return best, how


def _shaped_best(
    spec: Spec,
    search: _Search,
    best: tuple[Arc, ...] | None,
    how: str,
    check_limits: Callable[[tuple[Arc, ...]], bool] | None,
    grid_s: float,
) -> tuple[tuple[Arc, ...] | None, str]:
    """The shaped rigid move (optim.families.time_optimal.shaped), refined, or as it is, where it is shorter than
    ``best`` and than the grid optimum (``grid_s``): the answer is never longer than ZV shaping of the rigid
    move (ZV^(n+1) for derivative order n)."""
    start = shaped_start(spec)
    if start is None:
        return best, how
    durations, levels, free = start
    edges = np.concatenate(([0.0], np.cumsum(durations)))
    shaped = tuple(Arc(float(edges[k]), float(durations[k]), float(levels[k] * spec.scale)) for k in range(len(levels)))
    candidates = [(merged(shaped), "the rigid move shaped by ZV per mode (no shorter command was found)")]
    result = refine(spec, durations, levels, free, search.cuts) if len(durations) <= MAX_ARCS else None
    if result is not None:
        candidates.insert(0, (merged(result.arcs), f"{result.status} (from the shaped rigid move)"))
    for arcs, note in candidates:
        total = sum(a.duration_s for a in arcs)
        if total >= grid_s or (best is not None and total >= sum(a.duration_s for a in best)):
            continue
        if (check_limits is None or check_limits(arcs)) and search.verified(arcs):
            return arcs, note
    return best, how


def solve(
    spec: Spec, check_limits: Callable[[tuple[Arc, ...]], bool] | None = None, bound_spec: Spec | None = None
) -> Solution:
    """The minimum-time command of ``spec`` (see the module's docstring). ``check_limits(arcs) -> bool``
    tells whether a refined command meets the limits exactly (the caller's independent check); ``bound_spec``
    is the problem lower_bound_s certifies (default ``spec``).

    Without a torque limit or a band, the grid optimum's structure is refined to exact switching times (or,
    failing that, the structure of the early-acting weighted-L1 vertex); then a probe asks a grid PROBE_FINER
    times finer for the early-acting vertex at the refined duration: if one exists, its structure is refined in
    turn (at most PROBES times), so that a local optimum of one structure is not returned where a shorter one
    exists on the fine grid."""
    began = time.perf_counter()  # for solve_time_s only: the search's caps are counts (optim.families.time_optimal.lp)
    search = _Search(spec)
    grid = search.grid_optimum()
    values = _clip(spec, project(spec, grid))
    arcs = arcs_of(spec.scale * values, grid.step_s)
    refined, how = False, "not refined"
    if spec.torque is not None or spec.bands:
        how = (
            "not refined: with a torque limit or a band the grid optimum is returned (on the finer grid, within one "
            "of its steps of it)"
        )
    else:
        best, how = _refine_best(spec, search, [(values, grid.step_s)], None, check_limits)
        if best is None:  # another vertex, another structure
            late = search.late_vertex(grid.steps, grid.step_s)
            if late is not None:
                best, how = _refine_best(spec, search, [(_clip(spec, late), grid.step_s)], None, check_limits)
        best, how = _shaped_best(spec, search, best, how, check_limits, grid.steps * grid.step_s)
        for _ in range(PROBES if best is not None else 0):
            assert best is not None
            total = sum(a.duration_s for a in best)
            steps = PROBE_FINER * grid.steps
            dt = total / steps
            probe = search.late_vertex(steps, dt)
            if probe is None:
                break
            better, note = _refine_best(spec, search, [(np.clip(probe, -1, 1), dt)], best, check_limits)
            if better is best:
                break
            best, how = better, note
        if best is None:
            how = (
                "the refined switching times did not converge or check out (limits, band): the grid optimum is returned"
            )
        else:
            arcs, refined = best, True
    if not refined:  # the grid optimum on a grid FALLBACK_FINER times finer, from the coarse bounds
        fine = search.bisect(
            grid.step_s / FALLBACK_FINER, FALLBACK_FINER * grid.infeasible_steps, FALLBACK_FINER * grid.steps
        )
        if fine is not None:
            grid = fine
            values = _clip(spec, project(spec, fine))
            arcs = arcs_of(spec.scale * values, fine.step_s)
            if spec.torque is None and not spec.bands:  # the finer grid's structures, refined in turn
                starts = [(values, fine.step_s)]
                late = search.late_vertex(fine.steps, fine.step_s)
                if late is not None:
                    starts.append((_clip(spec, late), fine.step_s))
                best, note = _refine_best(spec, search, starts, arcs, check_limits)
                if best is not arcs and best is not None:
                    arcs, refined, how = best, True, f"{note} (from the finer grid's structure)"
    duration = sum(a.duration_s for a in arcs)
    bound, method = search.lower_bound(duration, bound_spec)
    return Solution(
        arcs=arcs,
        order=spec.order,
        duration_s=duration,
        lower_bound_s=min(bound, duration),
        lower_bound_method=method,
        grid=grid,
        refined=refined,
        refinement=how,
        lp_solves=search.counter.solves,
        lp_iterations=search.counter.iterations,
        solve_time_s=time.perf_counter() - began,
        cut_frequencies=len(search.cuts),
        max_lp_iterations=search.counter.max_iterations,
        max_lp_solves=search.counter.max_solves,
        capped_runs=search.counter.capped_runs,
        capped_lps=search.counter.capped_lps,
    )
