"""Exact, vectorised response of a plant to a piecewise-polynomial motor command.

Method. Write the load transfer function (motor position -> load position) in partial fractions,
G(s) = D + sum_j r_j / (s - lambda_j), so that y = D p + sum_j r_j x_j with x_j' = lambda_j x_j + p.
While the command p is a polynomial, x_j has the particular solution
x_j,p = -sum_m p^(m) / lambda_j^(m+1), and the load follows the quasi-static motion
y_p = sum_m g_m p^(m), where g_m are the Taylor coefficients of G at s = 0. What is left,
h_j = x_j - x_j,p, is a free response: it decays as exp(lambda_j t) and jumps by
sum_m [p^(m)] / lambda_j^(m+1) wherever a derivative of the command jumps. So

    y(t_k) = sum_m g_m p^(m)(t_k) + Re sum_j w_j r_j h_j(t_k),
    h_j(t_k) = exp(lambda_j (t_k - t_{k-1})) h_j(t_{k-1}) + jump_j(t_k),

which is exact for piecewise-polynomial commands and needs only one first-order recurrence per
pole: ``scipy.signal.lfilter`` on a uniform grid, a log-depth associative scan otherwise (no
Python loop over samples). At the end of the command, h_j is the state of the load's free
oscillation, from which the residual envelope, energy and settling time follow in closed form.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import lfilter

from models.commands import PiecewiseCommand
from models.errors import InvalidParameter
from models.plants import Plant

_REAL_POLE_TOLERANCE = 1e-12
_RELIABLE_RELATIVE = 1e-6  # largest round-off accepted, relative to the load's motion


@dataclass(frozen=True)
class ModalForm:
    """G(s) = sum_m taylor[m] s^m near 0, and sum over poles of weights * residues / (s - pole).

    One entry per real pole or per complex pair (the pole with Im > 0, weight 2).
    """

    taylor: NDArray[np.float64]
    poles: NDArray[np.complex128]
    residues: NDArray[np.complex128]
    weights: NDArray[np.float64]

    @property
    def oscillatory(self) -> NDArray[np.bool_]:
        pairs: NDArray[np.bool_] = self.weights == 2.0
        return pairs


def taylor_coefficients(num: ArrayLike, den: ArrayLike, count: int) -> NDArray[np.float64]:
    """First ``count`` Taylor coefficients of num(s)/den(s) at s = 0 (series division)."""
    n_asc = np.zeros(count)
    tail = np.asarray(num, dtype=float)[::-1][:count]
    n_asc[: tail.size] = tail
    d_asc = np.asarray(den, dtype=float)[::-1]
    g = np.zeros(count)
    for m in range(count):  # a loop over series terms (a handful), not samples
        acc = n_asc[m]
        for i in range(1, min(m, d_asc.size - 1) + 1):
            acc -= d_asc[i] * g[m - i]
        g[m] = acc / d_asc[0]
    return g


def modal_form(num: NDArray[np.float64], den: NDArray[np.float64], taylor_count: int) -> ModalForm:
    """Partial fractions of a proper transfer function with simple poles off the origin."""
    poles = np.roots(den).astype(complex)
    keep = poles.imag >= -_REAL_POLE_TOLERANCE * np.abs(poles)
    poles = poles[keep]
    real = np.abs(poles.imag) <= _REAL_POLE_TOLERANCE * np.abs(poles)
    poles = np.where(real, poles.real + 0j, poles)
    # A pole on the imaginary axis may come out with a round-off real part of either sign.
    poles = np.where(poles.real > 0.0, 1j * poles.imag, poles)
    # numpy's stubs type polyval at complex points as real: the annotations say what they are.
    at_num: NDArray[np.complex128] = np.polyval(num, poles)
    at_derivative: NDArray[np.complex128] = np.polyval(np.polyder(den), poles)
    residues = at_num / at_derivative
    residues = np.where(real, residues.real + 0j, residues)
    weights = np.where(real, 1.0, 2.0)
    return ModalForm(taylor_coefficients(num, den, taylor_count), poles, residues, weights)


def first_order_scan(
    decay: NDArray[np.complex128], drive: NDArray[np.complex128], uniform: bool
) -> NDArray[np.complex128]:
    """h_0 = drive_0, h_k = decay_{k-1} h_{k-1} + drive_k, vectorised.

    ``decay`` has one entry per step (len(drive) - 1). On a uniform grid this is one
    ``lfilter`` call; otherwise a Hillis-Steele scan with log2(N) vectorised passes. Every
    |decay| <= 1, so the scan's products only shrink and cannot overflow.
    """
    if uniform:
        filtered: NDArray[np.complex128] = lfilter([1.0], [1.0, -decay[0]], drive)
        return filtered
    a = np.concatenate(([0.0 + 0j], decay))
    h = drive.astype(complex, copy=True)
    shift = 1
    while shift < h.size:
        h[shift:] = h[shift:] + a[shift:] * h[:-shift]
        a[shift:] = a[shift:] * a[:-shift]
        shift *= 2
    return h


@dataclass(frozen=True)
class Response:
    """The load's motion at the command's breakpoints (right-hand values) and its free state."""

    plant: Plant
    command: PiecewiseCommand
    modal: ModalForm
    load_position: NDArray[np.float64]
    load_velocity: NDArray[np.float64]
    load_acceleration: NDArray[np.float64]
    free_state: NDArray[np.complex128]  # h_j at every breakpoint, shape (poles, samples)

    @property
    def time_s(self) -> NDArray[np.float64]:
        return self.command.time_s

    @property
    def has_deflection(self) -> bool:
        return self.plant.command_input == "position"

    @property
    def deflection(self) -> NDArray[np.float64] | None:
        """Load position minus its rigid-transmission value G(0) p (Incerti's alpha)."""
        if not self.has_deflection:
            return None
        return self.load_position - self.plant.dc_gain * self.command.derivative(0)

    @property
    def deflection_rate(self) -> NDArray[np.float64] | None:
        if not self.has_deflection:
            return None
        return self.load_velocity - self.plant.dc_gain * self.command.derivative(1)

    @property
    def motor_torque_nm(self) -> NDArray[np.float64] | None:
        """J_M th_M'' + J_L th_L'' where the plant defines both inertias."""
        inertias = self.plant.torque_inertias()
        if inertias is None:
            return None
        j_m, j_l = inertias
        return j_m * self.command.derivative(2) + j_l * self.load_acceleration

    def free_amplitudes(self, index: int, derivative: int = 0) -> NDArray[np.float64]:
        """|w_j r_j lambda_j^d h_j|: amplitude of each pole's free response at a breakpoint."""
        m = self.modal
        amplitudes: NDArray[np.float64] = np.abs(
            m.weights * m.residues * m.poles**derivative * self.free_state[:, index]
        )
        return amplitudes


def simulate(plant: Plant, command: PiecewiseCommand) -> Response:
    """The exact response of ``plant`` to ``command`` (see the module docstring)."""
    num, den = plant.load_transfer_function()
    degree = command.degree
    modal = modal_form(num, den, degree + 1)
    g = modal.taylor
    der = command.derivatives
    position = g[: degree + 1] @ der  # quasi-static motion: sum_m g_m p^(m)
    velocity = g[:degree] @ der[1:]
    acceleration = g[: max(degree - 1, 0)] @ der[2:] if degree >= 2 else np.zeros_like(position)

    jumps = command.jumps()
    steps = command.steps_s
    uniform = command.is_uniform
    active = np.flatnonzero(np.any(jumps != 0.0, axis=1))  # orders whose jumps excite the plant
    free = np.zeros((modal.poles.size, command.time_s.size), dtype=complex)
    weighted = modal.weights * modal.residues
    for j, pole in enumerate(modal.poles):  # a loop over poles, not samples
        if active.size == 0:
            break
        drive = sum(jumps[m] * pole ** -(m + 1) for m in active)
        decay = np.exp(pole * (steps[:1] if uniform else steps))
        free[j] = first_order_scan(decay, drive, uniform)
        real, imag = free[j].real, free[j].imag
        for k, out in enumerate((position, velocity, acceleration)):
            c = weighted[j] * pole**k  # Re(c h) without forming the complex product
            out += c.real * real - c.imag * imag
    for name, arr in (("load position", position), ("load velocity", velocity), ("load acceleration", acceleration)):
        if not np.all(np.isfinite(arr)):
            raise InvalidParameter("profile", "out of range", f"the {name} overflows double precision")
    _check_conditioning(command, modal, free, position)
    return Response(plant, command, modal, position, velocity, acceleration, free)


def _check_conditioning(
    command: PiecewiseCommand, modal: ModalForm, free: NDArray[np.complex128], position: NDArray[np.float64]
) -> None:
    """Refuse a result that round-off could have spoilt.

    The load position is the sum of the quasi-static part sum_m g_m p^(m) and the free responses;
    when a mode is very slow next to how fast the command changes, both are huge (1/lambda^(m+1))
    and cancel, and the sum keeps only eps times their size of accuracy.
    """
    eps = np.finfo(float).eps
    size = sum(abs(g) * float(np.max(np.abs(command.derivative(m)))) for m, g in enumerate(modal.taylor))
    size += float(np.sum(np.abs(modal.weights * modal.residues) * np.max(np.abs(free), axis=1))) if free.size else 0.0
    scale = max(
        float(np.max(np.abs(position))), abs(modal.taylor[0]) * float(np.max(np.abs(command.derivative(0)))), 1e-300
    )
    if 16 * eps * size > _RELIABLE_RELATIVE * scale:
        slowest = float(np.min(np.abs(modal.poles))) / (2 * np.pi)
        raise InvalidParameter(
            "plant",
            f"{slowest:.3g} Hz",
            f"the slowest pole ({slowest:.3g} Hz) is too slow for how fast this command changes: round-off would "
            f"reach {16 * eps * size / scale:.1e} of the motion; sample a slower command or check the plant",
        )


# ------------------------------------------------------------------------------------------
# Metrics


@dataclass(frozen=True)
class ModeResidual:
    natural_frequency_hz: float
    damping_ratio: float
    residual_amplitude: float
    residual_velocity_amplitude: float


@dataclass(frozen=True)
class Settling:
    quantity: str  # "position" or "velocity": what is compared with its steady-state value
    window: float  # half-width of the position band, in the load's units of that quantity
    time_s: float | None  # from the start of the command; None when it never settles
    vibration_window: float | None = None  # bound on the free-vibration envelope (None: not checked)


@dataclass(frozen=True)
class Metrics:
    command_end_s: float
    residual_amplitude: float
    residual_velocity_amplitude: float
    modes: tuple[ModeResidual, ...]
    final_energy_j: float | None
    settling: Settling
    peak_velocity: float | None  # None where the quantity is impulsive (its integral jumps)
    peak_acceleration: float | None
    peak_jerk: float | None
    peak_motor_torque_nm: float | None


def _steady_state(response: Response, end: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Load position and velocity of the steady motion that follows the command's last piece.

    With the last piece p(t_e + tau) = sum_n D_n tau^n / n!, the quasi-static load motion
    sum_m g_m p^(m) is the polynomial sum_j c_j tau^j with c_j = sum_m g_m D_(m+j) / j!.
    """
    cmd = response.command
    g = response.modal.taylor
    last = cmd.derivatives[:, end]
    d = cmd.degree
    coeffs = np.array([sum(g[m] * last[m + j] for m in range(d + 1 - j)) / math.factorial(j) for j in range(d + 1)])
    tau = cmd.time_s - cmd.time_s[end]
    position = np.polyval(coeffs[::-1], tau)
    velocity = np.polyval((coeffs[1:] * np.arange(1, d + 1))[::-1], tau) if d else np.zeros_like(tau)
    return position, velocity


UNDAMPED_DAMPING_RATIO = 1e-8  # a pole with -Re/|p| below this is undamped (its real part is round-off)


def _envelope_crossing_s(amplitudes: NDArray[np.float64], poles: NDArray[np.complex128], window: float) -> float | None:
    """Smallest t >= 0 with sum_j A_j exp(Re(p_j) t) <= window; None if never (an undamped pole
    carries more than the window)."""
    if np.sum(amplitudes) <= window:
        return 0.0
    decay_1_s = -poles.real
    still = decay_1_s <= UNDAMPED_DAMPING_RATIO * np.abs(poles)
    floor = float(np.sum(amplitudes[still]))
    if floor >= window:
        return None
    live = ~still & (amplitudes > 0.0)
    budget = (window - floor) / max(1, int(np.count_nonzero(live)))
    upper = float(np.max(np.log(amplitudes[live] / budget) / decay_1_s[live]))
    lower = 0.0
    for _ in range(200):  # bisection on one scalar
        mid = 0.5 * (lower + upper)
        if floor + np.sum(amplitudes[live] * np.exp(-decay_1_s[live] * mid)) > window:
            lower = mid
        else:
            upper = mid
        if upper - lower <= 1e-12 * max(1.0, upper):
            break
    return upper


def vibration_envelope(response: Response, order: int) -> NDArray[np.float64]:
    """At every breakpoint, the amplitude of the load's vibration about its rigid motion: the sum of
    the oscillatory free responses' amplitudes |w r p^order h| plus the quasi-static deflection of the
    oscillatory modes, Re sum_osc w r (-sum_(m>=1) p^(m+order) / p_j^(m+1)) (the elastic lag a moving
    command holds, -a / w^2 on one mode; real poles and the rigid part are no vibration). After the
    command's end it is the exact envelope of the free vibration."""
    modal = response.modal
    osc = modal.oscillatory
    weighted = (modal.weights * modal.residues)[osc]
    poles = modal.poles[osc]
    free = np.abs((weighted * poles**order)[:, None] * response.free_state[osc])
    der = response.command.derivatives
    quasi_static = np.zeros_like(der[0])
    for m in range(1, der.shape[0] - order):  # a loop over derivative orders (a handful)
        coefficient = float(np.sum(-(weighted / poles ** (m + 1))).real)
        quasi_static += coefficient * der[m + order]
    envelope: NDArray[np.float64] = np.sum(free, axis=0) + np.abs(quasi_static)
    return envelope


def settling(
    response: Response,
    tolerance: float = 1e-3,
    window: float | None = None,
    vibration_window: float | None = None,
    vibration_fraction: float | None = None,
) -> Settling:
    """The earliest time after which the load stays within its band for ever.

    Two criteria hold from then on: |load - steady motion| <= ``window`` (absolute, load units; default
    ``tolerance`` times the move: the load's total displacement, or its largest excursion if larger,
    when it ends at rest; its final speed when it ends moving, and then velocities are compared),
    and, when ``vibration_window`` is given (or ``vibration_fraction`` of the move), the vibration envelope
    (``vibration_envelope``) <= it.
    During the command both are checked at the samples; after its end the exact closed-form envelope
    of the free response is used, so the answer does not depend on the horizon. It can be earlier
    than the command's end when the last changes are within both bands. None when an undamped mode
    is left ringing above a band.
    """
    end = response.command.end_index()
    t = response.time_s
    ss_pos, ss_vel = _steady_state(response, end)
    moving = abs(ss_vel[end]) > 1e-9 * max(1.0, float(np.max(np.abs(response.load_velocity))))
    if moving:
        quantity, error, scale, order = "velocity", response.load_velocity - ss_vel, abs(ss_vel[end]), 1
    else:
        quantity, error = "position", response.load_position - ss_pos
        # The move: its net displacement, or its largest excursion for an out-and-back move.
        excursion = float(np.max(np.abs(response.load_position - response.load_position[0])))
        scale, order = max(abs(ss_pos[end] - response.load_position[0]), excursion), 0
    band = window if window is not None else tolerance * scale
    if vibration_window is None and vibration_fraction is not None:
        vibration_window = vibration_fraction * scale
    if band <= 0.0 or (vibration_window is not None and vibration_window <= 0.0):
        return Settling(quantity, band, None, vibration_window)
    poles = response.modal.poles
    amplitudes = response.free_amplitudes(end, order)
    if not np.any(response.modal.oscillatory):
        vibration_window = None  # nothing vibrates: the position band alone decides
    after = _envelope_crossing_s(amplitudes, poles, band)
    outside = np.abs(error[:end]) > band
    if vibration_window is not None:
        osc = response.modal.oscillatory
        after_vibration = _envelope_crossing_s(amplitudes[osc], poles[osc], vibration_window)
        after = None if after is None or after_vibration is None else max(after, after_vibration)
        outside |= vibration_envelope(response, order)[:end] > vibration_window
    if after is None:
        return Settling(quantity, band, None, vibration_window)
    if after > 0.0:
        return Settling(quantity, band, float(t[end] + after - t[0]), vibration_window)
    last = np.flatnonzero(outside)
    during = t[last[-1] + 1] if last.size else t[0]
    return Settling(quantity, band, float(during - t[0]), vibration_window)


def metrics(
    response: Response,
    tolerance: float = 1e-3,
    window: float | None = None,
    vibration_window: float | None = None,
    vibration_fraction: float | None = None,
) -> Metrics:
    """Residual vibration, energy, settling and peaks of a simulated command."""
    end = response.command.end_index()
    modal = response.modal
    pos_amp = response.free_amplitudes(end, 0)
    vel_amp = response.free_amplitudes(end, 1)
    osc = modal.oscillatory
    modes = tuple(
        ModeResidual(float(abs(p) / (2 * np.pi)), float(-p.real / abs(p)), float(a), float(v))
        for p, a, v in zip(modal.poles[osc], pos_amp[osc], vel_amp[osc], strict=True)
    )
    energy = None
    plant = response.plant
    deflection, deflection_rate = response.deflection, response.deflection_rate
    # Every kind with energy data takes the motor position, so it has a deflection.
    if (
        plant.energy_inertia is not None
        and plant.energy_stiffness is not None
        and deflection is not None
        and deflection_rate is not None
    ):
        alpha = deflection[end]
        rate = deflection_rate[end]
        energy = 0.5 * plant.energy_inertia * rate**2 + 0.5 * plant.energy_stiffness * alpha**2
    torque = response.motor_torque_nm
    cmd = response.command
    return Metrics(
        command_end_s=float(cmd.time_s[end]),
        residual_amplitude=float(np.sum(pos_amp[osc])),
        residual_velocity_amplitude=float(np.sum(vel_amp[osc])),
        modes=modes,
        final_energy_j=None if energy is None else float(energy),
        settling=settling(response, tolerance, window, vibration_window, vibration_fraction),
        peak_velocity=cmd.peak_abs(1),
        peak_acceleration=cmd.peak_abs(2),
        peak_jerk=cmd.peak_abs(3),
        peak_motor_torque_nm=None if torque is None else float(np.max(np.abs(torque))),
    )
