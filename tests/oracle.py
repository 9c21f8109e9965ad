"""Independent reference: integrate the plant's ODE with scipy's DOP853 at tight tolerance.

It shares nothing with models.simulation but the command's own interpolation: the realisation
comes from scipy.signal.tf2ss, the integration restarts at every breakpoint so each piece is
smooth, and the input is the kind's own (velocity for velocity-input plants). The load velocity
is integrated separately, as the same transfer function driven by the input's derivative:
differentiating the state would cancel large terms and lose digits.
"""

from __future__ import annotations

import numpy as np
from scipy import signal
from scipy.integrate import solve_ivp

from models.commands import PiecewiseCommand
from models.plants import Plant


def _integrate(plant: Plant, command: PiecewiseCommand, order: int, rtol: float) -> np.ndarray:
    num, den = plant.command_transfer_function()
    a, b, c, d = signal.tf2ss(np.trim_zeros(num, "f"), den)

    def u(t: float) -> float:
        return float(command.evaluate(order, np.array([t]))[0])

    def rhs(t: float, x: np.ndarray) -> np.ndarray:
        return a @ x + b[:, 0] * u(t)

    t = command.time_s
    before = command.derivative(0)[0] if order == 0 else 0.0  # at rest before t_0
    x = -np.linalg.solve(a, b[:, 0]) * before
    states = [x]
    for k in range(t.size - 1):
        sol = solve_ivp(rhs, (t[k], t[k + 1]), x, method="DOP853", rtol=rtol, atol=1e-15 * (1 + np.max(np.abs(x))))
        x = sol.y[:, -1]
        states.append(x)
    xs = np.array(states).T
    return (c @ xs)[0] + d[0, 0] * np.array([u(tk) for tk in t])


def ivp_response(plant: Plant, command: PiecewiseCommand, rtol: float = 1e-13) -> dict[str, np.ndarray]:
    order = 1 if plant.command_input == "velocity" else 0
    return {
        "position": _integrate(plant, command, order, rtol),
        "velocity": _integrate(plant, command, order + 1, rtol),
    }
