"""A mode whose natural frequency and damping ratio change while the motor moves (a plant that depends on a
position): the load's deflection e = load - motor of a spring and damper whose parameters follow a coordinate,

    e'' + 2 zeta(t) w(t) e' + w(t)^2 e = -motor''(t),

integrated by scipy's DOP853 at a relative tolerance of 1e-12, piece by piece between the command's
breakpoints (where motor'' may jump). A linear time-varying system has no closed form; this is the reference the
programs' stops are checked against (optim.programs), independent of the time-invariant designs and their
simulation (models.simulation). With w and zeta constant it is the ``mode`` plant's exact response, which the
tests hold it to.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from models.commands import PiecewiseCommand

RTOL = 1e-12
MAX_EVALUATIONS = 20_000_000  # right-hand sides per call, at most (a bound in work: about a minute)

ModeOfTime = Callable[[float], tuple[float, float]]  # t -> (w rad/s, zeta)


@dataclass(frozen=True)
class Deflection:
    """The deflection e and its rate at the instants asked (from rest at the first), and the work it took."""

    time_s: NDArray[np.float64]
    deflection: NDArray[np.float64]
    rate: NDArray[np.float64]
    evaluations: int


def free_amplitude(
    deflection: NDArray[np.float64],
    rate: NDArray[np.float64],
    omega_rad_s: NDArray[np.float64],
    zeta: NDArray[np.float64],
) -> NDArray[np.float64]:
    """The amplitude of the free vibration from (e, e') on a mode (w, zeta) that no longer changes:
    sqrt(A^2 + B^2) for e = exp(-zeta w t)(A cos w_d t + B sin w_d t), A = e, B = (e' + zeta w e) / w_d."""
    damped = omega_rad_s * np.sqrt(1.0 - zeta * zeta)
    return np.asarray(np.hypot(deflection, (rate + zeta * omega_rad_s * deflection) / damped), dtype=float)


def free_states(
    state: NDArray[np.float64], omega_rad_s: float, zeta: float, dt_s: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(e, e') a time dt after (e0, e0') = ``state`` on a mode that does not change and a motor at rest: the free
    damped vibration, e = exp(-sigma t)(A cos w_d t + B sin w_d t), in closed form (shape (2, dt.size))."""
    sigma = zeta * omega_rad_s
    damped = omega_rad_s * math.sqrt(1.0 - zeta * zeta)
    a, b = state[0], (state[1] + sigma * state[0]) / damped
    decay, c, s = np.exp(-sigma * dt_s), np.cos(damped * dt_s), np.sin(damped * dt_s)
    e = decay * (a * c + b * s)
    rate = decay * ((b * damped - sigma * a) * c - (a * damped + sigma * b) * s)
    return np.vstack((e, rate))


def deflection(
    command: PiecewiseCommand,
    mode_of_time: ModeOfTime,
    time_s: NDArray[np.float64],
    breaks_s: NDArray[np.float64],
    still_s: tuple[tuple[float, float], ...] = (),
) -> Deflection:
    """The deflection at the instants ``time_s`` (increasing) of the mode driven by ``command``, from rest at
    ``time_s[0]`` (the motor at rest there, the load still), its parameters ``mode_of_time(t)``; ``breaks_s``:
    where the mode's parameters have corners (the command's breakpoints are added). On the intervals of ``still_s``
    the motor and the mode do not change (the dwells at a machine's stops): there the free vibration is carried in
    closed form (``free_states``), so that their length costs no integration."""
    t = np.asarray(time_s, dtype=float)
    start_s, end_s = float(t[0]), float(t[-1])
    cuts = np.concatenate(([start_s, end_s], command.time_s, breaks_s, [x for pair in still_s for x in pair]))
    cuts = np.unique(cuts[(cuts >= start_s) & (cuts <= end_s)])
    w_end = mode_of_time(end_s)[0]
    atol = 1e-3 * RTOL * max(command.max_abs(2), 1e-300) / (w_end * w_end)  # of the deflection a'' causes
    out = np.zeros((2, t.size))
    state = np.zeros(2)
    evaluations = 0
    for a, b in itertools.pairwise(cuts):
        lo, hi = np.searchsorted(t, a, side="left"), np.searchsorted(t, b, side="left")  # the instants in [a, b)
        wanted = np.append(t[lo:hi], b)  # and the piece's end, where the next starts
        if any(u <= a and b <= v for u, v in still_s):
            w, zeta = mode_of_time(float(a))
            states = free_states(state, w, zeta, wanted - a)
            out[:, lo:hi] = states[:, :-1]
            state = states[:, -1]
            continue
        # each piece is smooth (motor'' one polynomial on it): the integrator never steps across a corner
        solution = solve_ivp(
            _equation(command, mode_of_time, float(a)),
            (float(a), float(b)),
            state,
            method="DOP853",
            t_eval=wanted,
            rtol=RTOL,
            atol=atol,
            first_step=min(float(b - a), 0.01 / max(w_end, 1e-9)),
        )
        if not solution.success or solution.t.size != wanted.size:
            raise ArithmeticError(f"the varying mode's integration failed on [{a:.6g}, {b:.6g}] s: {solution.message}")
        evaluations += int(solution.nfev)
        if evaluations > MAX_EVALUATIONS:
            raise ArithmeticError(f"the varying mode needs more than {MAX_EVALUATIONS} evaluations")
        out[:, lo:hi] = solution.y[:, :-1]
        state = solution.y[:, -1]
    out[:, -1] = state
    return Deflection(t, out[0], out[1], evaluations)


def _equation(
    command: PiecewiseCommand, mode_of_time: ModeOfTime, piece_start_s: float
) -> Callable[[float, NDArray[np.float64]], NDArray[np.float64]]:
    """The right-hand side on the command's piece that starts at or before ``piece_start_s``: motor'' is that
    piece's polynomial throughout (at the piece's far end too, where ``evaluate`` would take the next piece's)."""
    k = max(int(np.searchsorted(command.time_s, piece_start_s, side="right")) - 1, 0)
    t_k = float(command.time_s[k])
    coeffs = [float(command.derivatives[n, k]) / math.factorial(n - 2) for n in range(2, command.degree + 1)]
    if piece_start_s < float(command.time_s[0]):
        coeffs = [0.0]  # before the command: rest

    def rhs(t: float, y: NDArray[np.float64]) -> NDArray[np.float64]:
        w, zeta = mode_of_time(t)
        tau = t - t_k
        accel = 0.0
        for c in reversed(coeffs):
            accel = accel * tau + c
        return np.array([y[1], -accel - 2.0 * zeta * w * y[1] - w * w * y[0]])

    return rhs
