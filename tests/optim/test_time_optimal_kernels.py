"""The refinement's compiled constraint kernels (optim.families.time_optimal.kernels) against independent
computations: the motor's state by integrating each arc's polynomial exactly (numpy.polynomial), the residual
moments by quadrature (scipy.integrate.quad), and every Jacobian by central differences."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.polynomial import Polynomial
from scipy.integrate import quad

from optim.families.time_optimal.kernels import bound_system, end_system, moment_terms, state_terms

SEED = 20261204  # each test draws its arcs from its own generator (the same numbers on any xdist worker)
# Central differences on O(1) functions of O(1) arguments with h = 1e-6: truncation ~h^2 x f''' ~ 1e-12, round-off
# ~1e-16 / h ~ 1e-10; the Jacobians agree to 1e-7 (relative to their largest entry) with margin.
STEP = 1e-6
JACOBIAN_TOLERANCE = 1e-7


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(SEED)


def _arcs(rng: np.random.Generator, count: int) -> tuple[np.ndarray, np.ndarray]:
    return rng.uniform(0.05, 0.4, count), rng.choice([-1.0, 0.0, 1.0, 0.37, -0.6], count)


def _state_by_polynomials(t: float, d: np.ndarray, lv: np.ndarray, r: int) -> float:
    """The r-th integral of the piecewise-constant levels from rest at t, by integrating each arc's polynomial and
    carrying its derivatives across the arc ends: an independent form of sum_j lv_j (R(t - s_j) - R(t - e_j))."""
    state = np.zeros(r)  # the value and its derivatives below the level's, at the current arc's start
    edges = np.concatenate(([0.0], np.cumsum(d)))
    for j, level in enumerate(lv):
        span = min(t, edges[j + 1]) - edges[j]
        if span <= 0.0:
            break
        poly = Polynomial([*(state[k] / math.factorial(k) for k in range(r)), level / math.factorial(r)])
        state = np.array([poly.deriv(k)(span) for k in range(r)])
    return float(state[0])


def _central(fn, x: np.ndarray) -> np.ndarray:
    columns = []
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = STEP
        columns.append((fn(x + e) - fn(x - e)) / (2 * STEP))
    return np.stack(columns, axis=-1)


def _close(a: np.ndarray, b: np.ndarray) -> None:
    assert np.max(np.abs(a - b)) <= JACOBIAN_TOLERANCE * max(1.0, float(np.max(np.abs(b))))


@pytest.mark.parametrize("r", [1, 2, 3])
def test_state_terms_are_the_arcs_integrated_exactly(rng: np.random.Generator, r: int) -> None:
    d, lv = _arcs(rng, 7)
    times = np.vstack([np.tril(np.ones((7, 7)))[:-1], np.tril(np.ones((7, 7)), -1) + 0.5 * np.eye(7)])
    value, jac_d, diff = state_terms(times, d, lv, r, True)
    for p, row in enumerate(times):
        expected = _state_by_polynomials(float(row @ d), d, lv, r)
        assert value[p] == pytest.approx(expected, rel=1e-12, abs=1e-14)  # round-off of a few terms of O(1)
    assert diff @ lv == pytest.approx(value, rel=1e-12, abs=1e-14)  # the Jacobian in the levels
    _close(jac_d, _central(lambda x: state_terms(times, x, lv, r, False)[0], d))


@pytest.mark.parametrize("n", [0, 1, 2])
def test_moment_terms_are_the_residual_integrals(rng: np.random.Generator, n: int) -> None:
    d, lv = _arcs(rng, 6)
    poles = np.array([complex(-0.3, 9.0), complex(-2.0, 25.0)])
    value, jac_d, diff = moment_terms(poles, n, d, lv, True)
    total, ends = float(np.sum(d)), np.cumsum(d)
    for row, pole in enumerate(poles):
        # F_n = sum_j lv_j int_{T - e_j}^{T - s_j} tau^n e^(lambda tau) dtau, arc by arc by adaptive quadrature
        expected = 0.0j
        for j in range(d.size):
            lo, hi = total - ends[j], total - ends[j] + d[j]
            re = quad(lambda t, p=pole: (t**n * np.exp(p * t)).real, lo, hi, epsabs=1e-14, epsrel=1e-13)[0]
            im = quad(lambda t, p=pole: (t**n * np.exp(p * t)).imag, lo, hi, epsabs=1e-14, epsrel=1e-13)[0]
            expected += lv[j] * complex(re, im)
        assert abs(value[row] - expected) <= 1e-11 * max(1.0, abs(expected))
    assert np.allclose(diff @ lv, value, rtol=1e-12, atol=1e-14)
    for part in (np.real, np.imag):
        _close(part(jac_d), _central(lambda x, part=part: part(moment_terms(poles, n, x, lv, False)[0]), d))


@pytest.mark.parametrize("order", [2, 3])
def test_end_system_is_the_end_state_and_the_moments_with_their_jacobian(rng: np.random.Generator, order: int) -> None:
    count, t0 = 6, 1.3
    d, lv = _arcs(rng, count)
    free = np.array([1, 4], dtype=np.int64)
    z = np.concatenate([d / t0, lv[free]])
    state = np.array([0.0, 0.2, -0.5][:order])  # a start in motion: its drift enters every end derivative
    orders = np.arange(order, dtype=np.int64)
    targets = rng.uniform(-1, 1, order)
    scales = rng.uniform(0.5, 2.0, order)
    poles = np.array([complex(-0.5, 12.0)])
    moment_scales = np.array([[1.7], [0.4]])
    unit = 3.0
    structure = (count, t0, lv, free, unit, orders, targets, scales, state, poles, 1, moment_scales)
    values, jac = end_system(z, structure, True)
    for row, m in enumerate(orders):  # unit x the m-th derivative of the command's share, plus the start's drift
        r = order - m
        own = _state_by_polynomials(float(np.sum(d)), d, lv, r)
        drift = sum(state[k] * np.sum(d) ** (k - m) / math.factorial(k - m) for k in range(m, order))
        assert values[row] == pytest.approx((unit * own + drift - targets[row]) / scales[row], rel=1e-12, abs=1e-13)
    for n in (0, 1):
        f = moment_terms(poles, n, d, lv, False)[0][0]
        row = order + 2 * n
        assert values[row] == pytest.approx(f.real / moment_scales[n, 0], rel=1e-12, abs=1e-13)
        assert values[row + 1] == pytest.approx(f.imag / moment_scales[n, 0], rel=1e-12, abs=1e-13)

    def again(x: np.ndarray) -> np.ndarray:
        return end_system(x, structure, False)[0]

    _close(jac, _central(again, z))


def test_bound_system_is_the_derivative_within_its_limit_at_the_points(rng: np.random.Generator) -> None:
    count, t0, unit, limit = 5, 0.8, 2.0, 0.9
    d, lv = _arcs(rng, count)
    free = np.array([2], dtype=np.int64)
    z = np.concatenate([d / t0, lv[free]])
    state = np.array([0.0, 0.3, 0.1])  # held jerk, starting in motion
    times = np.vstack(
        [np.tril(np.ones((count, count)))[:-1], np.tril(np.ones((count, count)), -1) + 0.5 * np.eye(count)]
    )
    nothing = np.zeros(0)  # (the end conditions' and the moments' data: bound_system does not read them)
    orders, poles = np.zeros(0, dtype=np.int64), np.zeros(0, dtype=complex)
    structure = (count, t0, lv, free, unit, orders, nothing, nothing, state, poles, -1, np.ones((0, 0)))
    values, jac = bound_system(z, structure, 1, limit, times, True)
    points = times.shape[0]
    for p, row in enumerate(times):
        t = float(row @ d)
        velocity = unit * _state_by_polynomials(t, d, lv, 2) + state[1] + state[2] * t
        assert values[p] == pytest.approx(1.0 - velocity / limit, rel=1e-12, abs=1e-13)
        assert values[points + p] == pytest.approx(1.0 + velocity / limit, rel=1e-12, abs=1e-13)
    _close(jac, _central(lambda x: bound_system(x, structure, 1, limit, times, False)[0], z))


def test_refines_inequalities_are_the_bound_and_peak_rows_in_turn() -> None:
    # refine._Model's inequalities come from one compiled call (kernels.inequality_system) and its Jacobian only when
    # SLSQP asks for it: the same bits as bound_system at each bound's check points (velocity, then acceleration)
    # followed by peak_system, whichever is asked first (SLSQP's search and its answers depend on them bit for bit).
    from models.plants import ModePlant
    from optim.families.time_optimal import refine
    from optim.families.time_optimal.kernels import peak_system
    from optim.problem import Limits, Problem

    spec = _spec_of(Problem(ModePlant(25.0, 0.02), displacement=0.3, limits=Limits(0.5, 10.0, 2000.0)))
    durations = [0.004, 0.02, 0.004, 0.03, 0.006, 0.02, 0.006]
    model = refine._Model(spec, durations, [1.0, 0.0, -1.0, 0.0, -1.0, 0.4, 1.0], [False] * 5 + [True, False], [])
    z = model.z0 * (1.0 + 0.01 * np.sin(np.arange(model.z0.size)))
    parts = [bound_system(z, model.structure, m, limit, at, True) for m, limit, at in model.bounds]
    parts.append(peak_system(z, model.structure, float(spec.max_velocity), True))
    assert [m for m, _, _ in model.bounds] == [1, 2] and model.peaks
    values = model.inequalities(z)  # the values first, as SLSQP asks them
    assert np.array_equal(values, np.concatenate([v for v, _ in parts]))
    assert np.array_equal(model.inequality_jacobian(z), np.vstack([j for _, j in parts]))
    again = refine._Model(spec, durations, [1.0, 0.0, -1.0, 0.0, -1.0, 0.4, 1.0], [False] * 5 + [True, False], [])
    assert np.array_equal(again.inequality_jacobian(z), np.vstack([j for _, j in parts]))  # the Jacobian first
    assert np.array_equal(again.inequalities(z), values)


def _spec_of(problem):  # type: ignore[no-untyped-def]
    from optim.families.time_optimal.family import selected_modes, spec_of
    from optim.families.time_optimal.options import TimeOptimalOptions

    options = TimeOptimalOptions()
    return spec_of(problem, options, selected_modes(problem, options)[0])


def test_compiled_newton_finds_singh_and_vadalis_switching_times() -> None:
    # The README's move (40 Hz undamped, 0.12 m at 10 m/s^2, the velocity limit not reached): the optimum is Singh
    # and Vadali's +a t1, -a t2, +a t2, -a t1, whose t2 the oracle finds by brentq on its closed-form residual
    # equation. Newton (kernels.polish) from switching times 5 % off reaches them to 1e-9 of the duration
    # (its own residual is round-off: the scaled equalities below 1e-12).
    from models.plants import ModePlant
    from optim.families.time_optimal.refine import newton
    from optim.problem import Limits, Problem
    from tests.time_optimal_oracle import four_arc

    spec = _spec_of(Problem(ModePlant(40.0), displacement=0.12, limits=Limits(5.0, 10.0)))
    exact = four_arc(2 * math.pi * 40.0, 10.0, 0.12)
    start = [d * f for d, f in zip(exact.durations_s, (1.05, 0.95, 1.05, 0.95), strict=True)]
    command = newton(spec, start, [1.0, -1.0, 1.0, -1.0])
    assert command is not None
    found = [a.duration_s for a in command.arcs]
    assert found == pytest.approx(exact.durations_s, abs=1e-9 * exact.duration_s)


def test_compiled_polish_takes_the_numpy_steps() -> None:
    # Every predicted structure of a held-jerk move with velocity and acceleration limits (bounds active at the
    # solution: the Newton system holds them as equalities), solved by the compiled Newton and by its numpy form
    # (refine._polish_numpy, used where band cuts are present): the same converged ones, the same switching times
    # to 1e-12 (both take minimal-norm least-squares steps by LAPACK's gelsd; only round-off differs).
    from models.plants import ModePlant
    from optim.families.time_optimal import refine
    from optim.families.time_optimal.shaped import rigid_of
    from optim.families.time_optimal.structures import reversal_starts
    from optim.problem import Limits, Problem

    spec = _spec_of(Problem(ModePlant(25.0, 0.02), displacement=0.3, limits=Limits(0.5, 10.0, 2000.0)))
    starts = reversal_starts(spec, rigid_of(spec))
    converged = 0
    for durations, levels, free in starts:
        model = refine._Model(spec, durations, levels, free, [])
        compiled = refine._polish(model, model.z0, refine.NEWTON_ITERATIONS, stall=True)
        ineq = model.inequalities(model.z0)
        active = np.flatnonzero(np.abs(ineq) < refine.ACTIVE)
        movable = np.arange(model.count)
        reference = refine._polish_numpy(model, model.z0.copy(), movable, active, refine.NEWTON_ITERATIONS, True)
        assert (compiled is None) == (reference is None)
        if compiled is not None and reference is not None:
            converged += 1
            assert np.max(np.abs(compiled - reference)) <= 1e-12
    assert 0 < converged < len(starts)  # both outcomes compared


def _switching_spec(q: int, derivative_order: int, poles: tuple[complex, ...]):  # type: ignore[no-untyped-def]
    """A spec of order q (a held jerk for 3) with these zero-residual poles: the certificate's basis for them."""
    from dataclasses import replace

    from models.plants import ModePlant
    from optim.problem import Limits, Problem

    jerk = 2000.0 if q == 3 else None
    spec = _spec_of(Problem(ModePlant(7.0, 0.05), displacement=0.3, limits=Limits(None, 10.0, jerk)))
    return replace(spec, zero_poles=poles, derivative_order=derivative_order)


@pytest.mark.parametrize("q", [2, 3])
@pytest.mark.parametrize("derivative_order", [0, 1])
def test_phi_values_are_the_certificates_basis_times_theta(
    rng: np.random.Generator, q: int, derivative_order: int
) -> None:
    # The switching function phi(tau) = k(tau) - theta . basis(tau) and its first two derivatives, point by point
    # (certify_kernels.phi_values), against certify's own matrix form (kernel - _basis @ theta, numpy) to round-off
    # of terms of O(1) (1e-12 of the largest), and each derivative against central differences of the one below it
    # (h = 1e-6 on O(1) values: truncation h^2 ~ 1e-12, round-off 1e-10; 1e-6 of the largest with margin).
    from optim.families.time_optimal.certify import _basis, _width, kernel
    from optim.families.time_optimal.certify_kernels import phi_values

    spec = _switching_spec(q, derivative_order, (complex(-0.4, 6.0), complex(-1.5, 11.0)))
    theta = rng.normal(size=_width(spec))
    tau = np.linspace(0.0, 1.3, 57)
    poles = np.asarray(spec.zero_poles, dtype=complex)
    exact = np.zeros(tau.size)  # (no step: every exponential computed)
    values = [phi_values(tau, exact, theta, q, poles, derivative_order, d) for d in range(3)]
    for d in range(3):
        expected = kernel(q, tau, d) - _basis(spec, tau, d) @ theta
        assert np.max(np.abs(values[d] - expected)) <= 1e-12 * max(1.0, float(np.max(np.abs(expected))))
    for d in (1, 2):
        slope = (
            phi_values(tau + STEP, exact, theta, q, poles, derivative_order, d - 1)
            - phi_values(tau - STEP, exact, theta, q, poles, derivative_order, d - 1)
        ) / (2 * STEP)
        assert np.max(np.abs(values[d] - slope)) <= 1e-6 * max(1.0, float(np.max(np.abs(values[d]))))


@pytest.mark.parametrize("q", [2, 3])
@pytest.mark.parametrize("derivative_order", [0, 1])
def test_phi_values_on_the_certificates_check_points_take_products_to_round_off(
    rng: np.random.Generator, q: int, derivative_order: int
) -> None:
    # On the check points certify._samples lays (each arc's evenly spaced, 64 per period of the fastest pole, here
    # 150 Hz over 1.3 s: 12,500 points; tau = T - s descending, a junction's time twice), phi_values takes most
    # exponentials as products (certify_kernels.EXACT_EVERY): the same values as certify's matrix form to 1e-12 of the
    # largest term (found: 2e-13, |p| x an ulp of tau, the rounded points against the progression's; the products'
    # own round-off, ~1e-16 each, stays below it). A step of the wrong sign or size is off by O(1).
    from optim.families.time_optimal.certify import _basis, _samples, _width, kernel
    from optim.families.time_optimal.certify_kernels import phi_values

    spec = _switching_spec(q, derivative_order, (complex(-0.4, 6.0), complex(-30.0, 2 * np.pi * 150.0)))
    theta = rng.normal(size=_width(spec))
    edges = np.array([0.0, 0.1237, 0.5, 0.5031, 1.3])
    sampled = _samples(spec, np.diff(edges), edges[:-1], edges[1:])
    assert sampled is not None
    s, _, step = sampled
    tau = edges[-1] - s
    assert tau.size > 12_000 and np.count_nonzero(step) == tau.size - 4
    poles = np.asarray(spec.zero_poles, dtype=complex)
    for d in range(3):
        basis = _basis(spec, tau, d)
        expected = kernel(q, tau, d) - basis @ theta
        terms = float(np.max(np.abs(kernel(q, tau, d)) + np.abs(basis) @ np.abs(theta)))
        found = phi_values(tau, step, theta, q, poles, derivative_order, d)
        assert np.max(np.abs(found - expected)) <= 1e-12 * terms


def test_check_points_are_each_arcs_linspace_bit_for_bit(rng: np.random.Generator) -> None:
    # certify_kernels.check_points (the certificate's check points) against np.linspace on each arc, concatenated:
    # the same bits (i x step + start, the end exact), on 200 random sets of arcs from 1e-8 s to 10 s; each point's
    # arc, and its step in T - s from the point before on its arc (minus linspace's step; 0 at an arc's first point).
    from optim.families.time_optimal.certify_kernels import check_points

    for _ in range(200):
        durations = rng.uniform(0.0, 1.0, rng.integers(1, 12)) * 10.0 ** rng.uniform(-8.0, 1.0)
        ends = np.cumsum(durations)
        starts = ends - durations
        counts = rng.integers(2, 400, durations.size).astype(np.int64)
        s, arc, step = check_points(starts, ends, counts)
        expected = np.concatenate([np.linspace(a, b, n) for a, b, n in zip(starts, ends, counts, strict=True)])
        assert np.array_equal(s, expected)
        assert np.array_equal(arc, np.repeat(np.arange(durations.size), counts))
        spacing = np.repeat((ends - starts) / (counts - 1), counts)
        first = np.concatenate(([0], np.cumsum(counts)[:-1]))
        assert np.all(step[first] == 0.0) and np.array_equal(np.delete(step, first), -np.delete(spacing, first))


def _agreement_wrong(sigma: np.ndarray, arc: np.ndarray, bang: np.ndarray, levels: np.ndarray, tol: float) -> bool:
    """The numpy form certify_kernels.bang_disagrees replaced (certify's agreement, _with_minima, _wrong_signed)."""
    on = bang[arc]
    values = np.where(on, levels[arc] * sigma, np.inf)
    size = float(np.max(np.abs(sigma[on]), initial=0.0))
    mid, left, right = values[1:-1], values[:-2], values[2:]
    same = (arc[:-2] == arc[1:-1]) & (arc[1:-1] == arc[2:])
    dip = same & (mid <= left) & (mid <= right) & np.isfinite(mid)
    curvature = left[dip] - 2 * mid[dip] + right[dip]
    with np.errstate(divide="ignore", invalid="ignore"):
        vertex = mid[dip] - (right[dip] - left[dip]) ** 2 / (8 * curvature)
    vertex = np.where(curvature > 0, vertex, mid[dip])
    return bool(np.any(np.concatenate([values, vertex]) < -tol * (size or 1.0)))


def test_the_certificates_sign_checks_decide_as_their_numpy_form(rng: np.random.Generator) -> None:
    # certify_kernels.bang_disagrees and density_disagrees against the numpy forms they replaced (certify's agreement
    # with the parabola's vertex at each dip, and its density; _wrong_signed), on 3000 random switching functions whose
    # dips sit within 3x the tolerance of the threshold on either side (parabolas between samples, random arcs,
    # levels and kinds): the same decision every time, and both decisions taken.
    from optim.families.time_optimal.certify_kernels import bang_disagrees, density_disagrees

    tol = 1e-6
    decided = {True: 0, False: 0}
    for _ in range(3000):
        counts = rng.integers(3, 40, rng.integers(1, 6))
        arc = np.repeat(np.arange(counts.size), counts).astype(np.int64)
        bang = rng.random(counts.size) < 0.7
        levels = np.where(bang, rng.choice([-1.0, 1.0], counts.size), 0.0)
        x = rng.random(arc.size).cumsum()
        dip = rng.uniform(x[0], x[-1])
        floor = rng.uniform(-3.0, 3.0) * tol
        shape = rng.uniform(0.1, 2.0) * (x - dip) ** 2 / (x[-1] - x[0]) ** 2 + floor  # min near floor, size ~1
        sigma = np.where(levels[arc] != 0.0, levels[arc], 1.0) * shape
        found = bang_disagrees(sigma, arc, bang, levels, tol)
        assert found == _agreement_wrong(sigma, arc, bang, levels, tol)
        decided[found] += 1
        first, sign, beta = ~bang, rng.choice([-1.0, 1.0], counts.size), rng.normal(0.0, 1e-6, counts.size)
        slope = sign[arc] * shape - beta[arc]
        expected = np.where(first[arc], sign[arc] * (slope + beta[arc]), np.inf)
        wrong = bool(np.any(expected < -tol * (float(np.max(np.abs(slope))) or 1.0)))
        assert density_disagrees(slope, arc, first, sign, beta, tol) == wrong
    assert min(decided.values()) > 300
