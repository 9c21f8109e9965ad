"""Symmetric trapezoidal acceleration profiles (STAP), Cusimano 2022 (Machines 10, 767).

The motor accelerates from rest to ``v`` in the acceleration time t_a with an acceleration that
rises linearly for the jerk time t_j, stays at its maximum for t_c = t_a - 2 t_j and falls linearly
for t_j (Fig. 2, eqs. 9-18):

    a_max = v / (t_a - t_j)                                        (eq. 11)
    jerk  = a_max / t_j = v / (t_j (t_a - t_j))                    (eq. 16, read with PAPER-NOTES)

with the rectangle (t_j = 0, t_c = t_a) and the triangle (t_j = t_a/2, t_c = 0) as its limits
(Fig. 3). The profile is an exact piecewise polynomial (``models.commands.PiecewiseCommand``) with
its breakpoints at the corners 0, t_j, t_a - t_j, t_a; after t_a the motor keeps the velocity v.
``command(...).resampled(h, end_s=horizon)`` adds a uniform grid and keeps the corners, so the
samples (acceleration held linearly between them) describe the profile exactly.

Residual vibration. With jerk +j on [0, t_j], 0, and -j on [t_a - t_j, t_a], the free state that the
profile leaves in a pole lambda of the load (models.simulation: the jumps of the jerk divided by
lambda^4, propagated to t_a) factorises:

    h(t_a) = (j / lambda^4) (exp(lambda (t_a - t_j)) - 1) (exp(lambda t_j) - 1),

which is the paper's exciting term u (eq. 41, s = lambda) written as a product. Undamped, it is
zero when f_n t_j or f_n (t_a - t_j) is an integer: the zeros of eq. (44) and their side bands.
The sensitivity curve (SC) of Appendix B (A5-A12) is |lambda h| / v for lambda = i 2 pi f_n; it
equals 4 D |sin(pi rho k_j) sin(pi rho (r - k_j))| with rho = f_n/f_n,e, r = f_n,e t_a,
k_j = f_n,e t_j and D of (A9), for any real k_j (checked in tests/models/test_stap.py).

The sensitivity (eq. 41, Appendix B) and the worst torque overshoot over a frequency band (eqs. 57-59)
are small pure functions here too; the limits (eqs. 19, 21, 27-28), the zero-vibration jerk times
(eqs. 44, 48-50) and eqs. (45)-(46) as printed are in ``models.stap_design``, the exact peak motor
torque in ``models.stap_torque``; ``optim.families.stap`` composes them into designs.

A rest-to-rest move (``RestToRest``, beyond the paper) is an accelerating STAP to the cruise
velocity, a cruise phase and the mirrored decelerating STAP. The decelerating ramp leaves minus
the free state of the accelerating one, so the move leaves h(t_a) (exp(lambda D/v) - 1): no
residual wherever the ramp leaves none.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import cast

import numpy as np
from numpy.typing import NDArray

from models.commands import MIN_STEP_S, PiecewiseCommand, check_time_grid
from models.errors import InvalidParameter

MAX_TIME_S = 1e6  # longest acceleration or cruise time accepted (keeps positions and grids finite)

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]


@dataclass(frozen=True)
class Stap:
    """A STAP from rest to ``velocity`` (signed) in ``acceleration_time_s`` with ``jerk_time_s``.

    Pieces shorter than 1e-9 s (``models.commands.MIN_STEP_S``) are merged: a jerk time below it
    becomes the rectangle, a constant-acceleration time below it the triangle.
    """

    velocity: float
    acceleration_time_s: float
    jerk_time_s: float

    def __post_init__(self) -> None:
        v, t_a, t_j = float(self.velocity), float(self.acceleration_time_s), float(self.jerk_time_s)
        if not (math.isfinite(v) and v != 0.0):
            raise InvalidParameter("velocity", v, "must be finite and non-zero")
        if not (math.isfinite(t_a) and MIN_STEP_S <= t_a <= MAX_TIME_S):
            raise InvalidParameter("acceleration_time_s", t_a, f"must lie in [{MIN_STEP_S:g}, {MAX_TIME_S:g}] s")
        if not (math.isfinite(t_j) and 0.0 <= t_j <= 0.5 * t_a * (1.0 + 1e-12)):
            raise InvalidParameter("jerk_time_s", t_j, f"must satisfy 0 <= t_j <= t_a/2 = {0.5 * t_a:.9g} s (eq. 9)")
        if t_j < MIN_STEP_S:
            t_j = 0.0
        elif t_a - 2.0 * t_j < MIN_STEP_S:
            t_j = 0.5 * t_a
        object.__setattr__(self, "velocity", v)
        object.__setattr__(self, "acceleration_time_s", t_a)
        object.__setattr__(self, "jerk_time_s", t_j)

    # --- eqs. 9-18 -----------------------------------------------------------------------
    @property
    def constant_acceleration_time_s(self) -> float:
        """t_c = t_a - 2 t_j (Fig. 2)."""
        return self.acceleration_time_s - 2.0 * self.jerk_time_s

    @property
    def dimensionless_jerk_time(self) -> float:
        """t^_j = t_j / t_a (eq. 12)."""
        return self.jerk_time_s / self.acceleration_time_s

    @property
    def peak_acceleration(self) -> float:
        """a_max = v / (t_a - t_j) (eq. 11), signed like the velocity."""
        return self.velocity / (self.acceleration_time_s - self.jerk_time_s)

    @property
    def jerk(self) -> float | None:
        """j = v / (t_j (t_a - t_j)) (eq. 16); None for the rectangle, whose jerk is impulsive."""
        if self.jerk_time_s == 0.0:
            return None
        return self.peak_acceleration / self.jerk_time_s

    @property
    def acceleration_coefficient(self) -> float:
        """c_a,v = 1 / (1 - t^_j) (eq. 14): a_max over the mean acceleration v/t_a."""
        return 1.0 / (1.0 - self.dimensionless_jerk_time)

    @property
    def jerk_coefficient(self) -> float | None:
        """c_j,v = 1 / (t^_j (1 - t^_j)) (eq. 17); None for the rectangle."""
        t = self.dimensionless_jerk_time
        return None if t == 0.0 else 1.0 / (t * (1.0 - t))

    @property
    def shape(self) -> str:
        """``rectangle`` (t_j = 0), ``triangle`` (t_c = 0) or ``trapezoid`` (Fig. 3)."""
        if self.jerk_time_s == 0.0:
            return "rectangle"
        if self.constant_acceleration_time_s == 0.0:
            return "triangle"
        return "trapezoid"

    @property
    def displacement(self) -> float:
        """Motor displacement during t_a: v t_a / 2 (the acceleration is symmetric about t_a/2)."""
        return 0.5 * self.velocity * self.acceleration_time_s

    # --- the exact command ----------------------------------------------------------------
    def pieces(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(durations, acceleration at each piece's start, jerk on each piece), corners only."""
        t_j, t_c = self.jerk_time_s, self.constant_acceleration_time_s
        a, j = self.peak_acceleration, self.jerk
        if j is None:  # the rectangle
            return np.array([t_c]), np.array([a]), np.array([0.0])
        if self.shape == "triangle":
            return np.array([t_j, t_j]), np.array([0.0, a]), np.array([j, -j])
        return np.array([t_j, t_c, t_j]), np.array([0.0, a, a]), np.array([j, 0.0, -j])

    def command(self) -> PiecewiseCommand:
        """The exact rest-to-velocity command: breakpoints at the corners, then velocity v held."""
        return command_from_pieces(*self.pieces(), final_position=self.displacement, final_velocity=self.velocity)

    def free_state(self, poles: ComplexArray) -> ComplexArray:
        """h(t_a) for each pole (see the module docstring): the free state left when the ramp ends.

        The rectangle's limit is (v / (t_a lambda^3)) (exp(lambda t_a) - 1).
        """
        lam = np.asarray(poles, dtype=complex)
        t_a, t_j, v = self.acceleration_time_s, self.jerk_time_s, self.velocity
        j = self.jerk
        if j is None:  # the rectangle (t_j = 0)
            return cast(ComplexArray, v / (t_a * lam**3) * np.expm1(lam * t_a))
        return cast(ComplexArray, j / lam**4 * np.expm1(lam * (t_a - t_j)) * np.expm1(lam * t_j))


def command_from_pieces(
    durations: FloatArray,
    accelerations: FloatArray,
    jerks: FloatArray,
    *,
    final_position: float,
    final_velocity: float,
) -> PiecewiseCommand:
    """A command from rest whose acceleration starts each piece at ``accelerations[k]`` and
    changes with the constant ``jerks[k]`` over ``durations[k]``; position and velocity are the
    exact integrals (a loop over the handful of pieces). The last breakpoint takes the exact
    final position and velocity, with no acceleration: the command then holds that velocity."""
    durations = np.asarray(durations, dtype=float)
    n = durations.size
    der = np.zeros((4, n + 1))
    der[2, :n] = accelerations
    der[3, :n] = jerks
    for k in range(n):  # pieces, not samples
        h, a, j = durations[k], der[2, k], der[3, k]
        der[1, k + 1] = der[1, k] + a * h + j * h * h / 2.0
        der[0, k + 1] = der[0, k] + der[1, k] * h + a * h * h / 2.0 + j * h**3 / 6.0
    der[0, n], der[1, n] = final_position, final_velocity
    times = check_time_grid(np.concatenate([[0.0], np.cumsum(durations)]))
    # The acceleration is continuous unless a piece starts with a jump (the rectangle's corners).
    ends = np.concatenate([[0.0], der[2, :n] + der[3, :n] * durations])  # acceleration reached at each breakpoint
    starts = np.concatenate([der[2, :n], [0.0]])
    scale = max(float(np.max(np.abs(der[2]))), 1e-300)
    continuous = 3 if np.all(np.abs(starts - ends) <= 1e-9 * scale) else 2
    return PiecewiseCommand(times, der, continuous_orders=continuous)


@dataclass(frozen=True)
class RestToRest:
    """Accelerating STAP to the cruise velocity, cruise for ``cruise_time_s``, mirrored deceleration.

    Each ramp lasts t_a; the displacement is v (t_a + t_cruise) and the move lasts 2 t_a + t_cruise.
    """

    ramp: Stap
    cruise_time_s: float

    def __post_init__(self) -> None:
        t = float(self.cruise_time_s)
        if not (math.isfinite(t) and 0.0 <= t <= MAX_TIME_S):
            raise InvalidParameter("cruise_time_s", t, f"must lie in [0, {MAX_TIME_S:g}] s")
        object.__setattr__(self, "cruise_time_s", 0.0 if t < MIN_STEP_S else t)

    @property
    def displacement(self) -> float:
        return self.ramp.velocity * (self.ramp.acceleration_time_s + self.cruise_time_s)

    @property
    def total_time_s(self) -> float:
        return 2.0 * self.ramp.acceleration_time_s + self.cruise_time_s

    def command(self) -> PiecewiseCommand:
        """The exact move: corners as breakpoints, rest at the displacement afterwards."""
        d, a, j = self.ramp.pieces()
        parts_d, parts_a, parts_j = [d], [a], [j]
        if self.cruise_time_s > 0.0:
            parts_d.append(np.array([self.cruise_time_s]))
            parts_a.append(np.zeros(1))
            parts_j.append(np.zeros(1))
        parts_d.append(d)
        parts_a.append(-a)
        parts_j.append(-j)
        return command_from_pieces(
            np.concatenate(parts_d),
            np.concatenate(parts_a),
            np.concatenate(parts_j),
            final_position=self.displacement,
            final_velocity=0.0,
        )


# ------------------------------------------------------------------------------------------
# Zeros and sensitivity (Secs. 2.3-2.4, Appendices A-B)


def exciting_term_u(r_na: FloatArray | float, t_hat_j: FloatArray | float) -> ComplexArray:
    """u = 1 - exp(-i 2 pi r t^_j) - exp(-i 2 pi r (1 - t^_j)) + exp(-i 2 pi r) (eq. 41), r = f_n t_a."""
    r = np.asarray(r_na, dtype=float)
    t = np.asarray(t_hat_j, dtype=float)
    phase = -2j * np.pi * r
    return cast(ComplexArray, 1.0 - np.exp(phase * t) - np.exp(phase * (1.0 - t)) + np.exp(phase))


def sensitivity_appendix_b(frequency_ratio: FloatArray, r_na: float, k_j: float) -> FloatArray:
    """|residual load velocity| / v versus rho = f_n / f_n,e for zeta = 0: eqs. (A5)-(A12).

    ``r_na`` = f_n,e t_a and ``k_j`` = f_n,e t_j (> 0; any real value, not only the integers of
    delta = 0, for which the paper states it). ``rectangle_sensitivity`` covers t_j = 0.
    """
    if not k_j > 0.0:
        raise InvalidParameter("jerk_time_s", k_j, "Appendix B needs t_j > 0 (use rectangle_sensitivity)")
    rho = np.asarray(frequency_ratio, dtype=float)
    x = 2.0 * np.pi * rho
    s_j, c_j = np.sin(x * k_j), np.cos(x * k_j)  # (A5), (A6)
    s_a, c_a = np.sin(x * (r_na - 2.0 * k_j)), np.cos(x * (r_na - 2.0 * k_j))  # (A7), (A8)
    d = 1.0 / ((2.0 * np.pi) ** 2 * rho**2 * r_na * k_j * (1.0 - k_j / r_na))  # (A9)
    p = s_j * c_a - (1.0 - c_j) * s_a
    q = 1.0 + s_j * s_a + (1.0 - c_j) * c_a
    a = p * c_j - q * s_j  # (A10)
    b = 1.0 - p * s_j - q * c_j  # (A11)
    return d * np.hypot(a, b)  # (A12)


def rectangle_sensitivity(frequency_ratio: FloatArray, r_na: float) -> FloatArray:
    """The t_j -> 0 limit of Appendix B: |sin(pi rho r)| / (pi rho r) (the rectangle's SC)."""
    z = np.pi * np.asarray(frequency_ratio, dtype=float) * r_na
    return np.abs(np.sinc(z / np.pi))


def stap_sensitivity(stap: Stap, estimated_frequency_hz: float, frequency_ratio: FloatArray) -> FloatArray:
    """The undamped SC of a STAP designed for f_n,e: Appendix B, or its rectangle limit."""
    r = estimated_frequency_hz * stap.acceleration_time_s
    k = estimated_frequency_hz * stap.jerk_time_s
    if stap.jerk_time_s == 0.0:
        return rectangle_sensitivity(frequency_ratio, r)
    return sensitivity_appendix_b(frequency_ratio, r, k)


# ------------------------------------------------------------------------------------------
# Load acceleration and motor torque during t_c (Sec. 3, eqs. 57-59)


def load_acceleration_oscillation(frequency_ratio: FloatArray | float, k_j: float) -> FloatArray:
    """|a_l,c| / a_max = sqrt(2) sqrt(1 - cos(2 pi rho k_j)) / (2 pi rho k_j) (eq. 57).

    The amplitude of the load's acceleration oscillation about the motor's during t_c (zeta = 0,
    t_c long enough for the peak). It equals |sin(pi rho k_j)| / (pi rho k_j); k_j = f_n,e t_j
    may be any real value (k_j = 0, the rectangle, gives 1).
    """
    x = np.pi * np.asarray(frequency_ratio, dtype=float) * k_j
    return np.abs(np.sinc(x / np.pi))


def torque_coefficient(inertia_ratio: float) -> float:
    """(J_L/J_M) / (1 + J_L/J_M) (Fig. 19; the factor of eq. 59)."""
    return inertia_ratio / (1.0 + inertia_ratio)


def motor_torque_scale(motor_inertia: float, load_inertia: float, peak_acceleration: float) -> float:
    """M_m,max = (J_M + J_L) a_max (eq. 58)."""
    return (motor_inertia + load_inertia) * peak_acceleration


def motor_torque_oscillation(frequency_ratio: FloatArray | float, k_j: float, inertia_ratio: float) -> FloatArray:
    """|M_m,c| / M_m,max = (J_L/J_M)/(1 + J_L/J_M) * |a_l,c| / a_max (eq. 59, read with PAPER-NOTES)."""
    return torque_coefficient(inertia_ratio) * load_acceleration_oscillation(frequency_ratio, k_j)


def worst_torque_overshoot(k_j: float, inertia_ratio: float, uncertainty: float) -> tuple[float, float, float]:
    """(eq. 57, eq. 59, rho) at the rho in [1 - u, 1 + u] where eq. (59) is largest.

    Eq. (57) is |sin(pi x)| / (pi x), x = rho k_j: its maxima on an interval are at the ends or at
    the roots of tan(pi x) = pi x (x_m in (m, m + 1/2)), found by a few Newton steps each.
    """
    lo, hi = 1.0 - uncertainty, 1.0 + uncertainty
    rhos = [lo, hi]
    if k_j > 0.0:
        for m in range(math.floor(lo * k_j), math.ceil(hi * k_j) + 1):  # a handful of lobes
            if m < 1:
                continue
            x = m + 0.45
            for _ in range(50):
                g = math.tan(math.pi * x) - math.pi * x
                dg = math.pi / math.cos(math.pi * x) ** 2 - math.pi
                x_new = min(max(x - g / dg, m + 1e-9), m + 0.5 - 1e-9)
                if abs(x_new - x) < 1e-15:
                    break
                x = x_new
            rho = x / k_j
            if lo <= rho <= hi:
                rhos.append(rho)
    values = [float(load_acceleration_oscillation(r, k_j)) for r in rhos]
    i = int(np.argmax(values))
    return values[i], torque_coefficient(inertia_ratio) * values[i], rhos[i]
