"""What a response says about the move: the load's residual per mode, its settling (position band and vibration
envelope) and the peaks (metrics), from models.simulation's exact response."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from models.simulation import Response


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
        coefficient = float(np.sum(weighted * modal.pole_term(m)[osc]).real)
        quasi_static += coefficient * der[m + order]
    envelope: NDArray[np.float64] = np.sum(free, axis=0) + np.abs(quasi_static)
    return envelope


def settling(
    response: Response,
    tolerance: float = 1e-3,
    window: float | None = None,
    vibration_window: float | None = None,
    vibration_fraction: float | None = None,
    free_from: int | None = None,
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
    is left ringing above a band. ``free_from``: the sample from which the response is free and linear, if later
    than the command's end (a drive that saturates after it, models.servo_limits).
    """
    end = free_from if free_from is not None else response.command.end_index()
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
    free_from: int | None = None,
) -> Metrics:
    """Residual vibration, energy, settling and peaks of a simulated command; the residual is the free vibration
    from the command's end, or from ``free_from`` (``settling``)."""
    command_end = response.command.end_index()
    end = free_from if free_from is not None else command_end
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
        command_end_s=float(cmd.time_s[command_end]),
        residual_amplitude=float(np.sum(pos_amp[osc])),
        residual_velocity_amplitude=float(np.sum(vel_amp[osc])),
        modes=modes,
        final_energy_j=None if energy is None else float(energy),
        settling=settling(response, tolerance, window, vibration_window, vibration_fraction, free_from),
        peak_velocity=cmd.peak_abs(1, command_end),  # the command's own span: after its end it continues its motion
        peak_acceleration=cmd.peak_abs(2, command_end),
        peak_jerk=cmd.peak_abs(3, command_end),
        peak_motor_torque_nm=None if torque is None else float(np.max(np.abs(torque))),
    )
