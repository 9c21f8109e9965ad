"""Exact simulation: checked against an ODE integrator, lsim, closed forms and Incerti's eq. (31)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, signal

from models.commands import PiecewiseCommand
from models.metrics import metrics
from models.plants import BeltPlatformPlant, ModePlant, TransferFunctionPlant, TwoInertiaPlant, example_plants
from models.simulation import first_order_scan, simulate
from tests.oracle import ivp_response

PLANTS = {
    **example_plants(),
    "two_modes": TransferFunctionPlant((20611800.0,), (1.0, 9.92743, 21881.9, 34801.4, 20611800.0)),
    "damped_two_inertia": TwoInertiaPlant(0.01, 0.02, 50.0, 0.2),
}


def smooth_move(period_s: float, samples: int, uniform: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """An acceleration of one sine period lasting 1.7 plant periods, then rest.

    On the uniform grid the end of the move is a sample and the held acceleration integrates to
    zero velocity (a rest-to-rest move); the random grid leaves a small final velocity.
    """
    duration = 1.7 * period_s
    if uniform:
        t = np.linspace(0.0, 3 * duration, 3 * (samples // 3) + 1)
    else:
        rng = np.random.default_rng(samples)
        t = np.sort(np.concatenate([[0.0, 3 * duration], rng.uniform(0, 3 * duration, samples - 2)]))
    acc = np.where(t < duration, np.sin(2 * np.pi * t / duration), 0.0)
    return t, acc


@pytest.mark.parametrize("uniform", [True, False])
@pytest.mark.parametrize("name", sorted(PLANTS))
def test_matches_ode_integration(name, uniform):
    plant = PLANTS[name]
    period = plant.modes()[0].natural_period_s
    t, acc = smooth_move(period, 120, uniform)
    # A velocity-input plant gets a velocity command (held linearly), the others an acceleration.
    order = 1 if plant.command_input == "velocity" else 2
    values = np.cumsum(np.concatenate([[0.0], np.diff(t) * acc[:-1]])) if order == 1 else acc
    command = PiecewiseCommand.from_samples(t, values, order, initial=(0.3,))
    ours = simulate(plant, command)
    ref = ivp_response(plant, command)
    # DOP853 at rtol 1e-13 is good to ~1e-11 relative: 1e-9 leaves room and still catches any error
    # of the method (a wrong jump, residue or Taylor term shows up at 1e-3 or worse).
    scale = np.max(np.abs(ref["position"]))
    assert np.max(np.abs(ours.load_position - ref["position"])) <= 1e-9 * scale
    vscale = np.max(np.abs(ref["velocity"]))
    assert np.max(np.abs(ours.load_velocity - ref["velocity"])) <= 1e-9 * vscale


def test_matches_lsim_for_a_linearly_held_position():
    # lsim interpolates its input linearly, i.e. a first-order hold on the position.
    plant = PLANTS["incerti_table_iii"]
    t = np.linspace(0, 2, 2001)
    tau = np.clip(t, 0, 1)
    pos = 30 * np.pi * (10 * tau**3 - 15 * tau**4 + 6 * tau**5)
    ours = simulate(plant, PiecewiseCommand.from_samples(t, pos, 0))
    num, den = plant.load_transfer_function()
    _, y, _ = signal.lsim((num, den), pos, t)
    assert np.max(np.abs(ours.load_position - y)) <= 1e-12 * np.max(np.abs(y))


def test_undamped_mode_under_constant_acceleration_closed_form():
    # alpha'' + w^2 alpha = -a0 from rest: alpha = -(a0/w^2)(1 - cos w t).
    plant = ModePlant(3.0, 0.0)
    w = 2 * np.pi * 3.0
    t = np.linspace(0, 1.3, 40)
    a0 = 2.5
    response = simulate(plant, PiecewiseCommand.from_samples(t, np.full_like(t, a0), 2, hold="zero"))
    alpha = -(a0 / w**2) * (1 - np.cos(w * t))
    np.testing.assert_allclose(response.deflection, alpha, rtol=0, atol=1e-14)
    np.testing.assert_allclose(response.load_position, 0.5 * a0 * t**2 + alpha, rtol=0, atol=1e-13)


@pytest.mark.parametrize("zeta", [0.0, 0.05, 0.4])
def test_residual_amplitude_is_the_envelope_of_the_free_oscillation(zeta):
    # For one mode the free deflection after the end is A exp(-sigma t) cos(w_d t + phi), with
    # A = sqrt(alpha^2 + ((alpha' + sigma alpha)/w_d)^2) at the end: a closed form independent
    # of the modal decomposition.
    plant = ModePlant(2.0, zeta)
    mode = plant.modes()[0]
    t, acc = smooth_move(0.37, 400)
    response = simulate(plant, PiecewiseCommand.from_samples(t, acc, 2))
    m = metrics(response)
    end = response.command.end_index()
    alpha, rate = response.deflection[end], response.deflection_rate[end]
    envelope = math.hypot(alpha, (rate + mode.decay_rate_1_s * alpha) / mode.damped_frequency_rad_s)
    assert m.residual_amplitude == pytest.approx(envelope, rel=1e-10)
    assert m.residual_amplitude > 1e-4  # the test move does excite the mode
    # ...and the sampled free oscillation never exceeds it and reaches it within a period.
    after = response.time_s > response.time_s[end]
    decay = np.exp(-mode.decay_rate_1_s * (response.time_s[after] - response.time_s[end]))
    assert np.max(np.abs(response.deflection[after]) / decay) <= envelope * (1 + 1e-9)


def incerti_quintic(phi: float, duration: float) -> PiecewiseCommand:
    """The (3, 4, 5) polynomial of Table II as one exact polynomial piece, then rest."""
    c = np.array([10.0, -15.0, 6.0])  # phi(t) = Phi (10 s^3 - 15 s^4 + 6 s^5), s = t/T
    at_start = np.zeros(6)
    for coef, power in zip(c, (3, 4, 5), strict=True):
        at_start[power] = phi * coef * math.factorial(power) / duration**power
    at_end = np.zeros(6)
    at_end[0] = phi
    return PiecewiseCommand.from_derivatives(
        np.array([0.0, duration, 2 * duration]), np.column_stack([at_start, at_end, at_end])
    )


def test_incerti_residual_and_eq_31_energy():
    plant = PLANTS["incerti_table_iii"]
    assert isinstance(plant, BeltPlatformPlant)
    phi, duration = 30 * np.pi, 1.0
    response = simulate(plant, incerti_quintic(phi, duration))
    m = metrics(response)
    # PAPER-NOTES: residual platform vibration about 3.48e-3 rad for (3, 4, 5) and T = 1 s.
    assert m.residual_amplitude == pytest.approx(3.48e-3, rel=2e-3)
    # Eqs. (30)-(31) evaluated by quadrature: E = J/2 (lambda/w_d)^2 (G^2 + w_n^2 F^2).
    mode = plant.modes()[0]
    wn, wd, xi = mode.natural_frequency_rad_s, mode.damped_frequency_rad_s, mode.damping_ratio
    delta = math.atan(xi / math.sqrt(1 - xi**2))

    def acc(tau: float) -> float:
        s = tau / duration
        return phi / duration**2 * (60 * s - 180 * s**2 + 120 * s**3)

    f_int = integrate.quad(
        lambda x: acc(x) * math.exp(-xi * wn * (duration - x)) * math.sin(wd * (duration - x)),
        0,
        duration,
        epsabs=1e-11,
        epsrel=1e-11,
        limit=200,
    )[0]
    g_int = integrate.quad(
        lambda x: wn * acc(x) * math.exp(-xi * wn * (duration - x)) * math.cos(wd * (duration - x) + delta),
        0,
        duration,
        epsabs=1e-11,
        epsrel=1e-11,
        limit=200,
    )[0]
    lam = plant.transmission_ratio
    energy_eq31 = 0.5 * plant.platform_inertia_kgm2 * (lam / wd) ** 2 * (g_int**2 + wn**2 * f_int**2)
    assert m.final_energy_j == pytest.approx(energy_eq31, rel=1e-9)
    # The deflection alpha(T) of eq. (5) equals -lambda/w_d F.
    assert response.deflection[response.command.end_index()] == pytest.approx(-lam / wd * f_int, rel=1e-9)


def test_undamped_energy_equals_stiffness_times_amplitude_squared():
    plant = BeltPlatformPlant(6.0, 9e4, 0.0, 0.06, 0.18, 0.1)
    m = metrics(simulate(plant, incerti_quintic(30 * np.pi, 1.0)))
    assert m.final_energy_j == pytest.approx(
        0.5 * plant.equivalent_stiffness_nm_per_rad * m.residual_amplitude**2, rel=1e-10
    )


def test_settling_time_is_the_envelope_crossing():
    plant = ModePlant(2.0, 0.05)
    mode = plant.modes()[0]
    t, acc = smooth_move(0.37, 300)
    response = simulate(plant, PiecewiseCommand.from_samples(t, acc, 2))
    m = metrics(response, tolerance=1e-4)
    assert m.settling.quantity == "position"
    # The band: 1e-4 of the move, its net displacement (G(0) = 1) or its largest excursion if larger.
    net = abs(response.command.derivative(0)[-1] - response.load_position[0])
    band = 1e-4 * max(net, float(np.max(np.abs(response.load_position - response.load_position[0]))))
    assert m.settling.window == pytest.approx(band, rel=1e-6)
    expected = m.command_end_s + math.log(m.residual_amplitude / band) / mode.decay_rate_1_s
    assert m.settling.time_s == pytest.approx(expected, rel=1e-9)


def test_undamped_residual_never_settles():
    plant = ModePlant(2.0, 0.0)
    t, acc = smooth_move(0.37, 300)
    m = metrics(simulate(plant, PiecewiseCommand.from_samples(t, acc, 2)), tolerance=1e-6)
    assert m.settling.time_s is None


def test_velocity_move_settles_on_velocity():
    # Cusimano Sec. 3, k_j = 1 on a 40 Hz mode: zero residual, so the load settles when the command ends.
    plant = ModePlant(40.0, 0.0)
    t = np.array([0.0, 0.025, 0.15, 0.175, 0.3])
    m = metrics(simulate(plant, PiecewiseCommand.from_samples(t, np.array([0, 1000, 1000, 0, 0.0]), 2)))
    assert m.settling.quantity == "velocity"
    assert m.settling.time_s == pytest.approx(0.175, abs=1e-12)
    assert m.residual_velocity_amplitude < 1e-9 * 150
    assert m.peak_velocity == pytest.approx(150.0, rel=1e-14)
    assert m.peak_acceleration == pytest.approx(1000.0, rel=1e-14)
    assert m.peak_jerk == pytest.approx(1000 / 0.025, rel=1e-12)


def test_two_inertia_torque_from_the_shaft_equation():
    # Independent route: J_M a_M + k (th_M - th_L) + c (w_M - w_L), with th_L, w_L from the ODE.
    plant = PLANTS["damped_two_inertia"]
    assert isinstance(plant, TwoInertiaPlant)
    t, acc = smooth_move(plant.modes()[0].natural_period_s, 150)
    command = PiecewiseCommand.from_samples(t, acc, 2)
    ours = simulate(plant, command)
    ref = ivp_response(plant, command)
    torque = (
        plant.motor_inertia_kgm2 * command.derivative(2)
        + plant.stiffness_nm_per_rad * (command.derivative(0) - ref["position"])
        + plant.damping_nms_per_rad * (command.derivative(1) - ref["velocity"])
    )
    assert np.max(np.abs(ours.motor_torque_nm - torque)) <= 1e-8 * np.max(np.abs(torque))


def test_uniform_and_general_scans_agree():
    rng = np.random.default_rng(7)
    drive = rng.normal(size=5000) + 1j * rng.normal(size=5000)
    decay = np.full(4999, np.exp((-0.3 + 40j) * 1e-3))
    np.testing.assert_allclose(
        first_order_scan(decay, drive, True), first_order_scan(decay, drive, False), rtol=0, atol=1e-11
    )


def test_long_nonuniform_horizon_stays_finite_and_exact():
    # A stiff, well-damped fast pole over many time constants: the scan's products underflow to 0.
    plant = TransferFunctionPlant((1e6,), (1.0, 2500.0, 1e6))  # real poles at -500 and -2000 1/s
    rng = np.random.default_rng(11)
    t = np.sort(np.concatenate([[0.0, 0.05, 20.0], rng.uniform(0, 20, 3000)]))
    ramp = np.clip(t / 0.05, 0.0, 1.0)  # a position ramp to 1, held linearly: rest to rest
    response = simulate(plant, PiecewiseCommand.from_samples(t, ramp, 0))
    assert np.all(np.isfinite(response.load_position))
    # exp(-500 t) has long died out: the load sits exactly at G(0) times the final position.
    assert response.load_position[-1] == pytest.approx(1.0, rel=1e-13)
    assert metrics(response).residual_amplitude == 0.0  # no complex pole pair: no vibration mode


def test_out_and_back_move_settles_against_its_excursion():
    # A move that goes out and comes back has no net displacement: the band is then a fraction of
    # its largest excursion (here about 1), not of zero.
    t = np.linspace(0, 2, 201)
    out_and_back = np.where(t <= 1.0, np.sin(np.pi * t), 0.0)
    response = simulate(ModePlant(3.0, 0.05), PiecewiseCommand.from_samples(t, out_and_back, 0))
    m = metrics(response, tolerance=1e-3)
    excursion = float(np.max(np.abs(response.load_position)))
    assert m.settling.window == pytest.approx(1e-3 * excursion, rel=1e-12)
    assert m.settling.time_s is not None and m.settling.time_s < 10.0


# --- the fast recurrence (one real second-order lfilter per mode) against independent routes -------------


def _foh_per_step(plant, t: np.ndarray, position: np.ndarray) -> np.ndarray:
    """Load position by the exact first-order-hold discretisation of every step, each built on its own from
    one matrix exponential (``_foh_matrices``; shares nothing with ours but the plant's state space)."""
    ss = plant.state_space()
    x = -np.linalg.solve(ss.a, ss.b[:, 0]) * position[0]  # at rest at the first sample
    out = [float(ss.c[0] @ x + ss.d[0, 0] * position[0])]
    for k in range(t.size - 1):  # a loop over steps: this is the slow reference
        phi, gamma1, gamma2 = _foh_matrices(ss.a, ss.b, t[k + 1] - t[k])
        x = phi @ x + gamma1 * position[k] + gamma2 * position[k + 1]
        out.append(float(ss.c[0] @ x + ss.d[0, 0] * position[k + 1]))
    return np.array(out)


def _foh_matrices(a: np.ndarray, b: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Phi = e^(A h) and the first-order-hold input matrices from one matrix exponential of the block
    matrix [[A, B, 0], [0, 0, I/h], [0, 0, 0]] h (Franklin, Powell & Workman, Digital Control of Dynamic
    Systems, 3rd ed., Sec. 6.3.2): with E = expm(.), Phi = E11, G1 = E12, G2 = E13, and
    x_{k+1} = Phi x_k + (G1 - G2) u_k + G2 u_{k+1}."""
    from scipy.linalg import expm

    n = a.shape[0]
    block = np.zeros((n + 2, n + 2))
    block[:n, :n] = a * h
    block[:n, n] = b[:, 0] * h
    block[n, n + 1] = 1.0
    e = expm(block)
    phi, g1, g2 = e[:n, :n], e[:n, n], e[:n, n + 1]
    return phi, g1 - g2, g2


def test_100k_samples_agree_with_lsim_on_the_fast_path():
    # lsim holds its input linearly (a first-order hold on the position), so on the same samples it is the
    # same exact response; its own error is ~1e-14 here (the issue measured 1.5e-11 for a direct-form filter),
    # so 1e-9 of the motion (the acceptance) can only fail through a wrong recurrence, jump or initial state.
    plant = ModePlant(5.0, 0.05)
    t = np.linspace(0.0, 10.0, 100_000)
    rng = np.random.default_rng(5)
    acc = np.sin(2 * np.pi * 0.3 * t) * np.exp(-0.1 * t) + 0.05 * rng.normal(size=t.size)  # every step jumps
    position = np.array(PiecewiseCommand.from_samples(t, acc, 2).derivative(0))
    ours = simulate(plant, PiecewiseCommand.from_samples(t, position, 0))
    assert ours.free[0].s is not None  # the real second-order form ran (not the complex fallback)
    ss = plant.state_space()
    y = signal.lsim(signal.StateSpace(ss.a, ss.b, ss.c, ss.d), position, t)[1]
    assert np.max(np.abs(ours.load_position - y)) <= 1e-9 * np.max(np.abs(y))


def test_fast_path_equals_the_complex_recurrence_in_position_velocity_and_acceleration():
    # The complex first-order recurrence h_k = z h_(k-1) + J_k / p^2 (scipy lfilter on complex numbers,
    # the method of the module docstring) computed here on its own; the real second-order form must give
    # the same load motion. The real form's round-off, relative to the free response itself, is about
    # a few eps x the memory (6400 steps of decay) x |1 - z| / Im(z): 1e-12 to 1e-11 here (2e-11 measured on
    # the acceleration, all free response); 1e-10 of each quantity's own range leaves room for that and the
    # reference's own round-off, while a wrong coefficient, shift or initial state errs by 1e-4 or more.
    plant = ModePlant(5.0, 0.05)
    t = np.linspace(0.0, 10.0, 100_000)
    rng = np.random.default_rng(6)
    acc = np.sin(2 * np.pi * 0.3 * t) + 0.05 * rng.normal(size=t.size)
    position = np.array(PiecewiseCommand.from_samples(t, acc, 2).derivative(0))
    command = PiecewiseCommand.from_samples(t, position, 0)
    ours = simulate(plant, command)
    assert ours.free[0].s is not None
    num, den = plant.load_transfer_function()
    poles = np.roots(den)
    pole = poles[poles.imag > 0][0]
    residue = np.polyval(num, pole) / np.polyval(np.polyder(den), pole)
    jumps = command.jumps()
    drive = jumps[0] / pole + jumps[1] / pole**2
    h = signal.lfilter([1.0], [1.0, -np.exp(pole * (t[1] - t[0]))], drive)
    slope = command.derivative(1)
    # Quasi-static part: G(0) = 1 and G'(0) = (2 zeta w w^2 - w^2 2 zeta w) / w^4 = 0, so it is p (and p').
    expected = {
        "position": position + (2 * residue * h).real,
        "velocity": slope + (2 * residue * pole * h).real,
        "acceleration": (2 * residue * pole**2 * h).real,
    }
    for name, got in (
        ("position", ours.load_position),
        ("velocity", ours.load_velocity),
        ("acceleration", ours.load_acceleration),
    ):
        scale = np.max(np.abs(expected[name]))
        assert np.max(np.abs(got - expected[name])) <= 1e-10 * scale, name


@pytest.mark.parametrize(("frequency_hz", "zeta"), [(50.0, 0.02), (5.0, 0.0)])
def test_ramp_on_100k_samples_matches_its_closed_form(frequency_hz, zeta):
    # A position ramp v t from rest on G = (2 zeta w s + w^2)/(s^2 + 2 zeta w s + w^2): p - y has the
    # transform (1 - G) v / s^2 = v / (s^2 + 2 zeta w s + w^2), so y = v t - (v / w_d) e^(-zeta w t) sin(w_d t).
    # The undamped 5 Hz case keeps ringing over 100k steps: ours falls back to the complex recurrence there
    # (the real form's angle round-off would grow); the damped one runs the real form. 1e-10 of the move:
    # far above either's round-off (~1e-13), far below any error of the method.
    plant = ModePlant(frequency_hz, zeta)
    w = 2 * np.pi * frequency_hz
    wd = w * math.sqrt(1 - zeta**2)
    t = np.linspace(0.0, 2.0, 100_000)
    v = 3.0
    response = simulate(plant, PiecewiseCommand.from_samples(t, v * t, 0))
    expected = v * t - (v / wd) * np.exp(-zeta * w * t) * np.sin(wd * t)
    assert np.max(np.abs(response.load_position - expected)) <= 1e-10 * v * t[-1]
    expected_velocity = v - v * np.exp(-zeta * w * t) * (np.cos(wd * t) - zeta * w / wd * np.sin(wd * t))
    assert np.max(np.abs(response.load_velocity - expected_velocity)) <= 1e-10 * v
    assert (response.free[0].s is not None) == (zeta > 0.0)


def test_uneven_steps_agree_with_an_exact_discretisation_of_every_step():
    # On a jittered grid each step has its own decay; the reference discretises every step on its own with
    # one matrix exponential (Franklin, Powell & Workman), a route that shares nothing with ours. Both are
    # exact for the linearly held position: 1e-10 of the motion leaves room for the reference's round-off
    # (expm per step, 3000 steps) and catches any wrong step, jump or decay.
    plant = ModePlant(7.0, 0.03)
    rng = np.random.default_rng(9)
    t = np.linspace(0.0, 3.0, 3000)
    t[1:-1] += rng.uniform(-0.4, 0.4, t.size - 2) * (t[1] - t[0])
    position = np.sin(2 * np.pi * 0.7 * t) + 0.01 * rng.normal(size=t.size)
    ours = simulate(plant, PiecewiseCommand.from_samples(t, position, 0))
    assert not ours.command.is_uniform
    reference = _foh_per_step(plant, t, position)
    assert np.max(np.abs(ours.load_position - reference)) <= 1e-10 * np.max(np.abs(reference))
