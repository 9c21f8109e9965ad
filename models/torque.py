"""The exact peak of the motor torque of a piecewise-constant-acceleration command, from the modal state.

On a two-inertia plant the motor torque is T = J_M p'' + J_L y'' (``models.plants.TwoInertiaPlant``). While
the command's acceleration is a constant a_k (a piece [t_k, t_(k+1)) of a command of degree <= 2), the load's
acceleration is its quasi-static part g_0 a_k plus the free response of the plant's one pole pair
(``models.simulation``): y''(t_k + tau) = g_0 a_k + Re(w r lambda^2 h_k exp(lambda tau)), with h_k the pole's
free state just after t_k. So on the piece

    T(tau) = Q_k + Re(C_k exp(lambda tau)),   Q_k = (J_M + J_L g_0) a_k,   C_k = J_L w r lambda^2 h_k,

a constant plus one damped sinusoid. Its derivative Re(C_k lambda exp(lambda tau)) =
|C_k lambda| exp(-sigma tau) cos(omega_d tau + arg(C_k lambda)) vanishes at tau_n = tau_0 + n pi / omega_d,
tau_0 = ((pi/2 - arg(C_k lambda)) mod pi) / omega_d; from one critical point to the next the sinusoid is
multiplied by exp(lambda pi / omega_d) = -exp(-sigma pi / omega_d): the values alternate in sign and never
grow. So the largest and the smallest value of T on [0, H_k] are among tau = 0, tau_0, tau_0 + pi / omega_d
(where inside) and H_k (the left limit at the next breakpoint), and max |T| is exact from four evaluations
per piece: no sampling, whatever the frequency or the length of the command. The last piece runs for ever
(H = inf), so the peak is the supremum over all time, the free vibration after the command included.
"""

from __future__ import annotations

import math

import numpy as np

from models.commands import PiecewiseCommand
from models.plants import Plant
from models.simulation import simulate


def peak_motor_torque_nm(plant: Plant, command: PiecewiseCommand) -> float | None:
    """sup over all t of |J_M p''(t) + J_L y''(t)| for a command of degree <= 2 (piecewise-constant
    acceleration) on a plant with one vibrating pole pair (two_inertia): exact, in closed form per piece
    (module docstring). None where the plant defines no motor torque; inf where the acceleration is
    impulsive (the velocity or the position jumps), since the torque then is.

    The work is one simulation at the command's breakpoints and four evaluations per piece."""
    inertias = plant.torque_inertias()
    if inertias is None:
        return None
    if command.degree > 2:
        raise ValueError(f"the closed-form torque peak needs a command of degree <= 2, not {command.degree}")
    if command.peak_abs(2) is None:
        return math.inf
    response = simulate(plant, command)
    modal = response.modal
    if modal.poles.size != 1 or not modal.oscillatory[0]:
        raise ValueError(f"the closed-form torque peak needs one pole pair, not {modal.poles.size} poles")
    j_m, j_l = inertias
    pole = complex(modal.poles[0])
    rigid = (j_m + j_l * float(modal.taylor[0])) * command.derivative(2)  # Q_k
    oscillation = j_l * complex(modal.weights[0] * modal.residues[0]) * pole**2 * response.free[0].full()  # C_k
    lengths = np.append(command.steps_s, math.inf)  # H_k; the last piece never ends
    omega = pole.imag
    first = np.mod(0.5 * math.pi - np.angle(oscillation * pole), math.pi) / omega
    candidates = np.stack([np.zeros_like(first), first, first + math.pi / omega, lengths])
    inside = candidates <= lengths  # tau = 0 is always inside; a critical point past the piece's end is not
    tau = np.where(inside & np.isfinite(candidates), candidates, 0.0)
    torque = rigid + (oscillation * np.exp(pole * tau)).real
    return float(np.max(np.abs(torque)))
