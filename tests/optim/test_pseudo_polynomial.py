"""Exponent optimisation (Incerti Secs. IV-V) against the paper, the simulator and quadrature."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from models.errors import Infeasible, InvalidParameter, SolverTimedOut
from models.metrics import metrics
from models.plants import ModePlant, RigidFlexiblePlant, TransferFunctionPlant, TwoInertiaPlant, example_plants
from models.pseudo_polynomial import PseudoPolynomial
from models.simulation import simulate
from optim.families import pseudo_polynomial as pp
from optim.solver import SolveCaps

TABLE_III = example_plants()["incerti_table_iii"]
PHI = 30 * math.pi  # 15 motor revolutions (Sec. V)


def dense_peaks(law: PseudoPolynomial) -> tuple[float, float, float]:
    """Peaks of |velocity|, |acceleration|, |jerk| on 200001 points plus a cluster near T."""
    t = np.concatenate([np.linspace(0, law.duration_s, 200_001), law.duration_s * (1 - np.logspace(-12, -5, 50))])
    return tuple(float(np.max(np.abs(law.derivative(k, t)))) for k in (1, 2, 3))  # type: ignore[return-value]


def test_free_state_quadrature_matches_adaptive_quadrature():
    # The optimiser's model computes alpha(T) = -lambda/w_d F (Incerti eqs. 5, 30) by Gauss-Legendre
    # after u = v^2; scipy's adaptive quad of eq. (30)'s F, split at many points, is the reference.
    request = pp.PseudoPolynomialRequest(TABLE_III, PHI, 1.0, 2, (3.3, 4.8, 7.1))
    law = PseudoPolynomial(PHI, 1.0, (3.3, 4.8, 7.1))
    mode = TABLE_III.modes()[0]
    wn, wd, xi = mode.natural_frequency_rad_s, mode.damped_frequency_rad_s, mode.damping_ratio

    def integrand(tau: float) -> float:
        return float(law.derivative(2, np.array([tau]))[0]) * math.exp(-xi * wn * (1 - tau)) * math.sin(wd * (1 - tau))

    f_int = integrate.quad(integrand, 0, 1, points=np.linspace(0, 1, 41)[1:-1], limit=500, epsabs=1e-11, epsrel=1e-11)[
        0
    ]
    energy, residual = pp.evaluate(request, np.array([3.3, 4.8, 7.1]))
    lam = TABLE_III.transmission_ratio
    alpha_t = -lam / wd * f_int
    response = simulate(TABLE_III, law.command(2.5e-4, 1.5))
    end = response.command.end_index()
    # Two routes to alpha(T): quadrature of eq. (30) (to ~1e-12) and the exact simulation of the
    # sampled law (Hermite velocity hold at 0.25 ms: ~1e-9 relative).
    assert response.deflection[end] == pytest.approx(alpha_t, rel=1e-8)
    assert metrics(response).final_energy_j == pytest.approx(energy, rel=1e-7)
    assert metrics(response).residual_amplitude == pytest.approx(residual, rel=1e-7)


def test_table_iii_reaches_zero_energy():
    design = pp.design(pp.PseudoPolynomialRequest(TABLE_III, PHI, 1.0))
    # Acceptance: final energy ratio below 1e-6 and residual below 1e-6 rad, from about 3.5e-3 rad.
    assert design.initial_residual_amplitude == pytest.approx(3.48e-3, rel=2e-3)  # PAPER-NOTES
    assert design.energy_ratio < 1e-6
    assert design.residual_amplitude < 1e-6
    assert design.selection == "closest_zero_energy"
    assert design.solver.status == "Solve_Succeeded"
    # The returned samples, simulated (an independent route), agree: residual below 1e-6 rad.
    simulated = metrics(simulate(TABLE_III, design.law.command(1e-3, 2.0)))
    assert simulated.residual_amplitude < 1e-6
    assert simulated.final_energy_j / design.initial_energy < 1e-6


def test_the_choice_is_the_zero_energy_design_nearest_the_start():
    # The paper's (3.024, 4.565, 5.874) lies on the same zero-energy curve (H/H0 ~ 1e-8, PAPER-NOTES);
    # the rule returns a point of that curve at least as close to (3, 4, 5).
    design = pp.design(pp.PseudoPolynomialRequest(TABLE_III, PHI, 1.0))
    start = np.array([3.0, 4.0, 5.0])
    paper = np.array([3.024, 4.565, 5.874])
    request = pp.PseudoPolynomialRequest(TABLE_III, PHI, 1.0, 2, (3.0, 4.0, 5.0))
    assert pp.evaluate(request, paper)[0] / design.initial_energy < 1e-6
    assert np.linalg.norm(np.array(design.law.exponents) - start) <= np.linalg.norm(paper - start)


@pytest.mark.parametrize("order", [3, 4])
def test_higher_orders_work_on_table_iii(order):
    # Order 3 from (4, 5, 6, 7) has no zero-energy design nearby (the closest solve fails), so the
    # multi-start search is what finds one here.
    design = pp.design(pp.PseudoPolynomialRequest(TABLE_III, PHI, 1.0, order))
    assert design.energy_ratio < 1e-6
    simulated = metrics(simulate(TABLE_III, design.law.command(1e-3, 2.0)))
    assert simulated.residual_amplitude < 1e-6
    assert min(design.law.exponents) >= pp.lower_bound(order) - 1e-12
    assert np.min(np.diff(sorted(design.law.exponents))) >= pp.MIN_SEPARATION - 1e-9


def test_acceleration_limit_tighter_than_the_free_design():
    free = pp.design(pp.PseudoPolynomialRequest(TABLE_III, PHI, 1.0))
    free_peak = dense_peaks(free.law)[1]
    assert free_peak == pytest.approx(615.09, abs=0.05)  # the zero-energy design's own peak
    limited = pp.design(pp.PseudoPolynomialRequest(TABLE_III, PHI, 1.0, limits=pp.Limits(max_acceleration=600.0)))
    # Along the zero-energy curve the peak stays within 614.6..621 rad/s^2 (traced by fsolve while
    # writing this test), so at 600 the lowest energy within the limit is returned, and the limit holds.
    assert dense_peaks(limited.law)[1] <= 600.0 * (1 + 1e-6)
    assert limited.selection == "minimum_energy"
    assert 0 < limited.energy_ratio < 0.1


def test_limits_no_command_meets_are_refused():
    with pytest.raises(Infeasible) as info:
        pp.design(pp.PseudoPolynomialRequest(TABLE_III, PHI, 1.0, limits=pp.Limits(max_velocity=PHI / 1.0 * 0.99)))
    assert info.value.field == "limits.max_velocity"
    with pytest.raises(Infeasible):  # 4 Phi/T^2 = 377 < 500 < 544 (the quintic): no pseudo-polynomial finds it
        pp.design(pp.PseudoPolynomialRequest(TABLE_III, PHI, 1.0, limits=pp.Limits(max_acceleration=500.0)))


def test_shortest_duration_within_limits():
    limits = pp.Limits(max_velocity=200.0, max_acceleration=700.0)
    design = pp.design(pp.PseudoPolynomialRequest(TABLE_III, PHI, 1.0, limits=limits, minimize_duration=True))
    law = design.law
    assert law.duration_s < 1.0
    peaks = dense_peaks(law)
    assert peaks[0] <= 200.0 * (1 + 1e-6) and peaks[1] <= 700.0 * (1 + 1e-6)
    tolerance = 1e-6 * PHI / 30  # default: 1e-6 of the platform's displacement
    simulated = metrics(simulate(TABLE_III, law.command(1e-3, law.duration_s + 1.0)))
    assert simulated.residual_amplitude <= tolerance
    # The bracket: a duration at most 0.2 % shorter was tried and failed.
    failed_below = [d for d, ok in design.duration_search if not ok and d < law.duration_s]
    assert failed_below and max(failed_below) >= law.duration_s * (1 - 2e-3)


def test_torque_limit_on_a_two_inertia_plant():
    plant = TwoInertiaPlant(0.005, 0.02, 0.02 * (2 * math.pi * 8.0) ** 2, 0.05)
    free = pp.design(pp.PseudoPolynomialRequest(plant, 10.0, 0.6))
    free_torque = float(np.max(np.abs(simulate(plant, free.law.command(1e-4, 1.0)).motor_torque_nm)))
    limit = 0.97 * free_torque
    limited = pp.design(pp.PseudoPolynomialRequest(plant, 10.0, 0.6, limits=pp.Limits(max_torque_nm=limit)))
    torque = simulate(plant, limited.law.command(1e-4, 1.0)).motor_torque_nm  # exact simulation, 0.1 ms
    # The optimiser imposes the limit on a T/200 grid with 0.01 % margin; the fine simulation checks it.
    assert float(np.max(np.abs(torque))) <= limit * (1 + 1e-3)


@pytest.mark.parametrize(
    "plant", [ModePlant(3.0, 0.02), RigidFlexiblePlant(2.0, 3.0, 1.0, 0.1, 30.0)], ids=["mode", "rigid_flexible"]
)
def test_plants_without_physical_energy(plant):
    # Order-2 zero-energy designs exist near whole numbers of periods (a scan of 1.5..8 periods on a
    # mode found them at 4, 5, 6, 7, 8 and not at the half periods), so the move lasts 5 periods.
    period = plant.modes()[0].natural_period_s
    design = pp.design(pp.PseudoPolynomialRequest(plant, 1.0, 5.0 * period))
    assert not design.energy_is_physical
    assert design.energy_ratio < 1e-6
    simulated = metrics(simulate(plant, design.law.command(period / 500, 8 * period)))
    initial = metrics(simulate(plant, design.initial.command(period / 500, 8 * period)))
    assert simulated.residual_amplitude < 1e-3 * initial.residual_amplitude


def test_problem_is_built_once_per_plant_kind_from_its_symbolic_form():
    # Two two-inertia plants with different values share one compiled problem (their values are
    # parameters of the plant's symbolic form), and it agrees with the modal-data form used for
    # higher-order plants, evaluated on the same plant.
    a = TwoInertiaPlant(0.005, 0.02, 50.0, 0.05)
    b = TwoInertiaPlant(0.01, 0.03, 80.0, 0.0)
    keys_before = set(pp.SOLVER_CACHE)
    for plant in (a, b):
        design = pp.design(pp.PseudoPolynomialRequest(plant, 1.0, 5 * plant.modes()[0].natural_period_s))
        assert design.energy_is_physical and design.energy_ratio < 1.0
    new = set(pp.SOLVER_CACHE) - keys_before
    assert len({key[-1] for key in new}) <= 1  # at most one new plant-kind key (none if warm)
    request = pp.PseudoPolynomialRequest(a, 1.0, 0.6, 2, (3.2, 4.4, 6.1))
    symbolic_compiled, p_symbolic, gamma = pp.prepare(request)
    modal = pp.oscillatory_modal_form(a)
    numeric_compiled = pp._build(2, 1, (False,) * 4, request.caps, None)
    p_numeric = pp.parameter_vector(request, modal, numeric_compiled, gamma)
    e_symbolic = float(symbolic_compiled.evaluate(gamma, p_symbolic)[0])
    e_numeric = float(numeric_compiled.evaluate(gamma, p_numeric)[0])
    assert "plant" in symbolic_compiled.layout and "plant" not in numeric_compiled.layout
    assert e_symbolic == pytest.approx(e_numeric, rel=1e-12)


# --- issue 11: limits that hold, fallbacks, long moves, time-outs, the duration search -----------------


def test_product_weights_match_a_composite_gauss_legendre_reference():
    # The problem's free states use 2 sum_j W_j v_j^(2 gamma - 3) (product integration, problem.py). The
    # reference integrates 2 v^(2 gamma - 3) exp(z v^2) directly by 40-node Gauss-Legendre on |z| + 64 panels
    # (the phase turns < 2 rad per panel: converged to round-off). Tolerance: (gamma - 1) |error| below
    # 1e-13, the level measured while writing the rule (5e-14 worst, at |z| = 31 and gamma = 80).
    x, w = np.polynomial.legendre.leggauss(40)
    for size in (31.0, 500.0, 3000.0):
        z = size * complex(-0.05, math.sqrt(1 - 0.05**2))
        weights, v = pp.product_weights(z), pp.product_integration.chebyshev_nodes()
        edges = np.linspace(0.0, 1.0, int(size) + 65)
        a, b = edges[:-1, None], edges[1:, None]
        nodes, node_weights = a + 0.5 * (b - a) * (x + 1), 0.5 * (b - a) * w
        for gamma in (3.0, 3.02, 3.3, 5.0, 13.0, 40.0, 80.0):
            reference = 2 * np.sum(node_weights * nodes ** (2 * gamma - 3) * np.exp(z * nodes * nodes))
            value = 2 * np.sum(weights * v ** (2 * gamma - 3))
            assert abs(value - reference) * (gamma - 1) < 1e-13, (size, gamma)


@pytest.mark.parametrize("periods", [83, 200])
def test_long_moves_against_the_simulation(periods):
    # Issue 11: a 1.17 s move at 83 periods (a 70.9 Hz mode) used to be refused above 76 periods (the
    # Gauss-Legendre node count grew with the phase). The optimiser's residual of the quintic start is
    # compared with the exact simulation of its command sampled at 1/200 period (Hermite velocity hold:
    # ~1e-9 relative, as in the Table III test above); the returned design's too (to 1e-6 of it, or 1e-15 of
    # the move where it is zero to round-off), and it must fall below 1e-3 of the quintic's. (At 83 periods
    # the closest zero-energy solve stops short and the minimum-energy design leaves 1.5e-8 of the energy.)
    plant = ModePlant(periods / 1.17, 0.02)
    period = plant.modes()[0].natural_period_s
    request = pp.PseudoPolynomialRequest(plant, 1.0, periods * period)
    design = pp.design(request)
    horizon = request.duration_s + 3 * period
    initial = metrics(simulate(plant, design.initial.command(period / 200, horizon)))
    assert initial.residual_amplitude == pytest.approx(design.initial_residual_amplitude, rel=1e-6)
    final = metrics(simulate(plant, design.law.command(period / 200, horizon)))
    assert final.residual_amplitude == pytest.approx(design.residual_amplitude, rel=1e-6, abs=1e-15)
    assert final.residual_amplitude < 1e-3 * initial.residual_amplitude


def test_too_long_a_move_is_refused_with_the_cap():
    plant = ModePlant(100.0, 0.02)
    with pytest.raises(InvalidParameter) as info:
        pp.design(pp.PseudoPolynomialRequest(plant, 1.0, 60.0))  # 6000 periods > 5000
    assert info.value.field == "duration_s" and "5000" in info.value.rule


def test_limits_hold_on_the_law_after_tightening():
    # Issue 11's reproducer: the solver's T/100 constraint grid let the jerk through (118722 > 118613 on the
    # law itself); the design is re-solved with the limit tightened until its own dense peaks hold.
    plant = ModePlant(3.4136132292137797, 0.2840572223301995)
    limit = 118612.89875371839
    request = pp.PseudoPolynomialRequest(
        plant, -717.9817512876891, 0.8859491534569945, 3, limits=pp.Limits(max_jerk=limit)
    )
    design = pp.design(request)
    assert dense_peaks(design.law)[2] <= limit * (1 + 1e-9)  # 200001 points vs the check's 20001: same peak


def test_fallback_when_no_minimum_energy_solve_converges():
    # Issue 11's reproducer (a two-mode transfer function, order 3): IPOPT's minimum-energy solves all stop
    # unconverged although designs within the limits exist (the classical 4-5-6-7 polynomial is one, its
    # peaks 2.24 < 4.18 and 61 < 245). The lowest-energy one met is returned, said to be a fallback.
    plant = TransferFunctionPlant(
        (5329676.87849852, 21471366684.057102),
        (1.0, 163.11501159112285, 689806.5368298043, 5329676.87849852, 21471366684.057102),
    )
    limits = pp.Limits(max_acceleration=4.180686100801731, max_jerk=244.7660123724046)
    request = pp.PseudoPolynomialRequest(plant, 0.016550784134077873, 0.22808753015020575, 3, limits=limits)
    design = pp.design(request)
    assert design.selection == "fallback" and "converged" in design.fallback_reason
    assert not design.solver.converged
    assert design.final_energy <= design.initial_energy  # never worse than the classical polynomial
    peaks = dense_peaks(design.law)
    assert peaks[1] <= limits.max_acceleration and peaks[2] <= limits.max_jerk


@pytest.mark.parametrize("minimize", [False, True])
def test_a_time_out_is_never_infeasible(minimize):
    # A wall-time cap of 0.1 ms stops IPOPT at its first iteration: the design must raise SolverTimedOut
    # (problem type solve-timeout), not Infeasible, with or without the duration search.
    caps = SolveCaps(max_wall_time_s=1e-4)
    limits = pp.Limits(max_velocity=200.0, max_acceleration=700.0)
    request = pp.PseudoPolynomialRequest(TABLE_III, PHI, 1.6, limits=limits, minimize_duration=minimize, caps=caps)
    with pytest.raises(SolverTimedOut):
        pp.design(request)


def test_duration_search_of_the_compare_example():
    # The compare example (app/routers/compare.py): Table III, 15 revolutions, v <= 200, a <= 700, order 2,
    # from 8 periods (the family's default). Before issue 11 the search returned 0.98011 s (4.863 periods)
    # after 43 solves reported as 1; the scan from the kinematic floor (3.64 periods) must do at least as well,
    # count every solve, and give a bracket within 0.1 % (the bisection's stop) with an infeasible duration.
    period = TABLE_III.modes()[0].natural_period_s
    limits = pp.Limits(max_velocity=200.0, max_acceleration=700.0)
    request = pp.PseudoPolynomialRequest(TABLE_III, PHI, 8 * period, limits=limits, minimize_duration=True)
    design = pp.design(request)
    law = design.law
    assert law.duration_s <= 0.98011294 * (1 + 1e-9)
    assert design.selection == "closest_zero_energy"
    assert design.solves >= len(design.duration_search) > 1
    below = design.longest_infeasible_below_s
    assert below is not None and law.duration_s * (1 - 1e-3) <= below < law.duration_s
    assert (below, False) in design.duration_search and (law.duration_s, True) in design.duration_search
    peaks = dense_peaks(law)
    assert peaks[0] <= 200.0 and peaks[1] <= 700.0
    simulated = metrics(simulate(TABLE_III, law.command(1e-3, law.duration_s + 1.0)))
    assert simulated.residual_amplitude <= 1e-6 * PHI / 30  # the default tolerance: 1e-6 of the platform's move


def test_a_duration_search_that_finds_nothing_falls_back_to_the_design_at_duration_s():
    """40 Hz, zeta 0.1, 0.05 within v <= 0.5, a <= 20: the whole-period scan finds no zero-energy design
    within the limits (one exists: a fixed 0.225 s design reaches it through the multi-start), so the search
    is no proof of infeasibility: the answer is the design at duration_s, with a warning naming the scan."""
    from optim.families.pseudo_polynomial.family import PseudoPolynomialOptions
    from optim.problem import Limits, Problem
    from optim.registry import FAMILIES

    family = FAMILIES["pseudo_polynomial"]
    problem = Problem(ModePlant(40.0, 0.1), displacement=0.05, limits=Limits(max_velocity=0.5, max_acceleration=20.0))
    options = family.default_options(problem)
    design = family.design(problem, options)
    assert design.end_s == options.duration_s
    assert any(w.startswith("minimize_duration: the duration search found no") for w in design.warnings)
    fixed = family.design(problem, PseudoPolynomialOptions(duration_s=0.225))
    assert fixed.summary.selection == "closest_zero_energy"


# --- issue 23: the built problems a worker keeps are bounded in estimated MiB, not only in count -------------


def test_cache_budget_evicts_before_building_and_keeps_the_newest():
    from runtime.cache import LruCache

    built: list[str] = []
    cache: LruCache[str, str] = LruCache("test-budget", size=64, weigh=lambda key: float(len(key)), budget=10.0)
    for key in ("aaaa", "bbbb", "cc"):  # 4 + 4 + 2 = 10: all fit
        cache.get(key, lambda key=key: built.append(key) or key)
    assert cache.keys() == ["aaaa", "bbbb", "cc"] and cache.weight == 10.0
    cache.get("aaaa", lambda: "never")  # a hit refreshes, builds nothing
    cache.get("ddddd", lambda: built.append("ddddd") or "ddddd")  # 5 more: least recently used first
    assert cache.keys() == ["aaaa", "ddddd"] and cache.weight == 9.0  # bbbb, then cc, made room
    cache.get("x" * 12, lambda: "big")  # heavier than the budget alone: built and kept, alone
    assert cache.keys() == ["x" * 12]
    assert built == ["aaaa", "bbbb", "cc", "ddddd"]


def test_every_problem_a_request_can_ask_for_fits_the_worker_budget():
    # The largest shapes the schema admits (order MAX_ORDER with all four limits on a two-inertia plant, or
    # MAX_MODES modes with the three kinematic ones) are estimated at ~100 MiB (measured: 93 MiB resident),
    # below the budget, so one request's problem is always built; the fuzz bench's (order 4, minimize_duration
    # with all four limits) 57 MiB. The warm-up's problems fit the budget together.
    from optim.families.pseudo_polynomial.problem import PROBLEM_CACHE_MIB, build_mib

    largest = max(
        build_mib(pp.MAX_ORDER, 1, (True,) * 4), build_mib(pp.MAX_ORDER, pp.MAX_MODES, (True,) * 3 + (False,))
    )
    assert 90.0 < largest < 110.0 < PROBLEM_CACHE_MIB
    assert build_mib(4, 1, (True,) * 4) == pytest.approx(56.7, abs=0.1)
    warm = sum(build_mib(order, 1, (False,) * 4) for order in (2, 3, 4)) * len(pp.SYMBOLIC_KINDS)
    assert warm < PROBLEM_CACHE_MIB
    assert pp.SOLVER_CACHE.budget == PROBLEM_CACHE_MIB and pp.SOLVER_CACHE.weight <= PROBLEM_CACHE_MIB


def test_a_built_problem_costs_no_more_than_its_estimate():
    # Order 3, one mode, velocity and jerk limits, in this (warm) process: the resident set grows by at most
    # the estimate (the fit's largest error was 1.6 MiB on consecutive builds, 6 MiB on a fresh process's first).
    import resource

    from optim.families.pseudo_polynomial.problem import build_mib
    from optim.solver import SolveCaps

    active = (True, False, True, False)
    pp._build(2, 1, active, SolveCaps(), None)  # the process's first build of this kind loads IPOPT's plug-ins
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    with open("/proc/self/status") as f:
        rss_before = next(int(line.split()[1]) for line in f if line.startswith("VmRSS"))
    kept = pp._build(3, 1, active, SolveCaps(), None)
    with open("/proc/self/status") as f:
        rss_after = next(int(line.split()[1]) for line in f if line.startswith("VmRSS"))
    assert kept is not None and before > 0
    assert (rss_after - rss_before) / 1024 <= build_mib(3, 1, active)
