"""Discrete smoothers (Biagiotti et al. 2020, eq. 17): unit DC gain, the paper's detuning, holds of their samples."""

from __future__ import annotations

import math

import numpy as np
import pytest

from models.commands import PiecewiseCommand
from models.metrics import metrics
from models.simulation import simulate
from models.smoothers import Chain, Smoother, discrete_filter, discrete_step_response, step_response
from tests.models.test_smoothers import OMEGA, OMEGA_N, PLANT, POLE, SIGMA, T1, H, damped_harmonic_trajectory


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
