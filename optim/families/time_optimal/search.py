"""The grid search: bisection on the grid, cutting planes for the bands, the certificate.

1. On a grid of ``STEPS`` steps over an upper guess (doubled until feasible, up to max_duration_s),
   feasibility is monotone in the number of steps (a feasible command padded with rest stays
   feasible: its residual at the end only decays), so bisection finds the grid's shortest command.
   Bands enter as cutting planes: each LP holds the band at the points found so far, the dense check
   (optim.families.time_optimal.check) adds the worst violating points until it passes.
2. The grid optimum is one start of the exact answer (optim.families.time_optimal.minimum_time).
3. ``lower_bound_s``: the largest duration whose relaxed LP (optim.families.time_optimal.lp.relaxed_lp) HiGHS
   proves infeasible, found by bisection, or the rigid floor (Ruckig's optimum within the motor's limits): no
   command at all (not only on the grid) that short meets the constraints.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from models.errors import Infeasible, SolverFailed
from optim.families.time_optimal.arcs import SNAP
from optim.families.time_optimal.check import (
    CHECK_MARGIN,
    INITIAL_POINTS,
    band_grid,
    dense_points,
    violations,
    worst_ratios,
)
from optim.families.time_optimal.highs_model import LpCounter
from optim.families.time_optimal.lp import MARGIN, Cut, GridLp, pieces, relaxed_lp
from optim.families.time_optimal.types import Arc, Band, GridSolution, Spec
from optim.families.time_optimal.weights import exponential_moment, integrated_box

Array = NDArray[np.float64]
STEPS = 96  # steps over the search's upper duration
CUT_ROUNDS = 12
RELAXED_STEPS = 250
BOUND_BISECTIONS = 2
# rad of the residual's phase between the LPs' first band points: the dense check adds points where a command
# breaks the band between them, in rounds solved warm (search.GridSearch.feasible)
PHASE_STEP = 1.2
DENSE_PHASE_STEP = 0.15  # rad: the dense start, added after COARSE_ROUNDS rounds of one LP
COARSE_ROUNDS = 5
MAX_INITIAL_POINTS = 200
KINEMATIC = "kinematic floor (the rigid time-optimal move within the limits)"
FIRST_PROBE = 0.15  # _narrow's first count, of the range above the count with no command found
LEAST_RTOL = 1e-5  # least_duration's bisection (at 1e-4 seed 29's design 34 of bench/programs.py lost its structure)
CRUISING = 1e-3  # without_chatter: a node within this share of max_velocity and ...
CHATTER = 0.1  # ... within this share of max_acceleration of no acceleration cruises


class GridSearch:
    def __init__(self, spec: Spec) -> None:
        self.spec = spec
        self.counter = LpCounter(time_limit_s=spec.lp_time_limit_s)
        self.dense = [band_grid(spec, b, dense_points(b, spec.upper_guess_s)) for b in spec.bands]
        self.cuts: list[Cut] = []
        self.dense_start: list[Cut] = []  # the points every DENSE_PHASE_STEP rad: added where the coarse start fails
        self.bases: dict[int, Any] = {}  # steps -> the basis of the last weighted LP on as many (without bands)
        for b in spec.bands:
            for step, into in ((PHASE_STEP, self.cuts), (DENSE_PHASE_STEP, self.dense_start)):
                points = initial_points(b, spec.upper_guess_s, step)
                into += band_grid(spec, b, points).cuts(np.arange(points * len(b.damping_ratios)))

    def feasible(self, steps: int, dt: float, weights: Array | None = None) -> Array | None:
        """A grid command of ``steps`` steps meeting every constraint (bands on the dense check), or None. The
        band points the dense check adds are added to the LP in HiGHS, which solves it again from its last basis.
        After COARSE_ROUNDS rounds the dense start's points are added too, for the rest of the search (a wide band,
        a small V_max or several damping ratios: adding a dozen points a round, the rounds ran out, and the search
        called lengths infeasible that the dense start shows feasible), with CUT_ROUNDS more rounds."""
        lp = GridLp(self.spec, steps, dt, self.cuts, self.counter, weights)
        if weights is not None and not self.dense:
            return self._weighted(lp)
        start, end = pieces(steps, dt)
        rounds = CUT_ROUNDS
        for round_ in range(1, CUT_ROUNDS + COARSE_ROUNDS + 1):
            x = lp.solve()
            if x is None:
                return None
            added = self.new_cuts(start, end, self.spec.scale * x, steps * dt)
            if not added:
                return x
            if round_ == COARSE_ROUNDS and self.dense_start:
                added += self.dense_start
                self.dense_start, rounds = [], round_ + CUT_ROUNDS
            self.cuts += added
            if round_ == rounds:
                break  # (the last round's points are for the next LP of the search)
            lp.add_cuts(added)
        return None  # the band still fails the dense check: not shown feasible at this length

    def _weighted(self, lp: GridLp) -> Array | None:
        """A weighted LP without bands, started from the basis of the last one on as many steps (the probes'
        LPs differ only in their step's length: 20-30 ms warm instead of 65-85 cold on 364 steps, the same vertex
        to 1e-9)."""
        basis = self.bases.get(lp.steps)
        if basis is not None:
            lp.model.start_from(basis)
        x = lp.solve()
        if x is not None:
            self.bases[lp.steps] = lp.model.basis()
        return x

    def least_duration(self, grid: GridSolution) -> GridSolution:
        """``grid``'s command at the least duration on as many steps, to LEAST_RTOL: the step bisected between
        ``grid``'s and the one of a step less in all, each LP from the last feasible one's basis (about half the time
        of one from nothing), then the vertex at the least duration found from nothing (a warm LP's vertex there, on
        bench/programs.py's seed-28 move 2, led SLSQP to another local optimum); a band's grid as it is. Near its
        least duration the LP's feasible set is nearly a point: its vertex has the optimum's arcs, where one with a
        step's slack dithers (a three-mode cruise's three dips, lost in a chatter of one-step pulses)."""
        if self.dense:
            return grid
        steps, values = grid.steps, grid.values
        low, high = grid.step_s * (steps - 1) / steps, grid.step_s
        basis = None
        while high - low > LEAST_RTOL * high:
            mid = 0.5 * (low + high)
            lp = GridLp(self.spec, steps, mid, self.cuts, self.counter)
            if basis is not None:
                lp.model.start_from(basis)
            x = lp.solve()
            if x is None:
                low = mid
            else:
                high, values, basis = mid, x, lp.model.basis()
        if basis is not None:  # (the same LP as the warm one: feasible, unless at HiGHS's tolerance)
            cold = GridLp(self.spec, steps, high, self.cuts, self.counter).solve()
            values = values if cold is None else cold
        return GridSolution(high, steps, values, grid.infeasible_steps)

    def new_cuts(self, start: Array, end: Array, level: Array, total: float) -> list[Cut]:
        """The band points where the command breaks a band on the dense check (none: it meets every band)."""
        added: list[Cut] = []
        for grid in self.dense:
            ratios = worst_ratios(self.spec, grid, start, end, level, total)
            added += grid.cuts(violations(ratios / (1.0 - CHECK_MARGIN), len(grid.band.damping_ratios)))
        return added

    def grid_optimum(self, upper_s: float | None = None) -> GridSolution:
        """The grid's shortest command, searched from ``upper_s`` (default the spec's upper guess) down. Without bands
        STEPS steps over it are solved last, only where no shorter count is feasible (``bisect``: 42 LPs fewer on
        bench/programs.py's 144 designs, whose grid optima are all shorter); where not even they are, the guess is
        doubled until they are, as with bands."""
        spec = self.spec
        upper = max(upper_s or spec.upper_guess_s, spec.floor_s * 1.01)
        while True:
            dt = upper / STEPS
            lo = min(math.floor(spec.floor_s / dt), STEPS - 1)
            if not self.dense:
                coarse = self.bisect(dt, lo, STEPS)
                if coarse is not None:
                    break
            else:
                x = self.feasible(STEPS, dt)
                if x is not None:
                    coarse = self._narrow(dt, lo, STEPS, x)
                    break
            if upper >= spec.max_duration_s:
                self.not_found()
            upper = min(2.0 * upper, spec.max_duration_s)
        assert coarse is not None  # (feasible at STEPS at least)
        hi = coarse.steps
        if hi < STEPS // 2:  # the guess was far too long: search again on steps that fit the duration found
            fine = self.bisect(hi * dt / STEPS, math.floor(spec.floor_s / (hi * dt / STEPS)), STEPS)
            if fine is not None:
                return fine
        return coarse

    def bisect(self, dt: float, lo: int, hi: int) -> GridSolution | None:
        """The least feasible step count in (lo, hi] on steps of dt (None if none is shown feasible). ``hi`` is
        solved last, only where no shorter count is feasible (its command is the answer only then; a finer grid's
        ``hi`` holds the coarse optimum: feasible, and one LP of four times the size saved where a shorter one is)."""
        return self._narrow(dt, min(lo, hi - 1), hi, None)

    def _narrow(self, dt: float, lo: int, hi: int, best: Array | None) -> GridSolution | None:
        """Bisection between ``lo`` (no command found) and ``hi`` (``best`` feasible, or None: solved only if no
        shorter count is feasible) on steps of dt. Without bands its first count is FIRST_PROBE of the way up from
        ``lo``: the grid optimum lies just above the rigid floor (``lo`` of the first search) on bench/programs.py's
        designs, 1 to 22 counts above it of 3 to 34 (their 42 coarse searches: 121 LPs instead of 149, the 4x grids'
        20 instead of 22; the same counts found, feasibility being monotone). With bands, halves throughout (the
        cutting planes are added along the search: another order would add others)."""
        top = hi
        first = lo + math.ceil(FIRST_PROBE * (hi - lo)) if not self.dense else lo
        while hi - lo > 1:
            mid = first if lo < first < hi else (lo + hi) // 2
            first = lo
            y = self.feasible(mid, dt)
            if y is None:
                lo = mid
            else:
                hi, best = mid, y
        if best is None:
            best = self.feasible(top, dt)
        return None if best is None else GridSolution(dt, hi, best, lo)

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
        method = KINEMATIC
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


def initial_points(band: Band, duration_s: float, phase_step: float = PHASE_STEP) -> int:
    """Band points to start with: about one per ``phase_step`` radians of the residual's phase across the band
    (the phase of F_0 turns by about T dw), at least INITIAL_POINTS, at most MAX_INITIAL_POINTS."""
    span = (band.high_rad_s - band.low_rad_s) * duration_s
    return int(min(MAX_INITIAL_POINTS, max(INITIAL_POINTS, math.ceil(span / phase_step) + 1)))


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
    nodes = np.arange(1, grid.steps + 1, dtype=float) * grid.step_s
    for m, limit in ((1, spec.max_velocity), (2, spec.max_acceleration if spec.order == 3 else None)):
        if limit is None:
            continue
        peak = float(np.max(np.abs(_node_motion(spec, values, grid.step_s, nodes, m))))
        if peak > limit * (1.0 - 0.5 * MARGIN):
            return False
    return True


def _node_motion(spec: Spec, values: Array, dt: float, nodes: Array, m: int) -> Array:
    """The grid command's m-th derivative (1: velocity, 2: acceleration) at ``nodes``: its held values integrated
    (weights.integrated_box) plus the start state's free motion."""
    start, end = pieces(values.size, dt)
    motion: Array = spec.scale * integrated_box(nodes, start, end, spec.order - m) @ values + spec.free_motion(m, nodes)
    return motion


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
        rhs.append(float(target - spec.free_motion(m, np.array([total]))[0]) / scale)
    for n in range(spec.derivative_order + 1):
        if not spec.zero_poles:
            break
        w = unit * exponential_moment(np.asarray(spec.zero_poles), start, end, total, n)
        for row in w:
            scale = np.max(np.abs(row))
            rows += [row.real / scale, row.imag / scale]
            rhs += [0.0, 0.0]
    return np.vstack(rows) if rows else np.zeros((0, steps)), np.asarray(rhs)


def without_chatter(spec: Spec, values: Array, dt: float) -> Array:
    """The held-jerk grid command with no jerk on the steps that cruise (both nodes within CRUISING of max_velocity
    and CHATTER of no acceleration): a vertex dithers there (one-step pulses that move the velocity by 2e-4 of
    its limit), arcs no optimum has; the values themselves without a held jerk or a velocity limit."""
    limit_v, limit_a = spec.max_velocity, spec.max_acceleration
    if spec.order != 3 or limit_v is None or limit_a is None:
        return values
    nodes = np.arange(values.size + 1, dtype=float) * dt
    velocity, acceleration = (_node_motion(spec, values, dt, nodes, m) for m in (1, 2))
    cruising = (np.abs(velocity) >= limit_v * (1.0 - CRUISING)) & (np.abs(acceleration) < CHATTER * limit_a)
    out = values.copy()
    out[cruising[:-1] & cruising[1:]] = 0.0
    return out


def clip(spec: Spec, values: Array) -> Array:
    return np.clip(values, -1.0, 1.0) if (spec.order == 3 or spec.max_acceleration is not None) else values
