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

The chain is ``state_chain.chain``, the LP's variables and rows are built by ``sparse_lp.SparseLp``. Where no state
can reach a bound between the ends (``states_free``: no torque, and the velocity limit, with a held jerk the
acceleration limit too, beyond what the box lets the command reach in T), the states are left out: the end state is
two or three dense rows of the held values (``_grid_held_lp``), the same LP as HiGHS's presolve made of the states'
form, without the presolve (16 of the 22 ms of a band's fine LP).

``relaxed_lp`` is the LP every continuous command of duration T satisfies in its step averages of the
acceleration, abar_k: the velocity at the nodes is exact, the other equalities are widened by what
averaging can change (|int f a - sum abar_k int_step f| <= A max|f'| T dt / 4), the band polygons are
circumscribed and widened alike, and the jerk bound becomes |abar_(k+1) - abar_k| <= J dt. HiGHS
proving it infeasible proves that no command of duration T exists (the certificate of lower_bound_s). Its velocity
is a state at every node only where max_velocity can bind (``velocity_implied``), else one row at the end.

Every LP is solved in HiGHS, capped in work (optim.families.time_optimal.highs_model); a grid LP's model is kept
so that the band points its cutting-plane rounds add are solved warm (``GridLp``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from optim.families.time_optimal.highs_model import INFEASIBLE, LpCounter, LpModel
from optim.families.time_optimal.sparse_lp import SparseLp
from optim.families.time_optimal.state_chain import chain
from optim.families.time_optimal.types import Spec
from optim.families.time_optimal.weights import exponential_moment, integrated_box

Array = NDArray[np.float64]
CArray = NDArray[np.complex128]
MARGIN = 1e-7  # bounds tightened by this fraction so that HiGHS's feasibility tolerance cannot break a limit
# The band's bound at its points is lowered by this fraction: between points 0.15 rad of the residual's phase apart
# it rises by about (0.15 / 2)^2 / 2 = 0.28 % (its phase turns, its modulus is smooth). The search starts with
# points further apart (search.PHASE_STEP) and the dense check adds them where the command breaks the band.
BAND_MARGIN = 0.003
TORQUE_POINTS = (0.0, 0.25, 0.5, 0.75, 1.0)  # 1.0: the left limit at the next node (the torque jumps)


@dataclass(frozen=True)
class Cut:
    """A band point: |F_0(pole)| <= bound, F_0 of the acceleration (see weights)."""

    pole: complex
    bound: float


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


@np.errstate(divide="ignore", invalid="ignore", over="ignore")  # rows are checked whole: highs_model.require_finite
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


class GridLp:
    """The LP on N = ``steps`` steps of ``dt`` (u_k = spec.scale x_k) in HiGHS: ``solve`` gives a feasible x, or
    None if none is found (with ``weights``, the one of least weighted L1 norm: see SparseLp.weighted_l1);
    ``add_cuts`` adds band points, and the next ``solve`` starts from the last basis."""

    def __init__(
        self, spec: Spec, steps: int, dt: float, cuts: list[Cut], counter: LpCounter, weights: Array | None = None
    ) -> None:
        self.spec, self.steps, self.dt = spec, steps, dt
        self.model = LpModel(_grid_sparse_lp(spec, steps, dt, cuts, weights), counter)

    def solve(self) -> Array | None:
        x, _ = self.model.solve()
        return None if x is None else x[: self.steps]

    def add_cuts(self, cuts: list[Cut]) -> None:
        weights, bounds = _band_weights(self.spec, self.steps, self.dt, cuts)
        self.model.add_band(weights, bounds)


def _band_weights(spec: Spec, steps: int, dt: float, cuts: list[Cut]) -> tuple[CArray, Array]:
    """The grid LP's band rows at ``cuts``: F_0's weights per step and the bounds, lowered by BAND_MARGIN."""
    start, end = pieces(steps, dt)
    poles = np.array([cut.pole for cut in cuts])
    weights = spec.scale * acceleration_moment(spec, poles, start, end, steps * dt, 0)
    return weights, np.array([cut.bound for cut in cuts]) * (1.0 - BAND_MARGIN)


def states_free(spec: Spec, total_s: float, dt: float) -> bool:
    """No state of the motor's chain can reach a bound between the ends: no torque, and max_velocity (with a held
    jerk, max_acceleration too) absent or above what any held values within the box reach in ``total_s`` (|v| <=
    |v0| + A T, or with a held jerk |a| <= |a0| + J T and |v| <= |v0| + |a0| T + J T^2 / 2): the node bounds are
    implied, and the grid LP needs its states only at the end (``_grid_held_lp``)."""
    if spec.torque is not None:
        return False
    unit, v0, a0 = spec.scale, abs(spec.start_velocity), abs(spec.start_acceleration)
    if spec.order == 2:
        reach_v, reach_a = v0 + unit * total_s, 0.0
    else:
        reach_v, reach_a = v0 + a0 * total_s + 0.5 * unit * total_s**2, a0 + unit * total_s
    tight = 1.0 - MARGIN
    if spec.max_velocity is not None and reach_v > velocity_bound(spec, dt) * tight:
        return False
    return spec.order == 2 or spec.max_acceleration is None or reach_a <= spec.max_acceleration * tight


def _grid_sparse_lp(spec: Spec, steps: int, dt: float, cuts: list[Cut], weights: Array | None) -> SparseLp:
    if states_free(spec, steps * dt, dt):
        return _grid_held_lp(spec, steps, dt, cuts, weights)
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
    rows_eq, rhs_eq = equality_rows(spec, steps, dt, end_state=False)  # (the end state is bounds on the states)
    if rows_eq.size:
        lp.add_eq(lp.dense_x_rows(rows_eq), rhs_eq)
    if cuts:
        lp.band(*_band_weights(spec, steps, dt, cuts), inscribed=True)
    return lp


def _grid_held_lp(spec: Spec, steps: int, dt: float, cuts: list[Cut], weights: Array | None) -> SparseLp:
    """The grid LP where ``states_free``: the held values alone, the end state and the residuals as dense rows of
    them (the same LP as _grid_sparse_lp's with its states eliminated: HiGHS's presolve did that in 16 of the 22 ms
    of a band's fine LP, 1068 columns to 384)."""
    lp = SparseLp(steps, 0, 0 if weights is None else steps, len(cuts))
    if weights is not None:
        lp.weighted_l1(weights)
    tight = 1.0 - MARGIN
    lp.lower[:steps], lp.upper[:steps] = -tight, tight  # (a held jerk, or a held acceleration: states_free)
    rows_eq, rhs_eq = equality_rows(spec, steps, dt)
    lp.add_eq(lp.dense_x_rows(rows_eq), rhs_eq)
    if cuts:
        lp.band(*_band_weights(spec, steps, dt, cuts), inscribed=True)
    return lp


def equality_rows(spec: Spec, steps: int, dt: float, end_state: bool = True) -> tuple[Array, Array]:
    """The grid LP's equalities on the held values, each row scaled to max 1: the end state (``end_state``: exact
    integrals of the steps, less the start state's share) and zero residual at each cancelled pole, Re F_n = Im F_n =
    0 (every real part, then every imaginary part); (0 rows, 0) where there are none."""
    q, unit = spec.order, spec.scale
    start, end = pieces(steps, dt)
    total = steps * dt
    at_end = np.array([total])
    rows: list[Array] = []
    rhs: list[float] = []
    if end_state:
        for m, target in spec.end_targets().items():
            rows.append(unit * integrated_box(at_end, start, end, q - m)[0])
            rhs.append(target - float(spec.free_motion(m, at_end)[0]))
    if spec.zero_poles:
        poles = np.asarray(spec.zero_poles)
        orders = range(spec.derivative_order + 1)
        w = np.vstack([unit * exponential_moment(poles, start, end, total, n) for n in orders])
        rows += [*w.real, *w.imag]
        rhs += [0.0] * (2 * w.shape[0])
    if not rows:
        return np.zeros((0, steps)), np.zeros(0)
    return _unit_rows(np.vstack(rows), np.asarray(rhs))


def velocity_implied(spec: Spec, total_s: float) -> bool:
    """The relaxation's velocity limit implied by its box (|v| <= |v0| + A T, or no limit): its velocity is needed
    at the end only, one row of the held values, instead of a state at every node (HiGHS's presolve eliminated them
    in most of a relaxed LP's time)."""
    assert spec.max_acceleration is not None
    reach = abs(spec.start_velocity) + spec.max_acceleration * total_s
    return spec.max_velocity is None or reach <= spec.max_velocity


@np.errstate(divide="ignore", invalid="ignore", over="ignore")  # rows are checked whole: highs_model.require_finite
def relaxed_lp(spec: Spec, total_s: float, steps: int, cuts: list[Cut], counter: LpCounter) -> bool:
    """False only if HiGHS proves the relaxation of duration ``total_s`` infeasible (then no command of that
    duration exists); x are step averages of the acceleration over max_acceleration."""
    if spec.max_acceleration is None or spec.start_acceleration or spec.end_acceleration:
        return True  # (the relaxation of a move between accelerations is not written: nothing is proven)
    accel = spec.max_acceleration
    dt = total_s / steps
    start, end = pieces(steps, dt)
    slack = 1e-9  # relative, against round-off (a wider relaxation stays valid)
    v_scale = accel * total_s
    v_start = spec.start_velocity / v_scale
    v_end = (spec.end_velocity if spec.rest_to_rest else spec.move) / v_scale
    ranged: list[tuple[Array, float, float]] = []  # row . x within target +- width
    implied = velocity_implied(spec, total_s)
    lp = SparseLp(steps, 0 if implied else 1, 0, len(cuts))  # (the velocity at the nodes, exact for averages)
    lp.lower[:steps], lp.upper[:steps] = -1.0, 1.0
    if implied:
        ranged.append((np.full(steps, dt / total_s), v_end - v_start, slack))
    else:
        k = np.arange(steps)
        dyn = sp.coo_matrix(
            (
                np.concatenate([np.ones(steps), -np.ones(steps), -np.full(steps, dt / total_s)]),
                (np.concatenate([k, k, k]), np.concatenate([lp.state(k + 1, 0), lp.state(k, 0), k])),
            ),
            shape=(steps, lp.lower.size),
        )
        lp.add_eq(dyn, np.zeros(steps))
        lp.lower[lp.state(0, 0)] = lp.upper[lp.state(0, 0)] = v_start
        lp.lower[lp.state(steps, 0)], lp.upper[lp.state(steps, 0)] = v_end - slack, v_end + slack
        assert spec.max_velocity is not None
        nodes = lp.state(np.arange(1, steps), 0)
        bound = spec.max_velocity / v_scale * (1 + slack)
        lp.lower[nodes], lp.upper[nodes] = -bound, bound
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
    x, status = LpModel(lp, counter).solve()
    return not (x is None and status == INFEASIBLE)  # only HiGHS's proven infeasibility is a certificate
