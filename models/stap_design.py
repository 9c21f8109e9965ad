"""STAP design formulas (Cusimano 2022): the limits (eqs. 19, 21, 27-28), the zero-vibration jerk times (eqs. 43-50)."""

from __future__ import annotations

import math

import numpy as np

from models.errors import InvalidParameter
from models.stap import FloatArray


def nodal_acceleration_limit(max_torque_nm: float, motor_inertia: float, load_inertia: float) -> float:
    """a_Max = M_m,Max / (J_M + J_L) (eq. 19): the acceleration of the nodal section."""
    return max_torque_nm / (motor_inertia + load_inertia)


def min_acceleration_time(velocity: float, acceleration_limit: float) -> float:
    """t_a,min = v / a_Max (eq. 21)."""
    return abs(velocity) / acceleration_limit


def max_jerk_time(acceleration_time_s: float, velocity: float, acceleration_limit: float | None) -> float:
    """t_j,max = min(t_a/2, t_a - t_a,min) (eqs. 9, 27, 28); t_a/2 without an acceleration limit."""
    if acceleration_limit is None:
        return 0.5 * acceleration_time_s
    return min(0.5 * acceleration_time_s, acceleration_time_s - min_acceleration_time(velocity, acceleration_limit))


def zero_vibration_jerk_time(
    frequency_hz: float, k_j: int, delta: int = 0, acceleration_time_s: float | None = None
) -> float:
    """t_j,0 = (k_j + delta dec(f_n,e t_a)) / f_n,e (eqs. 44, 49): a zero of the residual at f_n,e.

    With delta = 0 it is k_j / f_n,e (eq. 48; eq. 50 for k_j = 1) and needs no t_a; a side band
    (delta = 1) depends on t_a through dec (eq. 43)."""
    if delta == 0:
        return k_j / frequency_hz
    if acceleration_time_s is None:
        raise InvalidParameter("acceleration_time_s", None, "a side-band jerk time (delta = 1) depends on t_a (eq. 49)")
    return (k_j + delta * float(decimal_part(frequency_hz * acceleration_time_s))) / frequency_hz


def decimal_part(x: FloatArray | float) -> FloatArray | float:
    """dec(x) = x - int(x) (eq. 43), with values within 1e-9 of an integer taken as that integer,
    so that f_n t_a computed in floating point (40 * 0.15 = 6.000000000000001) reads as a whole
    number of periods."""
    x = np.asarray(x, dtype=float)
    nearest = np.round(x)
    snapped = np.where(np.abs(x - nearest) <= 1e-9 * np.maximum(1.0, np.abs(x)), nearest, x)
    out = snapped - np.floor(snapped)
    return float(out) if out.ndim == 0 else out


def paper_k_j_max(t_hat_j_max: float, r_na: float) -> int:
    """k_j,max = int[t^_j,max int(r_n,a)] (eq. 45), as printed."""
    return math.floor(t_hat_j_max * math.floor(r_na))


def paper_delta_f(t_hat_j_max: float, r_na: float) -> int:
    """delta_f = round(t^_j,max r_n,a - k_j,max) (eq. 46), as printed (halves round up)."""
    return math.floor(t_hat_j_max * r_na - paper_k_j_max(t_hat_j_max, r_na) + 0.5)
