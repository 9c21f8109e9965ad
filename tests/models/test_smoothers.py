"""Smoother filters (Biagiotti et al. 2020): transfer functions, step responses, residuals, eq. (17).

Independent references: quadrature of the impulse response (Laplace transform, convolution),
scipy.signal.freqresp of the rational part, the paper's closed-form trajectories, an ODE integration of
the plant driven by the closed-form trajectory, and z-transforms evaluated by hand.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, signal

from models.commands import PiecewiseCommand
from models.errors import InvalidParameter
from models.metrics import metrics
from models.plants import ModePlant, TwoInertiaPlant
from models.simulation import simulate
from models.smoothers import (
    Chain,
    Smoother,
    discrete_filter,
    discrete_step_response,
    mode_residuals,
    refinement,
    residual_fraction,
    step_response,
)

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


def test_discrete_filter_is_eq_17_with_unit_dc_gain():
    # Eq. (17) at Ts = 0.5 ms and N = round(153.6) = 154, written out by hand.
    f = Smoother("damped_harmonic", T1, -SIGMA)
    ts, n = 5e-4, 154
    d = discrete_filter(f, ts, n)
    r = math.exp(SIGMA * ts)
    k = (1 - 2 * r * math.cos(math.pi / n) + r * r) / (1 + math.exp(SIGMA * n * ts))
    assert d.gain == pytest.approx(k, rel=1e-14)
    np.testing.assert_allclose(d.denominator, [1, -2 * r * math.cos(math.pi / n), r * r], rtol=1e-15)
    assert d.numerator[1] == 1.0 and d.numerator[n + 1] == pytest.approx(math.exp(SIGMA * n * ts), rel=1e-14)
    assert np.count_nonzero(d.numerator) == 2
    # Unit static gain: H(1) = K (1 + e^(sigma N Ts)) / den(1) = 1.
    assert d.gain * np.sum(d.numerator) / np.sum(d.denominator) == pytest.approx(1.0, rel=1e-13)
    # Its impulse response is the continuous one (eq. 14) sampled at k Ts, k = 1..N, up to a constant
    # (the filter it samples lasts N Ts; here N Ts = 0.077 s).
    impulse = d.filter(np.r_[1.0, np.zeros(n + 5)])
    samples = Smoother("damped_harmonic", n * ts, -SIGMA).impulse_response(ts * np.arange(n + 6))
    ratio = impulse[1:n] / samples[1:n]
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-9)
    # FIR: nothing after N. The recursive form cancels its poles with zeros exactly in exact arithmetic; in
    # doubles a tail of ~1e-13 of the peak is left (measured 1.0e-13), decaying as e^(sigma k Ts).
    assert np.max(np.abs(impulse[n:])) < 1e-12 * np.max(impulse)


@pytest.mark.parametrize("kind", ["rectangular", "harmonic", "damped_harmonic", "exponential"])
def test_discrete_filters_have_unit_dc_gain_and_end(kind):
    f = Smoother(kind, 0.3, 4.0 if kind in ("damped_harmonic", "exponential") else 0.0)
    d = discrete_filter(f, 0.01, 30)
    assert d.transfer(np.array([1.0 + 0j]))[0] == pytest.approx(1.0, rel=1e-13)
    y = discrete_step_response([d], 2.0, 40)
    assert y[30:] == pytest.approx(2.0, rel=1e-13)  # at rest after N samples


@pytest.mark.parametrize("n", [154, 1540])
def test_sinusoidal_discrete_filter_follows_within_half_a_sample(n):
    # Acceptance: with N Ts = T, eq. (17)'s output equals the continuous trajectory half a sample later to
    # O(Ts^2) (midpoint rule: measured 1.08 (Ts/T)^2 of h), while at the sample itself it is O(Ts) off.
    f = Smoother("damped_harmonic", T1, -SIGMA)
    ts = T1 / n
    y = discrete_step_response([discrete_filter(f, ts, n)], H, n + 3)
    t = ts * np.arange(n + 3)
    lead = np.max(np.abs(y - damped_harmonic_trajectory(t + ts / 2, H, T1, SIGMA)))
    at_sample = np.max(np.abs(y - damped_harmonic_trajectory(t, H, T1, SIGMA)))
    assert lead <= 2.0 * (ts / T1) ** 2 * H
    assert at_sample > 50 * lead
    # The best time shift lies within half a sample of the sample time (and at about half a sample).
    shifts = np.linspace(0.0, 1.0, 201)
    errors = [np.max(np.abs(y - damped_harmonic_trajectory(t + s * ts, H, T1, SIGMA))) for s in shifts]
    assert 0.45 <= shifts[int(np.argmin(errors))] <= 0.55


def test_rounding_n_detunes_by_the_papers_figure():
    # PAPER-NOTES: N = round(153.6) = 154 leaves about 0.27 % of the unfiltered residual. The ratio of the
    # envelopes at the same time is |D(e^(p Ts))| (z-transform at the plant's pole).
    f = Smoother("damped_harmonic", T1, -SIGMA)
    ts = 5e-4
    d = discrete_filter(f, ts, round(T1 / ts))
    z = np.exp(POLE * ts)
    ratio = abs(d.transfer(np.array([z]))[0])
    assert ratio == pytest.approx(0.0027, rel=0.01)
    # The same by simulation: the discrete output held linearly, driving the plant. With the step, the linear
    # hold turns h/s into h D(z) (2 cosh(p Ts) - 2)/(Ts p^2 (1 - 1/z)) = (h/s) D(z) (e^(p Ts) - 1)/(p Ts), and
    # the free vibration is read at the last change, k = N (closed form vs recurrence: round-off agreement).
    count = d.samples + 1
    y = discrete_step_response([d], H, count)
    y[-1] = H
    t = ts * np.arange(count)
    simulated = metrics(simulate(PLANT, PiecewiseCommand.from_samples(t, y, 0))).residual_amplitude
    hold = abs(np.expm1(POLE * ts) / (POLE * ts))
    expected = H * OMEGA_N / OMEGA * ratio * hold * math.exp(SIGMA * t[-1])
    assert simulated == pytest.approx(expected, rel=1e-9)
    # At Ts = T/N the zeros are on the pole again.
    exact = discrete_filter(f, T1 / 154, 154)
    assert abs(exact.transfer(np.array([np.exp(POLE * T1 / 154)]))[0]) < 1e-12


def test_a_cubic_hold_of_position_and_velocity_samples_keeps_the_cancellation():
    # The returned samples alone, as a cam table with velocity feed-forward reads them (cubic Hermite through
    # position and velocity, both continuous for S_sigma): 1.2e-12 of h at the paper's 0.5 ms, 3.5e-11 at 1 ms
    # (measured). A cubic hold of velocity with acceleration cannot: the acceleration jumps at T (3.3e-6).
    f = Smoother("damped_harmonic", T1, -SIGMA)
    for ts in (5e-4, 1e-3):
        r = step_response(Chain((f,)), H, ts)
        held = PiecewiseCommand.from_samples(r.time_s, r.position, 0, hold="cubic", slopes=r.derivative(1))
        assert metrics(simulate(PLANT, held)).residual_amplitude < 1e-9 * H
    r = step_response(Chain((f,)), H, 5e-4)
    held = PiecewiseCommand.from_samples(r.time_s, r.derivative(1), 1, hold="cubic", slopes=r.derivative(2))
    assert metrics(simulate(PLANT, held)).residual_amplitude > 1e-7 * H


def test_a_linear_hold_on_velocity_samples_is_vibration_free_when_t_is_a_whole_number_of_samples():
    # The held velocity's transform is the sampled impulse response's z-transform (eq. 17's), so a grid with
    # T = N Ts cancels the mode (measured 3e-16 of h); at Ts = 0.5 ms (T/Ts = 153.6) it leaves ~6e-8 of h.
    f = Smoother("damped_harmonic", T1, -SIGMA)
    for ts, bound in ((T1 / 154, 1e-12), (5e-4, 1e-6)):
        r = step_response(Chain((f,)), H, ts)
        held = PiecewiseCommand.from_samples(r.time_s, r.derivative(1), 1)
        residual = metrics(simulate(PLANT, held)).residual_amplitude / H
        assert residual < bound
        if ts == 5e-4:
            assert residual > 1e-9  # the off-grid end costs something: the figure is real, not round-off


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
