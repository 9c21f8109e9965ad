"""What smoothers leave on the paper's plant (Biagiotti et al. 2020, Sec. VI): residuals by simulation and an ODE."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from models.metrics import metrics
from models.plants import TwoInertiaPlant
from models.simulation import simulate
from models.smoothers import Chain, Smoother, mode_residuals, refinement, residual_fraction, step_response
from tests.models.test_smoothers import OMEGA, OMEGA_N, PLANT, POLE, SIGMA, T1, H


def test_damped_harmonic_smoother_cancels_the_papers_plant():
    # Acceptance: sigma = -15.6539, Omega = 122.7185, T1 = 3 pi/Omega = 0.0768 s (PAPER-NOTES), a 30 mm step.
    assert 2 * math.pi / OMEGA == pytest.approx(0.0512, abs=5e-5)  # T0, Sec. VI
    assert pytest.approx(0.0768, abs=5e-5) == T1
    chain = Chain((Smoother("damped_harmonic", T1, -SIGMA),))
    closed, unfiltered = mode_residuals(chain, PLANT, H)
    # Unfiltered: a step leaves 2|r/p| h = h omega_n/Omega of vibration (closed form of G at its pole).
    assert unfiltered[0] == pytest.approx(H * OMEGA_N / OMEGA, rel=1e-12)
    assert closed[0] < 1e-9 * H  # zero to round-off: the zeros of S_sigma sit on the plant's poles (eq. 11)
    simulated = metrics(simulate(PLANT, step_response(chain, H, 5e-4).command())).residual_amplitude
    assert simulated < 1e-9 * H  # measured: ~6e-17 m


def test_undamped_harmonic_leaves_about_four_percent():
    # Acceptance: S with T = 3 pi/Omega on the damped plant leaves a clear residual, about 4 % of 30 mm
    # (Sec. V, Fig. 6 (b)). Closed form and the simulation of the sampled command agree to 1e-9.
    chain = Chain((Smoother("harmonic", T1),))
    closed, _ = mode_residuals(chain, PLANT, H)
    simulated = metrics(simulate(PLANT, step_response(chain, H, 5e-4).command())).residual_amplitude
    assert simulated == pytest.approx(closed[0], rel=1e-9)
    assert 0.04 < simulated / H < 0.045  # 4.31 %


@pytest.mark.parametrize(("multiple", "free"), [(3, True), (5, True), (6, False), (7, True)])
def test_only_odd_multiples_of_pi_over_omega_are_vibration_free(multiple, free):
    # PAPER-NOTES: the zeros of S_sigma lie at sigma +- j (2m+1) pi/T, m >= 1, so T = k pi/Omega cancels the mode
    # only for odd k >= 3; eqs. (13) and (15) (T = 3k pi/Omega) are wrong for even k.
    chain = Chain((Smoother("damped_harmonic", multiple * math.pi / OMEGA, -SIGMA),))
    ratio = abs(chain.frequency_response(np.array([POLE]))[0])
    simulated = metrics(simulate(PLANT, step_response(chain, H, 5e-4).command())).residual_amplitude
    if free:
        assert ratio < 1e-12 and simulated < 1e-9 * H
    else:
        assert ratio > 0.05  # 8.3 % of the unfiltered envelope (same time)
        assert simulated > 5e-3 * H  # 0.75 % of the move when the motion ends


def test_exponential_filter_cancels_at_a_full_period():
    # M_sigma's zeros lie at sigma +- j 2 k pi/T: T = T0 = 2 pi/Omega with sigma = -zeta omega_n cancels the mode.
    chain = Chain((Smoother("exponential", 2 * math.pi / OMEGA, -SIGMA),))
    assert residual_fraction(chain, POLE) < 1e-13
    half = Chain((Smoother("exponential", math.pi / OMEGA, -SIGMA),))
    assert residual_fraction(half, POLE) > 0.1


def test_closed_form_residual_matches_simulation_on_a_two_inertia_plant():
    # The closed form uses the residues of any plant's load transfer function; a damped two-inertia plant
    # checks it against the simulated command (1e-9: the Taylor command is exact to ~1e-16 of the move).
    plant = TwoInertiaPlant(0.01, 0.02, 50.0, 0.2)
    mode = plant.modes()[0]
    chain = Chain((Smoother("rectangular", 0.3), Smoother("harmonic", 1.3 * math.pi / mode.damped_frequency_rad_s)))
    closed, _ = mode_residuals(chain, plant, 0.7)
    simulated = metrics(simulate(plant, step_response(chain, 0.7, 2e-3).command())).residual_amplitude
    assert closed[0] > 1e-4  # the chain is not tuned: there is something to compare
    assert simulated == pytest.approx(closed[0], rel=1e-9)


@pytest.mark.parametrize(("period", "k"), [(2e-4, 1), (1e-3, 1), (4e-3, 3)])
def test_smooth_chains_simulate_to_their_closed_form(period, k):
    # A C^7 chain of untuned filters (clear residual) on the paper's plant: the Taylor command's simulation
    # must equal the closed form (1e-7: at |lambda| Ts <= 0.2 the Taylor remainder is ~1e-10 of the move).
    # Every Taylor order is continuous here, so the command must not declare them all so (that would drop
    # the high-order jumps that carry the motion between samples). 4 ms is refined by 3 (|lambda| = 101 1/s).
    chain = Chain(
        (
            Smoother("harmonic", 0.05),
            Smoother("damped_harmonic", 0.09, 5.0),
            Smoother("harmonic", 0.031),
            Smoother("exponential", 0.02, 7.0),
            Smoother("rectangular", 0.04),
        )
    )
    assert chain.continuous_derivatives == 7  # 2 + 2 + 2 + 1 + 1 - 1
    assert refinement(chain, period) == k
    closed, _ = mode_residuals(chain, PLANT, H)
    simulated = metrics(simulate(PLANT, step_response(chain, H, period / k).command())).residual_amplitude
    assert closed[0] > 1e-6 * H
    assert simulated == pytest.approx(closed[0], rel=1e-7)


def test_load_response_matches_an_ode_driven_by_the_closed_form_trajectory():
    # Independent of the cascade and of the Taylor command: integrate eps'' + 2 zeta w eps' + w^2 eps = -q''
    # (eq. 7) with q'' from differentiating the paper's trajectory, and compare the deflection at the end.
    f = Smoother("harmonic", 0.0768)
    w, z = OMEGA_N, -SIGMA / OMEGA_N
    a = math.pi / f.duration_s

    def rhs(t, x):
        acc = H / 2 * a * a * math.cos(a * t) if t < f.duration_s else 0.0
        return [x[1], -2 * z * w * x[1] - w * w * x[0] - acc]

    sol = integrate.solve_ivp(rhs, (0, f.duration_s), [0.0, 0.0], method="DOP853", rtol=1e-12, atol=1e-16)
    response = simulate(PLANT, step_response(Chain((f,)), H, 5e-4).command())
    ours = response.deflection[-1]
    assert ours == pytest.approx(sol.y[0, -1], rel=1e-8)  # DOP853 at rtol 1e-12: ~1e-10 relative
