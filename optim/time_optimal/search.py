"""The minimum-time search: bisection on the grid, cutting planes for the bands, exact refinement, certificate.

1. On a grid of ``STEPS`` steps over an upper guess (doubled until feasible, up to max_duration_s),
   feasibility is monotone in the number of steps (a feasible command padded with rest stays
   feasible: its residual at the end only decays), so bisection finds the grid's shortest command.
   Bands enter as cutting planes: each LP holds the band at the points found so far, the dense check
   (optim.time_optimal.check) adds the worst violating points until it passes.
2. The grid optimum's structure is refined to exact switching times (optim.time_optimal.refine), kept
   only if it meets every constraint on the dense check and is shorter.
3. ``lower_bound_s``: the largest duration whose relaxed LP (optim.time_optimal.lp.relaxed_lp) HiGHS
   proves infeasible, found by bisection, or the rigid kinematic floor: no command at all (not only on
   the grid) that short meets the constraints.
"""

from __future__ import annotations

import math
import time

import numpy as np
from numpy.typing import NDArray

from models.errors import Infeasible, SolverFailed
from optim.solver import SolverReport
from optim.time_optimal import lp
from optim.time_optimal.arcs import arcs_of, merged, structure
from optim.time_optimal.check import DENSE_POINTS, INITIAL_POINTS, BandGrid, band_grid, violations, worst_ratios
from optim.time_optimal.lp import Cut, LpCounter, grid_lp, pieces, relaxed_lp
from optim.time_optimal.refine import refine
from optim.time_optimal.types import Arc, GridSolution, Solution, Spec

Array = NDArray[np.float64]
FINER = 2  # the second, finer grid's step is this fraction of the first's
STEPS = 128  # steps over the search's upper duration
CUT_ROUNDS = 12
RELAXED_STEPS = 250
BOUND_BISECTIONS = 7
BAND_RTOL = 1e-9
MAX_ARCS = 24  # a grid solution with more arcs is not refined (it chatters: another start is tried)


class _Search:
    def __init__(self, spec: Spec) -> None:
        self.spec = spec
        self.counter = LpCounter(deadline=time.perf_counter() + spec.wall_time_s)
        self.dense = [band_grid(spec, b, DENSE_POINTS) for b in spec.bands]
        self.cuts: list[Cut] = []
        self.alternatives: list[tuple[Array, float]] = []  # other vertices (values, step): other arc structures
        for b in spec.bands:
            self.cuts += band_grid(spec, b, INITIAL_POINTS).cuts(np.arange(INITIAL_POINTS * len(b.damping_ratios)))

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
            worst = violations(ratios / (1.0 + BAND_RTOL))
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
        lo = min(int(math.floor(spec.floor_s / dt)), STEPS - 1)
        hi, best = STEPS, x
        while hi - lo > 1:
            mid = (lo + hi) // 2
            y = self.feasible(mid, dt)
            if y is None:
                lo = mid
            else:
                hi, best = mid, y
        return self.finer(GridSolution(dt, hi, best, lo))

    def finer(self, coarse: GridSolution) -> GridSolution:
        """Other vertices at the grid optimum's duration on steps FINER times shorter: those of two weighted-L1
        objectives (acting early, and uniformly), starts for the refinement beside the coarse vertex."""
        steps, dt = FINER * coarse.steps, coarse.step_s / FINER
        k = np.arange(steps, dtype=float)
        for weights in (0.01 + ((k + 1) / steps) ** 4, np.ones(steps)):
            y = self.feasible(steps, dt, weights)
            if y is not None:
                self.alternatives.append((y, dt))
        return coarse

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
            SolverReport("not_found", self.counter.iterations, 0.0),
            f"no command of duration <= max_duration_s = {spec.max_duration_s:.6g} s was found on the search grid "
            "(infeasibility is not proven); allow a longer max_duration_s",
        )

    def lower_bound(self, found_s: float) -> tuple[float, str]:
        """(bound, method): the largest duration proven infeasible, by the relaxed LP or the kinematics. The
        relaxation's gap is a few of its steps, so it is probed there first, then bisected below."""
        spec = self.spec
        lo, hi = spec.floor_s, found_s
        method = "kinematic floor (the rigid time-optimal move within the limits)"
        if spec.max_acceleration is None or hi <= lo:
            return lo, method
        proven = "relaxed LP proven infeasible by HiGHS (no command of that duration exists)"
        step = found_s / RELAXED_STEPS
        if hi - lo <= 4.0 * step:  # within the relaxation's own gap of the floor: nothing more to prove
            return lo, method
        for gap in (2.0, 8.0):
            probe = found_s - gap * step
            if probe <= lo:
                break
            if not relaxed_lp(spec, probe, RELAXED_STEPS, self.cuts, self.counter):
                lo, method = probe, proven
                break
            hi = probe
        for _ in range(1 if method == proven else BOUND_BISECTIONS):
            mid = 0.5 * (lo + hi)
            if relaxed_lp(spec, mid, RELAXED_STEPS, self.cuts, self.counter):
                hi = mid
            else:
                lo, method = mid, proven
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
            float(np.max(worst_ratios(self.spec, grid, start, end, level, total))) <= 1.0 + BAND_RTOL
            for grid in self.dense
        )


def project(spec: Spec, grid: GridSolution) -> Array:
    """The grid values moved (by a least-norm step, ~1e-8 of the unit) onto the equalities exactly."""
    return project_values(spec, grid, grid.values)


def project_values(spec: Spec, grid: GridSolution, values: Array) -> Array:
    x = values.copy()
    rows, rhs = equality_system(spec, grid.steps, grid.step_s)
    if rows.size:
        x = x + np.linalg.lstsq(rows, rhs - rows @ x, rcond=None)[0]
    return x


def equality_system(spec: Spec, steps: int, dt: float) -> tuple[Array, Array]:
    from optim.time_optimal.weights import exponential_moment, integrated_box

    q, unit = spec.order, spec.scale
    start, end = pieces(steps, dt)
    total = steps * dt
    rows: list[Array] = []
    rhs: list[float] = []
    for m in range(q):
        if m == 0 and not spec.rest_to_rest:
            continue
        target = spec.move if (m == 0 or (m == 1 and not spec.rest_to_rest)) else 0.0
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


def solve(spec: Spec, check_limits: object = None) -> Solution:
    """The minimum-time command of ``spec`` (see the module's docstring). ``check_limits(arcs) -> bool``
    tells whether a refined command meets the limits exactly (the caller's independent check)."""
    began = time.perf_counter()
    search = _Search(spec)
    grid = search.grid_optimum()
    values = np.clip(project(spec, grid), -1.0, 1.0) if (spec.order == 3 or spec.max_acceleration) else project(
        spec, grid
    )
    grid_arcs = arcs_of(spec.scale * values, grid.step_s)
    arcs, refined, how = grid_arcs, False, "not refined"
    if spec.torque is not None:
        how = "not refined: with a torque limit the grid optimum is returned (within one step of it)"
    else:
        starts = [(values, grid.step_s)] + [(np.clip(y, -1, 1), h) for y, h in search.alternatives]
        how = "the refined switching times did not converge or check out (limits, band): the grid optimum is returned"
        for start, step in starts:
            if len(structure(start, step)[0]) > MAX_ARCS:
                continue
            result = refine(spec, *structure(start, step), search.cuts)
            if result is None:
                continue
            total = sum(a.duration_s for a in result.arcs)
            ok_limits = check_limits is None or bool(check_limits(result.arcs))  # type: ignore[operator]
            if total < sum(a.duration_s for a in arcs) and ok_limits and search.verified(result.arcs):
                arcs, refined, how = merged(result.arcs), True, result.status
    duration = sum(a.duration_s for a in arcs)
    bound, method = search.lower_bound(duration)
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
    )
