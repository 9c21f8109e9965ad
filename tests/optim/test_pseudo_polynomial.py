"""Exponent optimisation (Incerti Secs. IV-V) against the paper, the simulator and quadrature."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from models.errors import Infeasible
from models.plants import ModePlant, RigidFlexiblePlant, TwoInertiaPlant, example_plants
from models.pseudo_polynomial import PseudoPolynomial
from models.simulation import metrics, simulate
from optim import pseudo_polynomial as pp

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
    keys_before = set(pp._CACHE)
    for plant in (a, b):
        design = pp.design(pp.PseudoPolynomialRequest(plant, 1.0, 5 * plant.modes()[0].natural_period_s))
        assert design.energy_is_physical and design.energy_ratio < 1.0
    new = set(pp._CACHE) - keys_before
    assert len({key[-1] for key in new}) <= 1  # at most one new plant-kind key (none if warm)
    request = pp.PseudoPolynomialRequest(a, 1.0, 0.6, 2, (3.2, 4.4, 6.1))
    symbolic_compiled, p_symbolic, gamma = pp._prepare(request)
    modal = pp._oscillatory(a)
    numeric_compiled = pp._build(2, 1, (False,) * 4, request.caps, None)
    p_numeric = pp._parameters(request, modal, numeric_compiled, gamma)
    e_symbolic = float(symbolic_compiled.evaluate(gamma, p_symbolic)[0])
    e_numeric = float(numeric_compiled.evaluate(gamma, p_numeric)[0])
    assert "plant" in symbolic_compiled.layout and "plant" not in numeric_compiled.layout
    assert e_symbolic == pytest.approx(e_numeric, rel=1e-12)
