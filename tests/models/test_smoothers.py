"""Smoother filters (Biagiotti et al. 2020): transfer functions, step responses and chains.

Their residuals are in test_smoother_residuals.py, the discrete filters of eq. (17) in test_smoother_discrete.py.

Independent references: quadrature of the impulse response (Laplace transform, convolution),
scipy.signal.freqresp of the rational part and the paper's closed-form trajectories.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, signal

from models.errors import InvalidParameter
from models.plants import ModePlant
from models.smoothers import Chain, Smoother, step_response

# The paper's identified plant (Sec. VI): sigma = -15.6539 1/s, Omega = 122.7185 rad/s.
SIGMA = -15.6539
OMEGA = 122.7185
OMEGA_N = math.hypot(SIGMA, OMEGA)
PLANT = ModePlant(OMEGA_N / (2 * math.pi), -SIGMA / OMEGA_N)
POLE = complex(SIGMA, OMEGA)
H = 0.03  # the 30 mm step of Fig. 17
T1 = 3 * math.pi / OMEGA  # 0.0768 s (eq. 11)

FILTERS = {
    "rectangular": Smoother("rectangular", 0.4),
    "harmonic": Smoother("harmonic", 0.3),
    "damped_harmonic": Smoother("damped_harmonic", 0.3, 4.0),
    "exponential": Smoother("exponential", 0.25, 3.0),
}


def laplace_by_quadrature(f: Smoother, s: complex) -> complex:
    """int_0^T f(t) e^(-st) dt by adaptive quadrature of the closed-form impulse response."""

    def part(g):
        return integrate.quad(
            lambda t: g(f.impulse_response(np.array(t)) * np.exp(-s * t)),
            0,
            f.duration_s,
            epsabs=1e-13,
            epsrel=1e-12,
            limit=200,
        )[0]

    return part(np.real) + 1j * part(np.imag)


def damped_harmonic_trajectory(t: np.ndarray, h: float, duration: float, sigma: float) -> np.ndarray:
    """Sec. V: q = h/(1 + e^(sigma T)) (1 + e^(sigma t)((sigma T/pi) sin(pi t/T) - cos(pi t/T))), h after T."""
    q = (
        h
        / (1 + math.exp(sigma * duration))
        * (
            1
            + np.exp(sigma * t)
            * (sigma * duration / math.pi * np.sin(math.pi * t / duration) - np.cos(math.pi * t / duration))
        )
    )
    return np.where(t >= duration, h, q)


@pytest.mark.parametrize("name", sorted(FILTERS))
def test_impulse_response_has_unit_area(name):
    # Unit static gain F(0) = 1 (eqs. 1, 5, 10 and M_sigma's normalisation); quadrature is good to 1e-13.
    f = FILTERS[name]
    area = integrate.quad(lambda t: float(f.impulse_response(np.array(t))), 0, f.duration_s, epsabs=0, epsrel=1e-13)[0]
    assert area == pytest.approx(1.0, rel=1e-12)
    assert f.frequency_response(np.array([0j]))[0] == pytest.approx(1.0, rel=1e-15)


@pytest.mark.parametrize("name", sorted(FILTERS))
def test_transfer_function_equals_the_laplace_transform_of_the_impulse_response(name):
    # Closed forms (eqs. 1, 5, 10) against quadrature, including the removable poles s = sigma +- j pi/T where
    # the direct formula is 0/0, points just beside them, and a damped plant pole.
    f = FILTERS[name]
    a = math.pi / f.duration_s
    sigma = f.sigma_1_s
    points = [1j * 3.0, 2.0 - 5j, sigma + 1j * a, sigma - 1j * a, sigma + 1j * a * (1 + 1e-7), -1.5 + 40j, 0.7j * a]
    for s in points:
        expected = laplace_by_quadrature(f, s)
        ours = f.frequency_response(np.array([s]))[0]
        # quadrature is asked for 1e-12 relative; |F| is O(1) at these points
        assert abs(ours - expected) <= 1e-11 * max(1.0, abs(expected)), (s, ours, expected)
        shifted = f.end_response(np.array([s]))[0]
        assert shifted == pytest.approx(ours * np.exp(s * f.duration_s), rel=1e-12, abs=1e-14)


@pytest.mark.parametrize("name", sorted(FILTERS))
def test_transfer_function_matches_scipy_freqs_of_its_rational_part(name):
    # Second method: F(jw) = (c0 + c1 e^(-jwT)) R(jw), R written as polynomials from the paper (1/s for eq. 1,
    # 1/(s^2 + (pi/T)^2) for eq. 5, 1/((s - sigma)^2 + (pi/T)^2) for eq. 10, 1/(s - sigma) for M_sigma) and
    # evaluated by scipy.signal.freqs.
    f = FILTERS[name]
    sigma, a = f.sigma_1_s, math.pi / f.duration_s
    den = {
        "rectangular": [1.0, 0.0],
        "exponential": [1.0, -sigma],
        "harmonic": [1.0, 0.0, a * a],
        "damped_harmonic": [1.0, -2 * sigma, sigma * sigma + a * a],
    }[name]
    w = np.linspace(0.1, 80.0, 57)
    _, rational = signal.freqs([1.0], den, w)
    c0, c1 = f.delay_coefficients
    expected = (c0 + c1 * np.exp(-1j * w * f.duration_s)) * rational
    np.testing.assert_allclose(f.frequency_response(1j * w), expected, rtol=1e-9, atol=1e-12)


def test_harmonic_magnitude_is_the_papers_formula():
    # Sec. IV: |S(jw)| = |cos(pi w/w_i)| / |1 - (w/(w_i/2))^2| with w_i = 2 pi/T.
    f = Smoother("harmonic", 0.3)
    wi = 2 * math.pi / f.duration_s
    w = np.linspace(0.05, 100.0, 400)
    w = w[np.abs(w - wi / 2) > 1e-3]  # the formula is 0/0 at w_i/2
    expected = np.abs(np.cos(math.pi * w / wi)) / np.abs(1 - (w / (wi / 2)) ** 2)
    np.testing.assert_allclose(np.abs(f.frequency_response(1j * w)), expected, rtol=1e-9)


def test_harmonic_step_response_is_the_harmonic_trajectory():
    # Sec. III: q_h(t) = h/2 (1 - cos(pi t/T)); its velocity is h times the impulse response (eq. 4).
    f = Smoother("harmonic", 0.3)
    r = step_response(Chain((f,)), 2.0, 1e-3)
    t = r.time_s
    np.testing.assert_allclose(r.position, np.where(t < 0.3, 1.0 - np.cos(math.pi * t / 0.3), 2.0), rtol=0, atol=1e-14)
    np.testing.assert_allclose(r.derivative(1), 2.0 * f.impulse_response(t), rtol=0, atol=1e-12)
    assert Chain((f,)).continuous_derivatives == 1  # C^1: the step is C^-1, S adds 2


def test_damped_harmonic_step_response_is_the_papers_trajectory():
    # The damped harmonic trajectory of Sec. V, on the paper's plant: round-off agreement (cancellation in
    # the closed form itself is ~1e-16 of h).
    f = Smoother("damped_harmonic", T1, -SIGMA)
    r = step_response(Chain((f,)), H, 5e-4)
    expected = damped_harmonic_trajectory(r.time_s, H, T1, SIGMA)
    np.testing.assert_allclose(r.position, expected, rtol=0, atol=1e-15)
    np.testing.assert_allclose(r.derivative(1), H * f.impulse_response(r.time_s), rtol=0, atol=1e-13)


def truncated_power_chain(durations: list[float], h: float, t: np.ndarray, m: int) -> np.ndarray:
    """Sec. II by the binomial expansion of prod (1 - e^(-s T_i))/(s T_i): the m-th derivative of the step
    response is h/prod(T) sum_S (-1)^|S| (t - sum_S)_+^(n-m) / (n-m)!."""
    n = len(durations)
    total = np.zeros_like(t)
    for mask in range(2**n):
        shift = sum(d for i, d in enumerate(durations) if mask >> i & 1)
        sign = (-1) ** bin(mask).count("1")
        tau = np.clip(t - shift, 0.0, None)
        total += sign * (tau ** (n - m) if n > m else (t >= shift).astype(float)) / math.factorial(n - m)
    return h * total / math.prod(durations)


def test_rectangular_chain_is_the_exact_piecewise_polynomial():
    durations = [1.0, 0.5, 0.25]  # the acceptance chain for v = 1, a = 2, j = 8, h = 1 (eq. 2)
    chain = Chain(tuple(Smoother("rectangular", d) for d in durations))
    r = step_response(chain, 1.0, 0.01)
    command = r.command()
    assert command.degree == 3 and chain.is_polynomial
    dense = np.linspace(0, 1.75, 1999)
    for m in range(4):
        expected = truncated_power_chain(durations, 1.0, dense, m)
        if m == 3:  # right-continuous values; skip points that sit on a jump
            keep = (
                np.min(np.abs(dense[:, None] - np.array([0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 1.75])[None, :]), axis=1)
                > 1e-9
            )
            np.testing.assert_allclose(command.evaluate(3, dense)[keep], expected[keep], rtol=0, atol=1e-12)
        else:
            np.testing.assert_allclose(command.evaluate(m, dense), expected, rtol=0, atol=1e-12)
    # Eq. (3) holds, so the peaks are |h|/T1, |h|/(T1 T2), |h|/(T1 T2 T3) = 1, 2, 8 exactly.
    assert command.peak_abs(1) == pytest.approx(1.0, rel=1e-12)
    assert command.peak_abs(2) == pytest.approx(2.0, rel=1e-12)
    assert command.peak_abs(3) == pytest.approx(8.0, rel=1e-12)


def test_mixed_chain_equals_the_convolution_by_quadrature():
    # Rectangular + damped harmonic + exponential: y'(t) = h (f1 * f2 * f3)(t), checked by nested quadrature
    # of the closed-form impulse responses (an independent route, good to ~1e-10).
    f1, f2, f3 = Smoother("rectangular", 0.5), Smoother("damped_harmonic", 0.3, 4.0), Smoother("exponential", 0.2, 2.0)
    chain = Chain((f1, f2, f3))
    r = step_response(chain, 1.5, 0.01)

    def f23(t: float) -> float:
        lo, hi = max(0.0, t - f3.duration_s), min(t, f2.duration_s)
        if hi <= lo:
            return 0.0
        return integrate.quad(
            lambda u: float(f2.impulse_response(np.array(u)) * f3.impulse_response(np.array(t - u))),
            lo,
            hi,
            epsabs=1e-14,
            epsrel=1e-12,
        )[0]

    for t in (0.05, 0.31, 0.52, 0.77, 0.93):
        # f1 is 1/T1 on [0, T1]: (f1 * f23)(t) = (1/T1) int_{t - T1}^{t} f23
        lo, hi = max(0.0, t - f1.duration_s), min(t, f2.duration_s + f3.duration_s)
        expected = 1.5 / f1.duration_s * integrate.quad(f23, lo, hi, epsabs=1e-13, epsrel=1e-11, limit=200)[0]
        assert r.command().evaluate(1, np.array([t]))[0] == pytest.approx(expected, rel=1e-9, abs=1e-12)
    assert chain.continuous_derivatives == 3  # 1 + 2 + 1 - 1: C^3


def test_command_of_a_non_polynomial_chain_reproduces_the_trajectory_between_samples():
    # The degree-7 Taylor command from exact derivatives: between samples it stays within ~(Ts a)^8/8! of
    # the closed form (a few 1e-18 m here); 1e-15 m is round-off of the closed form itself.
    f = Smoother("damped_harmonic", T1, -SIGMA)
    command = step_response(Chain((f,)), H, 5e-4).command()
    dense = np.linspace(0, T1, 7777)
    np.testing.assert_allclose(
        command.evaluate(0, dense), damped_harmonic_trajectory(dense, H, T1, SIGMA), rtol=0, atol=1e-15
    )
    assert command.peak_abs(3) is None  # the acceleration jumps at 0 and T: the jerk is impulsive


@pytest.mark.parametrize(
    ("kind", "duration", "decay", "field"),
    [
        ("triangle", 1.0, 0.0, "type"),
        ("rectangular", -1.0, 0.0, "duration_s"),
        ("rectangular", float("nan"), 0.0, "duration_s"),
        ("harmonic", 1.0, 2.0, "decay_rate_1_s"),
        ("damped_harmonic", 10.0, 50.0, "decay_rate_1_s"),  # sigma T = 500: too close to zeta = 1
    ],
)
def test_bad_filters_are_refused(kind, duration, decay, field):
    with pytest.raises(InvalidParameter) as info:
        Smoother(kind, duration, decay)
    assert info.value.field == field


@pytest.mark.parametrize("rate", [1e-320, 5e-324 * 2.5e5])
def test_an_exponential_filter_with_a_subnormal_decay_rate_is_the_undamped_one(rate):
    """M_sigma(s) = phi((sigma - s) T) / phi(sigma T) tends to the rectangular filter's phi(-s T) as sigma -> 0
    (phi(z) = expm1(z)/z -> 1). A damping ratio near the smallest double gives a subnormal sigma T, where numpy's
    complex division overflowed (1e-320 / 1e-320 = inf + nan j): a NaN residual that let an infeasible move through
    (found by bench/fuzz.py, issue 23). Tolerance: the decay's own effect, |sigma| T, is below 1e-300."""
    s = np.array([POLE, 1j * OMEGA, -3.0 + 0j])
    damped = Smoother("exponential", T1, rate)
    undamped = Smoother("exponential", T1, 0.0)
    for f in ("frequency_response", "end_response"):
        assert np.allclose(getattr(damped, f)(s), getattr(undamped, f)(s), rtol=1e-14, atol=0), f
