"""The pseudo-polynomial motion law (Incerti eqs. 8-23)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from models.errors import InvalidParameter
from models.metrics import metrics
from models.plants import example_plants
from models.pseudo_polynomial import PseudoPolynomial, check_exponents, coefficients, coefficients_order_2
from models.simulation import simulate


def test_table_ii_coefficients():
    # Incerti Table II: (3, 4, 5) -> (10, -15, 6); (4.5, 6.2, 8.4) -> (7.855, -10.107, 3.252), and
    # PAPER-NOTES' reproduction to 4 decimals (7.8552, -10.1070, 3.2517).
    np.testing.assert_allclose(coefficients([3, 4, 5]), [10, -15, 6], rtol=1e-13)
    np.testing.assert_allclose(coefficients([4.5, 6.2, 8.4]), [7.8552, -10.1070, 3.2517], atol=5e-5)


@pytest.mark.parametrize("exponents", [(3, 4, 5), (4.5, 6.2, 8.4), (3.024, 4.565, 5.874)])
def test_linear_system_matches_the_closed_form_of_eq_16(exponents):
    np.testing.assert_allclose(coefficients(exponents), coefficients_order_2(*exponents), rtol=1e-12)


@pytest.mark.parametrize("exponents", [(2.5, 3.0), (3, 4, 5), (4.2, 5.1, 6.3, 7.7), (5.5, 6, 7, 8.5, 9.1)])
def test_boundary_conditions_hold_for_any_order(exponents):
    # eqs. (11), (12), (20): position 0 -> Phi, derivatives 1..n null at both ends.
    law = PseudoPolynomial(2.0, 0.5, exponents)
    n = law.order
    start, end = np.array([0.0]), np.array([0.5])
    # Round-off: the sums cancel terms of size Phi |C_i| (C grows as the exponents get closer).
    roundoff = 64 * np.finfo(float).eps * 2.0 * sum(abs(c) for c in law.coefficients)
    assert law.derivative(0, start)[0] == pytest.approx(0.0, abs=roundoff)
    assert law.derivative(0, end)[0] == 2.0
    for k in range(1, min(n, 3) + 1):
        assert law.derivative(k, start)[0] == pytest.approx(0.0, abs=1e-9 * 2.0 / 0.5**k)
        assert law.derivative(k, end - 1e-12, left_at_end=True)[0] == pytest.approx(0.0, abs=1e-6 * 2.0 / 0.5**k)


def test_derivatives_match_finite_differences():
    # An independent check of eq. (18): central differences of the law itself.
    law = PseudoPolynomial(30 * math.pi, 1.0, (4.5, 6.2, 8.4))
    t = np.linspace(0.05, 0.95, 37)
    h = 1e-5
    for k in (1, 2, 3):
        numeric = (law.derivative(k - 1, t + h) - law.derivative(k - 1, t - h)) / (2 * h)
        # central difference error ~ h^2 f'''/6, a few 1e-8 relative here
        np.testing.assert_allclose(law.derivative(k, t), numeric, rtol=1e-6, atol=1e-6 * np.max(np.abs(numeric)))


def test_quintic_is_the_classical_polynomial():
    law = PseudoPolynomial(1.0, 1.0, (3, 4, 5))
    s = np.linspace(0, 1, 11)
    np.testing.assert_allclose(law.derivative(0, s), 10 * s**3 - 15 * s**4 + 6 * s**5, atol=1e-14)


def test_sampled_command_follows_the_law_and_leaves_its_residual():
    # The command that the drive runs (velocity on the Hermite curve) must reproduce the law: same
    # velocity and acceleration at the samples, position within O(h^4), and (for the quintic, whose
    # acceleration is a cubic) exactly the residual of the exact polynomial, 3.4766e-3 rad
    # (PAPER-NOTES: about 3.48e-3), at any sample period.
    plant = example_plants()["incerti_table_iii"]
    law = PseudoPolynomial(30 * math.pi, 1.0, (3, 4, 5))
    residuals = []
    for period in (1e-3, 2.5e-4):
        command = law.command(period, 2.0)
        t = command.time_s
        np.testing.assert_allclose(command.derivative(1), law.derivative(1, t), rtol=0, atol=1e-9)
        np.testing.assert_allclose(command.derivative(0), law.derivative(0, t), rtol=0, atol=1e-8)
        residuals.append(metrics(simulate(plant, command)).residual_amplitude)
    assert residuals[0] == pytest.approx(3.48e-3, rel=2e-3)
    assert residuals[0] == pytest.approx(residuals[1], rel=1e-9)


@pytest.mark.parametrize(
    ("exponents", "order"), [((3, 4), 2), ((2, 3, 4), 2), ((3, 3, 4), 2), ((3, float("nan"), 5), 2)]
)
def test_bad_exponents(exponents, order):
    with pytest.raises(InvalidParameter):
        check_exponents(exponents, order)
