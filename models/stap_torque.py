"""The exact peak motor torque J_M a_M + J_L a_L of a STAP command (Cusimano 2022: beyond eq. 19, its rigid part)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from models.commands import PiecewiseCommand
from models.errors import InvalidParameter
from models.stap import FloatArray

if TYPE_CHECKING:
    from models.plants import Plant
    from models.simulation import Response

TORQUE_POINTS_PER_PERIOD = 32  # dense samples per period of the fastest mode before the refinement
DENSE_PERIODS = 64  # a piece up to this many slowest periods is sampled whole; past it, bounded
WINDOW_PERIODS = 2.0  # the first slowest periods of a longer piece are sampled, the rest bounded
REFINED_PEAKS = 4  # per piece, the largest local maxima of the samples maximised exactly


def _torque_in_pieces(response: Response, pieces: NDArray[np.intp], tau: FloatArray) -> FloatArray:
    """|J_M a_M + J_L a_L| at t_k + tau (k in ``pieces``, tau of shape (len(pieces), n)).

    Inside a piece the command's acceleration is a + j tau and each pole's free state h_k exp(lambda tau)
    (models.simulation), so a_L = g_0 (a + j tau) + g_1 j + Re sum w r lambda^2 h_k exp(lambda tau)."""
    j_m, j_l = _inertias(response.plant)
    cmd, modal = response.command, response.modal
    g = np.zeros(2)
    g[: min(2, modal.taylor.size)] = modal.taylor[:2]
    a = cmd.derivative(2)[pieces][:, None] + cmd.derivative(3)[pieces][:, None] * tau
    jerk = cmd.derivative(3)[pieces][:, None]
    coef = modal.weights * modal.residues * modal.poles**2  # (poles,)
    free = response.free_state[:, pieces]  # (poles, pieces)
    osc = np.einsum("p,pk,pkn->kn", coef, free, np.exp(modal.poles[:, None, None] * tau[None])).real
    return np.asarray(np.abs(j_m * a + j_l * (g[0] * a + g[1] * jerk + osc)), dtype=float)


def _inertias(plant: Plant) -> tuple[float, float]:
    inertias = plant.torque_inertias()
    if inertias is None:
        raise InvalidParameter("plant", plant.kind, "the plant defines no motor torque")
    return inertias


def _tail_bound(response: Response, k: int, start_s: float, stop_s: float) -> float:
    """An upper bound of the torque on piece k for tau in [start_s, stop_s]: the rigid part at its ends
    (it is linear in tau) plus J_L times the free vibration's envelope at start_s (it only decays)."""
    j_m, j_l = _inertias(response.plant)
    cmd, modal = response.command, response.modal
    g = np.zeros(2)
    g[: min(2, modal.taylor.size)] = modal.taylor[:2]
    a, jerk = float(cmd.derivative(2)[k]), float(cmd.derivative(3)[k])
    ramp = [a + jerk * start_s, a + jerk * stop_s] if math.isfinite(stop_s) else [math.inf]
    ends = [a] if jerk == 0.0 else ramp
    rigid = max(abs((j_m + j_l * g[0]) * e + j_l * g[1] * jerk) for e in ends)
    coef = modal.weights * modal.residues * modal.poles**2
    envelope = float(np.sum(np.abs(coef * response.free_state[:, k] * np.exp(modal.poles * start_s))))
    return float(rigid + j_l * envelope)


def _piece_peak(response: Response, k: int, length_s: float, fastest_s: float, slowest_s: float) -> float:
    """The largest torque on piece k (length ``length_s``, inf for the last): dense samples, their largest
    local maxima refined by bounded Brent on the closed form, and past the sampled window a bound."""
    from scipy.optimize import minimize_scalar

    whole = length_s <= DENSE_PERIODS * slowest_s
    window = length_s if whole else WINDOW_PERIODS * slowest_s
    n = int(min(math.ceil(window / fastest_s * TORQUE_POINTS_PER_PERIOD), 1_000_000)) + 2
    tau = np.linspace(0.0, window, n)
    index = np.array([k])
    values = _torque_in_pieces(response, index, tau[None])[0]
    best = float(np.max(values))
    inner = np.flatnonzero((values[1:-1] >= values[:-2]) & (values[1:-1] >= values[2:])) + 1
    for i in inner[np.argsort(values[inner])[-REFINED_PEAKS:]]:  # a handful of local maxima
        found = minimize_scalar(
            lambda t: -float(_torque_in_pieces(response, index, np.array([[t]]))[0, 0]),
            bounds=(float(tau[i - 1]), float(tau[i + 1])),
            method="bounded",
            options={"xatol": 1e-13 * max(window, 1e-300)},
        )
        best = max(best, -float(found.fun))
    if not whole:
        best = max(best, _tail_bound(response, k, window, length_s))
    return best


def peak_motor_torque_nm(plant: Plant, command: PiecewiseCommand) -> float:
    """sup_t |J_M a_M(t) + J_L a_L(t)| over all time, for a command of degree <= 3 starting from rest.

    On each piece of the command (and after its end) the torque is in closed form from the free state at
    the piece's start (``_torque_in_pieces``): it is sampled at 32 points per period of the fastest mode,
    its largest local maxima refined exactly (bounded Brent), and on a piece longer than 64 periods of
    the slowest mode (a cruise, the rest after the move) only the first 2 periods are sampled and the
    rest bounded by the rigid part plus the decaying envelope (exact for an undamped mode)."""
    from models.simulation import simulate

    modes = plant.modes()
    response = simulate(plant, command)
    if not modes:  # rigid: the torque is (J_M + J_L g_0) a_M, largest at a breakpoint
        torque = response.motor_torque_nm
        return 0.0 if torque is None else float(np.max(np.abs(torque)))
    fastest = min(m.natural_period_s for m in modes)
    slowest = max(m.natural_period_s for m in modes)
    lengths = np.append(command.steps_s, math.inf)
    return max(_piece_peak(response, k, float(lengths[k]), fastest, slowest) for k in range(lengths.size))
