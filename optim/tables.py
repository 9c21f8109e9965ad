"""A design as a table on an exact uniform grid, t_k = k * period, for a drive's cam table (the CSV).

The JSON answer samples the command on a uniform grid with every corner added (so the samples describe it
exactly); a drive wants one row per servo period and nothing else. Here every value is computed at the
instants t_k themselves: the command from the family's exact command (``Family.profile_at``), the load from
the simulation, whose samples hold every t_k (a corner closer than ``MIN_STEP_S`` to an instant stands in for
it there and is carried to t_k by its Taylor step). Nothing is interpolated between samples.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from decimal import Decimal

import numpy as np
from numpy.typing import NDArray

from models.commands import MIN_STEP_S
from models.errors import InvalidParameter
from models.simulation import Response
from optim.registry import FAMILIES
from optim.synthesis import Result

PROFILE_COLUMNS = ("time_s", "position", "velocity", "acceleration", "jerk")
LOAD_COLUMNS = ("load_position", "load_velocity", "load_acceleration", "deflection", "motor_torque_nm")
COLUMNS = (*PROFILE_COLUMNS, *LOAD_COLUMNS)
UNITS = {
    "time_s": "s",
    "position": "motor unit (rad or m)",
    "velocity": "motor unit/s",
    "acceleration": "motor unit/s^2",
    "jerk": "motor unit/s^3 (right-hand value where it jumps)",
    "load_position": "load unit (rad or m)",
    "load_velocity": "load unit/s",
    "load_acceleration": "load unit/s^2",
    "deflection": "load unit (load position minus its rigid-transmission value)",
    "motor_torque_nm": "N m",
}
_SNAP_S = MIN_STEP_S  # how far a corner may stand in for a grid instant (models.commands.resampled)


@dataclass(frozen=True)
class Table:
    """Rows at t_k = k * period_s, k = 0..n-1; one column per name."""

    columns: tuple[str, ...]
    values: NDArray[np.float64]  # shape (rows, columns)
    period_s: float


def uniform_times(period_s: float, horizon_s: float) -> NDArray[np.float64]:
    """t_k = k * period_s for k = 0.. floor(horizon / period), each rounded to the period's own decimals (so
    0.002 * 1003 is written 2.006, not 2.0060000000000002); the period as given is the step."""
    count = math.floor(horizon_s / period_s + 1e-9) + 1
    t = np.arange(count, dtype=float) * period_s
    exponent = Decimal(repr(period_s)).as_tuple().exponent
    decimals = -exponent if isinstance(exponent, int) else 0
    if 0 <= decimals <= 15:
        t = np.round(t, decimals)
    return t


def check_columns(columns: tuple[str, ...]) -> tuple[str, ...]:
    """The requested columns, time_s first (``all`` alone: every column); an unknown name is a 422 on ``columns``."""
    if columns == ("all",):
        return columns
    unknown = [c for c in columns if c not in COLUMNS]
    if unknown:
        rule = f"each column must be one of {', '.join(COLUMNS)} (or all, alone)"
        raise InvalidParameter("columns", ",".join(unknown), rule)
    rest = tuple(dict.fromkeys(c for c in columns if c != "time_s"))
    return ("time_s", *rest)


def table(result: Result, columns: tuple[str, ...] = PROFILE_COLUMNS) -> Table:
    """The design's profile (and load columns when asked; ``all``: every column the plant defines) at
    t_k = k * grid period up to the horizon."""
    columns = check_columns(columns)
    if columns == ("all",):
        response = result.response
        undefined = {"deflection": response.deflection, "motor_torque_nm": response.motor_torque_nm}
        columns = tuple(c for c in COLUMNS if c not in undefined or undefined[c] is not None)
    grid = result.run.grid
    t = uniform_times(grid.period_s, grid.horizon_s)
    family = FAMILIES[result.family]
    values: dict[str, NDArray[np.float64] | None] = {"time_s": t}
    if any(c in PROFILE_COLUMNS for c in columns[1:]):
        profile = family.profile_at(result.design, result.run.command, t)
        values.update({k: v for k, v in profile.items() if k != "time_s"})
    if any(c in LOAD_COLUMNS for c in columns):
        values.update(load_at(result.response, t))
    missing = [c for c in columns if values.get(c) is None]
    if missing:
        raise InvalidParameter("columns", ",".join(missing), "not defined for this plant (two_inertia only for torque)")
    matrix = np.column_stack([np.asarray(values[c], dtype=float) for c in columns])
    matrix[matrix == 0.0] = 0.0  # -0.0 becomes 0.0
    matrix[:, 0] = t
    return Table(columns, matrix, grid.period_s)


def load_at(response: Response, t: NDArray[np.float64]) -> dict[str, NDArray[np.float64] | None]:
    """The simulated load at instants that are (within ``_SNAP_S``) sample times, carried from the nearest
    sample by its Taylor step: position + v d + a d^2 / 2, velocity + a d (d < 1e-9 s)."""
    samples = response.time_s
    k = np.clip(np.searchsorted(samples, t), 1, samples.size - 1)
    k = np.where(np.abs(samples[k - 1] - t) <= np.abs(samples[k] - t), k - 1, k)
    d = t - samples[k]
    if np.any(np.abs(d) > _SNAP_S + 1e-12 * np.abs(t)):
        raise AssertionError("the simulation's samples do not hold every grid instant")  # a defect, not an input
    v, a = response.load_velocity[k], response.load_acceleration[k]
    deflection, torque = response.deflection, response.motor_torque_nm
    return {
        "load_position": response.load_position[k] + v * d + 0.5 * a * d * d,
        "load_velocity": v + a * d,
        "load_acceleration": a,
        "deflection": None if deflection is None else deflection[k],
        "motor_torque_nm": None if torque is None else torque[k],
    }
