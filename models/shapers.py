"""Input shaping: impulse sequences, their residual vibration (Sec. 3.1), shaped commands (eqs. 6-7, Fig. 7).

Chatlatanagulchai & Pongpanich (papers/chatlatanagulchai-zvd-acceleration-limit.txt), Sec. 3 and
Fig. 5: an input shaper is a sequence of impulses A_i at times t_i; the shaped command is the
baseline command convolved with it, v_s(t) = sum_i A_i v_b(t - t_i); the drive then limits the
slope of the velocity command to the acceleration limit a, v_a = rate_limit(v_s).

Everything here is pure: the design of a shaper (which A_i, t_i) and of a baseline lives in
``optim.families.input_shaped.shapers``, the drive's rate limiter and position follower in ``models.drives``;
the closed-form ZV^(k+1) (``zv_family``, eq. 11) is here, since the time-optimal family shapes with it too.
Velocity commands made of steps and ramps (the baseline v_b, the shaped v_s and the rate-limited v_a) are
described exactly by a ``RampTrain`` and become exact ``PiecewiseCommand`` objects (velocity piecewise linear, a
breakpoint at every kink), so that the simulation of the load is exact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import brentq

from models.breakpoints import integrated, merge_times, merge_tolerance, snap
from models.commands import PiecewiseCommand, check_time_grid
from models.errors import InvalidParameter
from models.plant_base import Mode

# ------------------------------------------------------------------------------------------
# Impulse sequences


@dataclass(frozen=True)
class ImpulseSequence:
    """Impulses of amplitude A_i at times t_i: t_1 = 0 (eq. 7), strictly increasing times.

    The amplitudes of a shaper sum to one (eq. 6), so the shaped command reaches the same final
    value; ``gain`` reports that sum for sequences built otherwise.
    """

    # Any float array on input; float64 once __post_init__ has copied it.
    amplitudes: NDArray[np.floating[Any]]
    times_s: NDArray[np.floating[Any]]

    def __post_init__(self) -> None:
        a = np.array(self.amplitudes, dtype=float).ravel()
        t = np.array(self.times_s, dtype=float).ravel()
        if a.size == 0 or a.size != t.size:
            raise InvalidParameter("impulses", f"{a.size} amplitudes, {t.size} times", "need one time per amplitude")
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(t))):
            raise InvalidParameter("impulses", "non-finite value", "amplitudes and times must be finite")
        if t[0] != 0.0:
            raise InvalidParameter("impulses.times_s[0]", float(t[0]), "the first impulse is at t_1 = 0 (eq. 7)")
        if np.any(np.diff(t) <= 0.0):
            raise InvalidParameter("impulses.times_s", t.tolist(), "times must be strictly increasing")
        a.setflags(write=False)
        t.setflags(write=False)
        object.__setattr__(self, "amplitudes", a)
        object.__setattr__(self, "times_s", t)

    @classmethod
    def merged(cls, amplitudes: ArrayLike, times_s: ArrayLike) -> ImpulseSequence:
        """The sequence with impulses at (numerically) coincident times added together, shifted so
        that the first impulse is at 0."""
        t = np.asarray(times_s, dtype=float).ravel()
        a = np.asarray(amplitudes, dtype=float).ravel()
        order = np.argsort(t, kind="stable")
        t, a = t[order], a[order]
        starts = np.flatnonzero(np.concatenate(([True], np.diff(t) > merge_tolerance(t))))
        return cls(np.add.reduceat(a, starts), t[starts] - t[0])

    @property
    def count(self) -> int:
        return int(self.amplitudes.size)

    @property
    def duration_s(self) -> float:
        return float(self.times_s[-1])

    @property
    def gain(self) -> float:
        return float(np.sum(self.amplitudes))


def zv_family(mode: Mode, derivatives: int) -> ImpulseSequence:
    """ZV (k = 0), ZVD (k = 1, eqs. 8-11), ZVDD, ...: (k + 2) impulses half a damped period apart,
    A_i = C(k+1, i) K^i / (1 + K)^(k+1), K = exp(-zeta pi / sqrt(1 - zeta^2)) (eq. 11)."""
    zeta = mode.damping_ratio
    big_k = math.exp(-zeta * math.pi / math.sqrt(1.0 - zeta * zeta))
    n = derivatives + 1
    amplitudes = np.array([math.comb(n, i) * big_k**i for i in range(n + 1)]) / (1.0 + big_k) ** n
    times = np.arange(n + 1) * math.pi / mode.damped_frequency_rad_s
    return ImpulseSequence(amplitudes, times)


def percentage_vibration(
    shaper: ImpulseSequence, natural_frequency_rad_s: ArrayLike, damping_ratio: ArrayLike
) -> NDArray[np.float64]:
    """V(omega_n, zeta) of Sec. 3.1 (the equation before eq. 4), vectorised over omega and zeta:

        V = exp(-zeta w t_n) sqrt(C^2 + S^2),
        C + jS = sum_i A_i exp(zeta w t_i) exp(j w sqrt(1 - zeta^2) t_i),

    the residual amplitude after the last impulse relative to a single unit impulse. It is
    evaluated as |sum_i A_i exp(-zeta w (t_n - t_i)) exp(j w_d t_i)|, the same number without
    the overflow of exp(zeta w t_i).
    """
    w = np.asarray(natural_frequency_rad_s, dtype=float)
    z = np.asarray(damping_ratio, dtype=float)
    w, z = np.broadcast_arrays(w, z)
    t = shaper.times_s
    wd = w * np.sqrt(1.0 - z * z)
    decay = np.exp(-(z * w)[..., None] * (t[-1] - t))
    phase = wd[..., None] * t
    c = np.sum(shaper.amplitudes * decay * np.cos(phase), axis=-1)
    s = np.sum(shaper.amplitudes * decay * np.sin(phase), axis=-1)
    residual: NDArray[np.float64] = np.hypot(c, s)
    return residual


def convolve(first: ImpulseSequence, second: ImpulseSequence) -> ImpulseSequence:
    """The shaper for two modes: every impulse of one applied to every impulse of the other
    (amplitudes multiply, times add); it cancels what each one cancels (Singhose 2009, Sec. 3)."""
    times = (first.times_s[:, None] + second.times_s[None, :]).ravel()
    amplitudes = (first.amplitudes[:, None] * second.amplitudes[None, :]).ravel()
    return ImpulseSequence.merged(amplitudes, times)


def vibration_band(
    shaper: ImpulseSequence,
    natural_frequency_rad_s: float,
    damping_ratio: float,
    threshold: float = 0.05,
    *,
    max_ratio: float = 4.0,
    points: int = 8001,
    slack: float = 1e-9,
) -> tuple[float | None, float | None] | None:
    """[low, high] ratios w/w_design around 1 where V <= threshold (zeta fixed), or None; an end
    is None where the band runs past the scanned ratios (0, max_ratio].

    V is scanned on a grid of ratios in (0, max_ratio] and every crossing is refined by Brent's
    method, so the ends are exact to ~1e-12. ``slack`` (relative) lets a shaper whose residual
    equals the threshold at a hump (EI shapers at their own tolerance) count as within it.
    """
    limit = threshold * (1.0 + slack)
    ratios = np.linspace(max_ratio / points, max_ratio, points)

    def v(r: ArrayLike) -> NDArray[np.float64]:
        return percentage_vibration(shaper, np.asarray(r) * natural_frequency_rad_s, damping_ratio)

    values = v(ratios)
    centre = int(np.argmin(np.abs(ratios - 1.0)))
    if float(v(1.0)) > limit:
        return None
    above = np.flatnonzero(values > limit)
    left, right = above[above < centre], above[above > centre]

    def crossing(outside: int, inside: int) -> float:
        return float(brentq(lambda r: float(v(r)) - limit, ratios[outside], ratios[inside], xtol=1e-14, rtol=1e-13))

    low = crossing(int(left[-1]), int(left[-1]) + 1) if left.size else None  # open: below the scanned ratios
    high = crossing(int(right[0]), int(right[0]) - 1) if right.size else None  # open: above max_ratio
    return low, high


# ------------------------------------------------------------------------------------------
# Step-and-ramp velocity commands


@dataclass(frozen=True)
class RampTrain:
    """A velocity command v(t) = sum_j h_j r_j(t - s_j): steps (rise_s = 0) and linear ramps that
    rise by h_j over rise_s (Figs. 5, 7 and 10 of the paper), r_j(tau) = clip(tau / d_j, 0, 1).
    """

    # Any float array on input; float64 once __post_init__ has copied it.
    start_s: NDArray[np.floating[Any]]
    rise_s: NDArray[np.floating[Any]]
    height: NDArray[np.floating[Any]]

    def __post_init__(self) -> None:
        arrays = [np.array(x, dtype=float).ravel() for x in (self.start_s, self.rise_s, self.height)]
        if len({a.size for a in arrays}) != 1 or arrays[0].size == 0:
            raise InvalidParameter(
                "ramps", [a.size for a in arrays], "start_s, rise_s and height need one entry per ramp"
            )
        if not all(np.all(np.isfinite(a)) for a in arrays):
            raise InvalidParameter("ramps", "non-finite value", "ramps must be finite")
        if np.any(arrays[0] < 0.0) or np.any(arrays[1] < 0.0):
            raise InvalidParameter("ramps", "negative time", "starts and rise times must be >= 0")
        for name, a in zip(("start_s", "rise_s", "height"), arrays, strict=True):
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    @classmethod
    def single(cls, start_s: float, rise_s: float, height: float) -> RampTrain:
        return cls(np.array([start_s]), np.array([rise_s]), np.array([height]))

    @property
    def end_s(self) -> float:
        """When the last ramp ends (the command is constant afterwards)."""
        return float(np.max(self.start_s + self.rise_s))

    @property
    def final_velocity(self) -> float:
        return float(np.sum(self.height))

    def pulse(self, cruise_s: float) -> RampTrain:
        """A rest-to-rest move: the train, then its negative ``cruise_s`` later (area = final velocity x cruise_s)."""
        return RampTrain(
            np.concatenate([self.start_s, self.start_s + cruise_s]),
            np.concatenate([self.rise_s, self.rise_s]),
            np.concatenate([self.height, -self.height]),
        )

    def shaped(self, shaper: ImpulseSequence) -> RampTrain:
        """The train convolved with the shaper: each ramp repeated at every t_i, scaled by A_i (Fig. 7)."""
        return RampTrain(
            (self.start_s[None, :] + shaper.times_s[:, None]).ravel(),
            np.broadcast_to(self.rise_s, (shaper.count, self.rise_s.size)).ravel(),
            (shaper.amplitudes[:, None] * self.height[None, :]).ravel(),
        )

    def velocity(self, t: ArrayLike) -> NDArray[np.float64]:
        """v(t), right-continuous at steps."""
        t = np.asarray(t, dtype=float)
        tau = t[..., None] - self.start_s
        with np.errstate(divide="ignore", invalid="ignore"):
            frac = np.where(self.rise_s > 0.0, np.clip(tau / self.rise_s, 0.0, 1.0), (tau >= 0.0).astype(float))
        velocity: NDArray[np.float64] = np.sum(frac * self.height, axis=-1)
        return velocity

    def max_slope(self) -> float:
        """Largest |dv/dt| between steps: the slope is piecewise constant, so it is checked on
        every piece (sum of the active ramps' slopes)."""
        ramps = self.rise_s > 0.0
        if not np.any(ramps):
            return 0.0
        times = merge_times(np.concatenate([self.start_s, self.start_s + self.rise_s]))
        starts = self.start_s[ramps][None, :]
        ends = (self.start_s + self.rise_s)[ramps][None, :]
        slack = 1e-12 * max(1.0, float(times[-1]))
        rates = self.height[ramps] / self.rise_s[ramps]
        largest = 0.0
        for rows in _row_chunks(times.size, rates.size):  # (times x ramps) in bounded pieces
            at = times[rows, None]
            slopes = ((starts <= at + slack) & (at < ends - slack)) @ rates
            largest = max(largest, float(np.max(np.abs(slopes))))
        return largest

    def to_command(self, initial_position: float = 0.0) -> PiecewiseCommand:
        """The exact PiecewiseCommand (position, velocity, acceleration) with a breakpoint at
        every start and end of a ramp; rest before t = 0."""
        grid = merge_times(np.concatenate([[0.0], self.start_s, self.start_s + self.rise_s]))
        if grid.size < 2:
            grid = np.array([grid[0], grid[0] + 1.0])
        a = snap(self.start_s, grid)
        b = snap(self.start_s + self.rise_s, grid)
        s, e = grid[a], grid[b]
        velocity, slope = np.empty(grid.size), np.empty(grid.size)
        for rows in _row_chunks(grid.size, self.height.size):  # (breakpoints x ramps) in bounded pieces
            k = np.arange(rows.start, rows.stop)[:, None]
            with np.errstate(divide="ignore", invalid="ignore"):
                inside = (k >= a) & (k < b)
                frac = np.where(k >= b, 1.0, np.where(inside, (grid[rows, None] - s) / (e - s), 0.0))
                slope_each = np.where(inside, self.height / (e - s), 0.0)
            velocity[rows] = frac @ self.height
            slope[rows] = slope_each.sum(axis=1)
        return integrated(grid, velocity, slope, initial_position, continuous_orders=1)


_CHUNK_ELEMENTS = 262_144  # a (breakpoints x ramps) table is built this many entries at a time: 2 MiB per array


def _row_chunks(rows: int, columns: int) -> list[slice]:
    """Slices of ``rows`` whose tables of ``columns`` entries each hold at most _CHUNK_ELEMENTS (one row at least):
    a shaped train of 2000 ramps built its 4001 x 2000 tables whole, 138 MiB."""
    step = max(1, _CHUNK_ELEMENTS // max(1, columns))
    return [slice(start, min(start + step, rows)) for start in range(0, rows, step)]


# ------------------------------------------------------------------------------------------
# Shaping any command


def _evaluate_shifted(
    command: PiecewiseCommand, m: int, t: NDArray[np.float64], shift_s: float, tol: float
) -> NDArray[np.float64]:
    """p^(m)(t - shift), right-continuous, treating breakpoints within ``tol`` of t as reached
    (so a merged breakpoint gets the values after the jump); rest at p(t_0) before t_0."""
    breaks = command.time_s + shift_s
    k = np.searchsorted(breaks, t + tol, side="right") - 1
    before = k < 0
    k = np.clip(k, 0, breaks.size - 1)
    tau = t - breaks[k]
    out = np.zeros_like(t)
    for n in range(m, command.degree + 1):  # a loop over polynomial orders
        out += command.derivatives[n, k] * tau ** (n - m) / math.factorial(n - m)
    out[before] = command.derivatives[0, 0] if m == 0 else 0.0
    return out


def shape_command(command: PiecewiseCommand, shaper: ImpulseSequence) -> PiecewiseCommand:
    """sum_i A_i p(t - t_i) for any piecewise-polynomial command (position or velocity alike: the
    convolution commutes with differentiation), exactly: its breakpoints are every t_k + t_i."""
    grid = merge_times((command.time_s[None, :] + shaper.times_s[:, None]).ravel())
    tol = merge_tolerance(grid)
    derivatives = np.zeros((command.degree + 1, grid.size))
    for a_i, t_i in zip(shaper.amplitudes, shaper.times_s, strict=True):  # a loop over impulses
        for m in range(command.degree + 1):
            derivatives[m] += a_i * _evaluate_shifted(command, m, grid, float(t_i), tol)
    return PiecewiseCommand(check_time_grid(grid), derivatives, command.continuous_orders)


def shape_samples(time_s: ArrayLike, values: ArrayLike, shaper: ImpulseSequence) -> NDArray[np.float64]:
    """A sampled command (position or velocity) shaped on its own grid: sum_i A_i u(t - t_i), with
    u interpolated linearly between samples, u(t_0) before and u(t_N) after. The samples of the
    shaped first-order-hold signal, exactly (its extra kinks fall between samples)."""
    t = check_time_grid(time_s)
    u = np.asarray(values, dtype=float)
    if u.shape != t.shape:
        raise InvalidParameter("values", f"{u.size} samples", f"must have as many samples as time_s ({t.size})")
    out = np.zeros_like(u)
    for a_i, t_i in zip(shaper.amplitudes, shaper.times_s, strict=True):  # a loop over impulses
        out += a_i * np.interp(t - t_i, t, u)
    return out
