"""The fixed-duration linear programs of the time-optimal search (HiGHS through scipy, sparse).

For N steps of dt the held derivative u (acceleration, or jerk with a jerk limit) is constant on each
step, u_k = U x_k. The motor's integrator chain (and, on a two-inertia plant, the load's response
G a, for the torque) is one linear system z' = A z + B u, discretised exactly (matrix exponential):
z_(k+1) = Phi z_k + Gamma u_k. The states are LP variables, so that the LP stays sparse:

- the end state (position, velocity, acceleration) and the node bounds are bounds on the states
  (exact: between nodes the velocity of a held acceleration, and the acceleration of a held jerk, are
  linear); the velocity of a jerk-limited command is also bounded mid-step (not exact: it may exceed
  the bound by up to J dt^2 / 32 between, which the family measures and tightens), the torque
  J_M a + J_L a_L at five points of every step, both sides of each node (rows C z_k + D u_k);
- zero residual at each cancelled pole: Re F_n = Im F_n = 0 (optim.families.time_optimal.weights), two dense rows;
- each band point |F_0| <= (1 - BAND_MARGIN) c, by the 16-gon inscribed in that circle.

The chain is ``state_chain.chain``, the LP's variables and rows are built by ``sparse_lp.SparseLp``.

``relaxed_lp`` is the LP every continuous command of duration T satisfies in its step averages of the
acceleration, abar_k: the velocity at the nodes is exact, the other equalities are widened by what
averaging can change (|int f a - sum abar_k int_step f| <= A max|f'| T dt / 4), the band polygons are
circumscribed and widened alike, and the jerk bound becomes |abar_(k+1) - abar_k| <= J dt. HiGHS
proving it infeasible proves that no command of duration T exists (the certificate of lower_bound_s).

Every LP is capped in work, so that a search is the same on any machine under any load: MAX_LP_ITERATIONS
HiGHS iterations per method (its simplex, then its interior-point method), after which the LP counts as "no
command found" at its length (a capped LP, reported in the design's search block); MAX_LP_SOLVES LPs per search
(SolverFailed beyond). Wall-clock time is only a last resort: HiGHS's own ``time_limit`` (the solve's
max_wall_time_s) reached, the design fails with SolverTimedOut, never a different design.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.optimize import linprog

from models.errors import InvalidParameter, SolverFailed, SolverTimedOut
from optim.families.time_optimal.sparse_lp import SparseLp
from optim.families.time_optimal.state_chain import chain
from optim.families.time_optimal.types import Spec
from optim.families.time_optimal.weights import exponential_moment
from optim.solver import SolverReport, record_solve

Array = NDArray[np.float64]
CArray = NDArray[np.complex128]
MARGIN = 1e-7  # bounds tightened by this fraction so that HiGHS's feasibility tolerance cannot break a limit
# The band's bound at its points is lowered by this fraction: between points a PHASE_STEP apart the residual
# rises by about (PHASE_STEP / 2)^2 / 2 = 0.28 % (its phase turns, its modulus is smooth), so the dense check
# seldom adds a point.
BAND_MARGIN = 0.003
# HiGHS iterations per LP and method (scipy's ``maxiter``: HiGHS's simplex_iteration_limit and ipm_iteration_limit).
# The LPs of tests/optim/test_time_optimal.py, the README's examples and bench/determinism.py's 50 random requests
# need at most 4036 simplex iterations (a band down to 1 mHz, 3856 rows; the 1 s time limit used to stop them) and
# 16 interior-point ones; one LP of the stalling move of those tests never ends in the simplex (515 000 iterations in
# 30 s), and the interior-point method proves it infeasible in 16.
MAX_LP_ITERATIONS = 10_000
MAX_LP_SOLVES = 200  # LPs per search (those runs need at most 30): beyond, SolverFailed
TORQUE_POINTS = (0.0, 0.25, 0.5, 0.75, 1.0)  # 1.0: the left limit at the next node (the torque jumps)


@dataclass(frozen=True)
class Cut:
    """A band point: |F_0(pole)| <= bound, F_0 of the acceleration (see weights)."""

    pole: complex
    bound: float


@dataclass
class LpCounter:
    """The LPs of one search: HiGHS runs (``solves``), their iterations and seconds, the runs that stopped at
    ``max_iterations`` (``capped_runs``) and the LPs that therefore counted as not found (``capped_lps``).
    ``time_limit_s``: each run's wall-clock last resort (HiGHS's own clock)."""

    time_limit_s: float = math.inf
    max_iterations: int = field(default_factory=lambda: MAX_LP_ITERATIONS)
    max_solves: int = field(default_factory=lambda: MAX_LP_SOLVES)
    solves: int = 0
    iterations: int = 0
    seconds: float = 0.0
    capped_runs: int = 0
    capped_lps: int = 0

    def report(self, status: str) -> SolverReport:
        return SolverReport(status, self.iterations, self.seconds)


def pieces(steps: int, dt: float) -> tuple[Array, Array]:
    k = np.arange(steps, dtype=float)
    return k * dt, (k + 1) * dt


def acceleration_moment(spec: Spec, poles: CArray, start: Array, end: Array, total: float, n: int) -> CArray:
    """Weights of F_n of the acceleration per unit u on each piece: the acceleration's own moment, or for a
    held jerk the jerk's divided by lambda (int a e^(lambda s) = int j e^(lambda s) / lambda when
    a(0) = a(T) = 0; n = 0, all the bands use)."""
    w = exponential_moment(poles, start, end, total, n)
    if spec.order == 3:
        w = w / poles[:, None]
    return w


def _unit_rows(rows: Array, rhs: Array) -> tuple[Array, Array]:
    scale = np.max(np.abs(rows), axis=1)
    scale[scale == 0.0] = 1.0
    return rows / scale[:, None], rhs / scale


@np.errstate(divide="ignore", invalid="ignore", over="ignore")  # rows are checked whole: _require_finite
def velocity_bound(spec: Spec, dt: float) -> float:
    """The velocity bound the grid LP holds at its check points (the nodes, and with a held jerk every step's
    middle) so that the command holds max_velocity everywhere: with a held jerk the velocity is a parabola on each
    step, |v''| <= J, so between check points h / 2 apart it exceeds their chord by at most J (h / 2)^2 / 8 =
    J h^2 / 32 (the interpolation error of a linear interpolant); without one it is linear between the nodes."""
    assert spec.max_velocity is not None
    if spec.order != 3 or spec.max_jerk is None:
        return spec.max_velocity
    return max(spec.max_velocity - spec.max_jerk * dt * dt / 32.0, 0.5 * spec.max_velocity)


def velocity_bounds(spec: Spec, times_s: Array, total_s: float, dt: float) -> Array:
    """velocity_bound at check points ``times_s``, except next to an end in motion: within one step plus the time
    the jerk needs to bring that end's acceleration to 0 (|a| / J), the speed that end cannot avoid (|v|, plus
    a^2 / 2J where the acceleration points the same way) may be above it (a start at max_velocity, or rising
    towards it): there the bound is that speed (at most max_velocity), and the exact check of the command decides
    (family.limits_met, and the tightening of family.solve_within_limits)."""
    assert spec.max_velocity is not None
    bound = velocity_bound(spec, dt)
    out = np.full(times_s.shape, bound)
    if spec.order != 3 or spec.max_jerk is None or not spec.in_motion:
        return out
    jerk, top = spec.max_jerk, spec.max_velocity
    for velocity, accel, near in (
        (spec.start_velocity, spec.start_acceleration, times_s <= dt + abs(spec.start_acceleration) / jerk),
        (spec.end_velocity, -spec.end_acceleration, times_s >= total_s - dt - abs(spec.end_acceleration) / jerk),
    ):
        unavoidable = abs(velocity) + (accel * accel / (2.0 * jerk) if velocity * accel > 0.0 else 0.0)
        out[near] = np.maximum(out[near], min(top, unavoidable))
    return out


def grid_lp(
    spec: Spec, steps: int, dt: float, cuts: list[Cut], counter: LpCounter, weights: Array | None = None
) -> Array | None:
    """A feasible x on N = ``steps`` steps of ``dt`` (u_k = spec.scale x_k), or None if none is found; with
    ``weights`` the one of least weighted L1 norm (see SparseLp.weighted_l1)."""
    q, unit = spec.order, spec.scale
    total = steps * dt
    c = chain(spec, total)
    lp = SparseLp(steps, c.a.shape[0], 0 if weights is None else steps, len(cuts))
    if weights is not None:
        lp.weighted_l1(weights)
    tight = 1.0 - MARGIN
    box = spec.order == 3 or spec.max_acceleration is not None
    if box:
        lp.lower[:steps], lp.upper[:steps] = -tight, tight
    lp.dynamics(c, dt, unit)
    first, last = lp.state(0, np.arange(lp.states)), lp.state(steps, np.arange(lp.states))
    lp.lower[first] = lp.upper[first] = 0.0
    start_state = np.asarray(spec.start_state())
    lp.lower[first[:q]] = lp.upper[first[:q]] = start_state / c.scale[:q]
    if spec.torque is not None and spec.start_acceleration:  # the load quasi-static: g1 = a0 / w^2, g1' = 0
        quasi_static = spec.start_acceleration / abs(spec.torque.pole) ** 2
        lp.lower[first[q]] = lp.upper[first[q]] = quasi_static / c.scale[q]
    for m, target in spec.end_targets().items():
        lp.lower[last[m]] = lp.upper[last[m]] = target / c.scale[m]
    nodes = lp.state(np.arange(1, steps), 0)
    if spec.max_velocity is not None:
        at_nodes = velocity_bounds(spec, np.arange(1, steps, dtype=float) * dt, total, dt) * tight
        bound = at_nodes / c.scale[1]
        lp.lower[nodes + 1] = np.maximum(lp.lower[nodes + 1], -bound)
        lp.upper[nodes + 1] = np.minimum(lp.upper[nodes + 1], bound)
        if q == 3:  # mid-step velocity of a held jerk
            e = np.zeros(lp.states)
            e[1] = 1.0
            rows = lp.output_rows(c, e, 0.0, dt, unit, (0.5,))
            mid = velocity_bounds(spec, (np.arange(steps, dtype=float) + 0.5) * dt, total, dt) * tight
            lp.add_ub(rows, mid)
            lp.add_ub(-rows, mid)
    if q == 3 and spec.max_acceleration is not None:
        bound = spec.max_acceleration * tight / c.scale[2]
        lp.lower[nodes + 2] = np.maximum(lp.lower[nodes + 2], -bound)
        lp.upper[nodes + 2] = np.minimum(lp.upper[nodes + 2], bound)
    if c.torque is not None and spec.torque is not None:
        row, d = c.torque
        rows = lp.output_rows(c, row, d, dt, unit, TORQUE_POINTS)
        limit = np.full(rows.shape[0], spec.torque.max_torque_nm * tight)
        lp.add_ub(rows, limit)
        lp.add_ub(-rows, limit)
    start, end = pieces(steps, dt)
    if spec.zero_poles:
        poles = np.asarray(spec.zero_poles)
        dense = [unit * exponential_moment(poles, start, end, total, n) for n in range(spec.derivative_order + 1)]
        w = np.vstack(dense)
        rows_eq, rhs_eq = _unit_rows(np.vstack([w.real, w.imag]), np.zeros(2 * w.shape[0]))
        lp.add_eq(lp.dense_x_rows(rows_eq), rhs_eq)
    if cuts:
        poles = np.array([cut.pole for cut in cuts])
        w = unit * acceleration_moment(spec, poles, start, end, total, 0)
        lp.band(w, np.array([cut.bound for cut in cuts]) * (1.0 - BAND_MARGIN), inscribed=True)
    x, _ = _solve(lp, counter)
    return None if x is None else x[:steps]


@np.errstate(divide="ignore", invalid="ignore", over="ignore")  # rows are checked whole: _require_finite
def relaxed_lp(spec: Spec, total_s: float, steps: int, cuts: list[Cut], counter: LpCounter) -> bool:
    """False only if HiGHS proves the relaxation of duration ``total_s`` infeasible (then no command of that
    duration exists); x are step averages of the acceleration over max_acceleration."""
    if spec.max_acceleration is None or spec.start_acceleration or spec.end_acceleration:
        return True  # (the relaxation of a move between accelerations is not written: nothing is proven)
    accel = spec.max_acceleration
    dt = total_s / steps
    start, end = pieces(steps, dt)
    lp = SparseLp(steps, 1, 0, len(cuts))  # the velocity at the nodes, exact for averages
    lp.lower[:steps], lp.upper[:steps] = -1.0, 1.0
    slack = 1e-9  # relative, against round-off (a wider relaxation stays valid)
    v_scale = accel * total_s
    k = np.arange(steps)
    dyn = sp.coo_matrix(
        (
            np.concatenate([np.ones(steps), -np.ones(steps), -np.full(steps, dt / total_s)]),
            (np.concatenate([k, k, k]), np.concatenate([lp.state(k + 1, 0), lp.state(k, 0), k])),
        ),
        shape=(steps, lp.lower.size),
    )
    lp.add_eq(dyn, np.zeros(steps))
    lp.lower[lp.state(0, 0)] = lp.upper[lp.state(0, 0)] = spec.start_velocity / v_scale
    v_end = (spec.end_velocity if spec.rest_to_rest else spec.move) / v_scale
    lp.lower[lp.state(steps, 0)], lp.upper[lp.state(steps, 0)] = v_end - slack, v_end + slack
    if spec.max_velocity is not None:
        nodes = lp.state(np.arange(1, steps), 0)
        lp.lower[nodes], lp.upper[nodes] = (
            -spec.max_velocity / v_scale * (1 + slack),
            spec.max_velocity / v_scale * (1 + slack),
        )
    ranged: list[tuple[Array, float, float]] = []  # row . x within target +- width
    if spec.rest_to_rest:
        row = accel * dt * (total_s - 0.5 * (start + end))
        moved = spec.move - spec.start_velocity * total_s  # what the acceleration adds to the start's drift
        ranged.append((row, moved, accel * total_s * dt / 4 + slack * spec.position_scale(total_s)))
    if spec.zero_poles:
        poles = np.asarray(spec.zero_poles)
        for n in range(spec.derivative_order + 1):
            w = accel * exponential_moment(poles, start, end, total_s, n)
            for pole, r in zip(poles, w, strict=True):
                lipschitz = n * total_s ** max(n - 1, 0) + abs(pole) * total_s**n
                width = accel * lipschitz * total_s * dt / 4 + slack * float(np.sum(np.abs(r)))
                ranged += [(r.real, 0.0, width), (r.imag, 0.0, width)]
    if ranged:
        rows = np.vstack([r for r, _, _ in ranged])
        hi = np.array([t + wd for _, t, wd in ranged])
        lo = np.array([t - wd for _, t, wd in ranged])
        scale = np.max(np.abs(rows), axis=1)
        lp.add_ub(lp.dense_x_rows(rows / scale[:, None]), hi / scale)
        lp.add_ub(lp.dense_x_rows(-rows / scale[:, None]), -lo / scale)
    if spec.max_jerk is not None:
        diff = sp.diags([np.ones(steps), -np.ones(steps)], [0, -1], shape=(steps + 1, steps)).tocoo()
        limit = np.full(steps + 1, spec.max_jerk * dt / accel * (1 + slack))
        limit[[0, -1]] /= 2.0  # the acceleration starts and ends at 0
        pad = sp.coo_matrix((steps + 1, lp.lower.size - steps))  # the velocities and the band's variables
        m = sp.hstack([diff, pad]).tocoo()
        lp.add_ub(m, limit)
        lp.add_ub(-m, limit)
    if cuts:
        poles = np.array([cut.pole for cut in cuts])
        w = accel * exponential_moment(poles, start, end, total_s, 0)
        widths = np.abs(poles) * total_s * dt / 4 * accel + slack * np.sum(np.abs(w), axis=1)
        lp.band(w, np.array([cut.bound for cut in cuts]) + widths, inscribed=False)
    x, status = _solve(lp, counter)
    return not (x is None and status == 2)  # only HiGHS's proven infeasibility is a certificate


def _require_finite(*parts: Array | sp.csr_matrix | None) -> None:
    """Refuse an LP whose rows are not finite in double precision (InvalidParameter on the body): a move, limits and
    modes whose scales are too far apart (the fuzz bench: a 1e-9 ramp at 5e11 on a 0.001 Hz mode lasts 2e-21 s, a
    band bound of 5e-324 % is 0) give inf / 0 rows, which HiGHS cannot take; no design is claimed impossible."""
    for part in parts:
        if part is None:
            continue
        data = part.data if sp.issparse(part) else part
        if not np.all(np.isfinite(data)):
            raise InvalidParameter(
                "body",
                "not finite",
                "the move, its limits and the plant's modes span scales too far apart for the time-optimal linear "
                "programme in double precision: bring them closer (e.g. a longer move, looser limits, a band nearer "
                "the mode)",
            )


def _solve(lp: SparseLp, counter: LpCounter) -> tuple[Array | None, int]:
    """HiGHS's solution (None unless optimal) and scipy's status (0 optimal, 1 iteration cap, 2 infeasible, ...).

    HiGHS's simplex now and then stalls on one of these small LPs (seen: 316 steps, held jerk): stopped at
    its iteration cap, the LP is solved again with the interior-point method (same cap), then counts as not found.
    Raises SolverFailed past the search's LP cap, SolverTimedOut when HiGHS reaches its time limit."""
    if counter.solves >= counter.max_solves:
        raise SolverFailed(
            counter.report("lp_solve_cap"),
            f"the time-optimal search reached its cap of {counter.max_solves} LP solves (max_lp_solves) without an "
            "answer",
        )
    a_eq = sp.vstack(lp.eq).tocsr() if lp.eq else None
    b_eq = np.concatenate(lp.eq_rhs) if lp.eq else None
    a_ub = sp.vstack(lp.ub).tocsr() if lp.ub else None
    b_ub = np.concatenate(lp.ub_rhs) if lp.ub else None
    bounds = np.column_stack([lp.lower, lp.upper])
    _require_finite(lp.cost, a_eq, b_eq, a_ub, b_ub)
    options: dict[str, Any] = {"maxiter": counter.max_iterations, "presolve": True}
    if math.isfinite(counter.time_limit_s):
        options["time_limit"] = counter.time_limit_s
    status = 1
    for method in ("highs", "highs-ipm"):
        lp_started = time.perf_counter()
        result = linprog(
            lp.cost, A_ub=a_ub, b_ub=b_ub, A_eq=a_eq, b_eq=b_eq, bounds=bounds, method=method, options=options
        )
        seconds = time.perf_counter() - lp_started  # reported only: nothing below depends on it
        nit = max(0, int(getattr(result, "nit", 0) or 0))
        counter.solves += 1
        counter.iterations += nit
        counter.seconds += seconds
        record_solve(nit, seconds)
        if result.status == 0:
            x: Array = np.asarray(result.x, dtype=float)
            return x, 0
        status = int(result.status)
        if status == 1 and "iteration limit" not in str(result.message).lower():  # HiGHS's time limit
            raise SolverTimedOut(
                counter.report("lp_time_limit"),
                f"an LP reached its wall-clock last resort ({counter.time_limit_s:g} s, the solve time limit) after "
                f"{counter.solves} LP solves of the search: no design is returned",
            )
        if status != 1:  # proven infeasible, or a numerical failure: no second method
            break
        counter.capped_runs += 1
    if status == 1:
        counter.capped_lps += 1
    return None, status
