"""Input shaping: impulse sequences, their residual vibration, shaped and rate-limited commands.

Chatlatanagulchai & Pongpanich (papers/chatlatanagulchai-zvd-acceleration-limit.txt), Sec. 3 and
Fig. 5: an input shaper is a sequence of impulses A_i at times t_i; the shaped command is the
baseline command convolved with it, v_s(t) = sum_i A_i v_b(t - t_i); the drive then limits the
slope of the velocity command to the acceleration limit a, v_a = rate_limit(v_s).

Everything here is pure: the design of a shaper (which A_i, t_i) and of a baseline lives in
``optim.families.input_shaped.shapers``. Velocity commands made of steps and ramps (the baseline v_b, the shaped v_s
and the rate-limited v_a) are described exactly by a ``RampTrain`` and become exact
``PiecewiseCommand`` objects (velocity piecewise linear, a breakpoint at every kink), so that the
simulation of the load is exact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import brentq

from models.commands import MIN_STEP_S, PiecewiseCommand, check_time_grid
from models.errors import InvalidParameter

# Times closer than this (absolute, or relative to the largest time) are one breakpoint: sums
# such as t_i + t_j and t_j + t_i differ by round-off only, and PiecewiseCommand needs steps of
# at least MIN_STEP_S. Merging moves a kink by at most 2e-9 s.
_MERGE_ABS_S = 2.0 * MIN_STEP_S
_MERGE_REL = 1e-12


def _merge_tolerance(times: NDArray[np.float64]) -> float:
    scale = float(np.max(np.abs(times))) if times.size else 0.0
    return max(_MERGE_ABS_S, _MERGE_REL * scale)


def _merge_times(times: ArrayLike) -> NDArray[np.float64]:
    """Sorted unique times, those within the merge tolerance of the previous kept one dropped."""
    t = np.sort(np.asarray(times, dtype=float))
    if t.size == 0:
        return t
    keep = np.concatenate(([True], np.diff(t) > _merge_tolerance(t)))
    return t[keep]


def _snap(times: NDArray[np.floating[Any]], grid: NDArray[np.float64]) -> NDArray[np.intp]:
    """Index of the grid point nearest to each time (every time is within tolerance of one)."""
    idx = np.clip(np.searchsorted(grid, times), 1, max(grid.size - 1, 1))
    if grid.size == 1:
        return np.zeros(times.shape, dtype=int)
    left = grid[idx - 1]
    right = grid[idx]
    return np.where(np.abs(times - left) <= np.abs(right - times), idx - 1, idx)


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
        starts = np.flatnonzero(np.concatenate(([True], np.diff(t) > _merge_tolerance(t))))
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
        times = _merge_times(np.concatenate([self.start_s, self.start_s + self.rise_s]))
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
        grid = _merge_times(np.concatenate([[0.0], self.start_s, self.start_s + self.rise_s]))
        if grid.size < 2:
            grid = np.array([grid[0], grid[0] + 1.0])
        a = _snap(self.start_s, grid)
        b = _snap(self.start_s + self.rise_s, grid)
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
        return _integrated(grid, velocity, slope, initial_position, continuous_orders=1)


_CHUNK_ELEMENTS = 262_144  # a (breakpoints x ramps) table is built this many entries at a time: 2 MiB per array


def _row_chunks(rows: int, columns: int) -> list[slice]:
    """Slices of ``rows`` whose tables of ``columns`` entries each hold at most _CHUNK_ELEMENTS (one row at least):
    a shaped train of 2000 ramps built its 4001 x 2000 tables whole, 138 MiB."""
    step = max(1, _CHUNK_ELEMENTS // max(1, columns))
    return [slice(start, min(start + step, rows)) for start in range(0, rows, step)]


def _integrated(
    time_s: NDArray[np.float64],
    velocity: NDArray[np.float64],
    slope: NDArray[np.float64],
    initial_position: float,
    continuous_orders: int,
) -> PiecewiseCommand:
    """The degree-2 command with these right-hand velocities and slopes; position integrated exactly."""
    h = np.diff(time_s)
    increments = velocity[:-1] * h + 0.5 * slope[:-1] * h * h
    position = initial_position + np.concatenate(([0.0], np.cumsum(increments)))
    return PiecewiseCommand(check_time_grid(time_s), np.array([position, velocity, slope]), continuous_orders)


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
    grid = _merge_times((command.time_s[None, :] + shaper.times_s[:, None]).ravel())
    tol = _merge_tolerance(grid)
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


# ------------------------------------------------------------------------------------------
# The drive's acceleration limit (Fig. 5)


def rate_limit(command: PiecewiseCommand, acceleration_limit: float) -> PiecewiseCommand:
    """v_a: the velocity command after the drive's rate limiter |dv_a/dt| <= a (Fig. 5).

    The limiter follows v_s while |dv_s/dt| <= a and v_a = v_s; otherwise v_a moves towards v_s
    at the full rate +-a until it meets it. For a velocity that is piecewise linear (steps and
    ramps; ``command`` of degree <= 2) the output is piecewise linear too and is found exactly:
    each piece of v_s gives at most two pieces of v_a (chase, then follow), the meeting time
    solving a linear equation. The loop runs over the command's pieces (a few dozen for shaped
    steps and ramps), not over samples. The drive starts at rest; the position is integrated.
    """
    a = float(acceleration_limit)
    if not (math.isfinite(a) and a > 0.0):
        raise InvalidParameter("acceleration_limit", a, "must be a finite number > 0")
    if command.degree > 2:
        raise InvalidParameter(
            "profile", f"degree {command.degree}", "the rate limiter needs a piecewise-linear velocity"
        )
    t = command.time_s
    v = command.derivative(1)
    s = command.derivative(2)
    scale = max(float(np.max(np.abs(v))), float(np.max(np.abs(command.left_limit(1)))), 1e-300)
    tol = 1e-12 * scale
    ends = np.append(t[1:], np.inf)
    out_t: list[float] = []
    out_slope: list[float] = []
    y = 0.0  # the drive's velocity, at rest before t_0
    for k in range(t.size):  # loop over the command's pieces
        start, length, u0, su = float(t[k]), float(ends[k] - t[k]), float(v[k]), float(s[k])
        tau = 0.0
        while True:
            error = u0 + su * tau - y
            if abs(error) <= tol:  # on the command: follow it if the drive can
                slope = min(max(su, -a), a)
                out_t.append(start + tau)
                out_slope.append(slope)
                if math.isfinite(length):
                    y = u0 + su * length if abs(su) <= a else y + slope * (length - tau)
                break
            slope = a if error > 0.0 else -a
            out_t.append(start + tau)
            out_slope.append(slope)
            closing = slope - su  # rate at which the gap closes
            meet = error / closing if closing * error > 0.0 else math.inf
            if tau + meet < length:
                y += slope * meet
                tau += meet
                continue
            if math.isfinite(length):
                y += slope * (length - tau)
            break
    times = np.array(out_t)
    slopes = np.array(out_slope)
    # Keep the last of breakpoints closer than the merge tolerance (it carries the right-hand slope).
    keep = np.concatenate((np.diff(times) > _merge_tolerance(times), [True]))
    times, slopes = times[keep], slopes[keep]
    if times.size < 2:
        times = np.array([times[0], times[0] + 1.0])
        slopes = np.array([slopes[0], slopes[0]])
    # The output velocity is continuous: integrate the slopes (it is exactly what the drive does).
    velocity = np.concatenate(([0.0], np.cumsum(slopes[:-1] * np.diff(times))))
    return _integrated(times, velocity, slopes, float(command.derivative(0)[0]), continuous_orders=2)


# ------------------------------------------------------------------------------------------
# A position-mode drive: the time-optimal follower of a position reference


def catch_up_plan(
    gap: float, velocity: float, target_velocity: float, acceleration_limit: float, velocity_limit: float
) -> tuple[tuple[float, float], ...]:
    """(duration_s, acceleration) phases that bring a double integrator onto a target moving at constant
    ``target_velocity`` in least time under |u| <= a and |velocity| <= velocity_limit (math.inf: none);
    ``gap`` = target - position.

    Bang-coast-bang, the classical time-optimal double integrator in the target's frame: the direction
    s is that of the gap left after braking, gap - w|w|/(2a) with w = velocity - target_velocity; the
    peak approach speed is sqrt(a s gap + w^2/2), or a coast at the top approach speed
    velocity_limit - s target_velocity when that is lower (a zero top speed coasts for ever).
    """
    a = acceleration_limit
    w = velocity - target_velocity
    s = 1.0 if gap >= w * abs(w) / (2.0 * a) else -1.0
    e, w = s * gap, s * w
    top = velocity_limit - s * target_velocity
    peak = math.sqrt(max(a * e + 0.5 * w * w, 0.0))
    if peak <= top:
        return ((max(peak - w, 0.0) / a, s * a), (peak / a, -s * a))
    if top <= 0.0:
        return ((max(-w, 0.0) / a, s * a), (math.inf, 0.0))
    coast = (e - (top * top - w * w) / (2.0 * a) - top * top / (2.0 * a)) / top
    return ((max(top - w, 0.0) / a, s * a), (max(coast, 0.0), 0.0), (top / a, -s * a))


def follow_position(
    reference: PiecewiseCommand, acceleration_limit: float, velocity_limit: float | None = None
) -> PiecewiseCommand:
    """What a position-mode drive makes of a position reference that moves at constant velocity between
    its breakpoints (a shaped velocity staircase): at every breakpoint its profile generator replans the
    time-optimal catch-up onto the reference under |a| <= acceleration_limit and |v| <= velocity_limit
    (``catch_up_plan``), then follows it. It starts at rest on the reference and reaches the final
    position at rest; piecewise constant in acceleration, so exact. The reference must not move faster
    than the velocity limit (then the follower's top approach speed is never negative).
    """
    a = float(acceleration_limit)
    if not (math.isfinite(a) and a > 0.0):
        raise InvalidParameter("acceleration_limit", a, "must be a finite number > 0")
    top = math.inf if velocity_limit is None else float(velocity_limit)
    if command_has_slopes(reference):
        raise InvalidParameter("profile", "ramps", "the position follower needs a reference of velocity steps")
    t, p_ref, v_ref = reference.time_s, reference.derivative(0), reference.derivative(1)
    if float(np.max(np.abs(v_ref))) > top * (1.0 + 1e-12):  # round-off of the impulses' sum allowed
        raise InvalidParameter("velocity_limit", top, "the reference itself moves faster than the velocity limit")
    on_reference = tuple(1e-13 * max(float(np.max(np.abs(x))), 1e-300) for x in (p_ref, v_ref))
    rows: list[tuple[float, float, float, float]] = []  # (time, position, velocity, acceleration) of each piece
    p, v = float(p_ref[0]), 0.0
    for k in range(t.size):  # loop over the reference's pieces (impulses x steps: a few dozen)
        start = float(t[k])
        length = float(t[k + 1] - t[k]) if k + 1 < t.size else math.inf
        gap, target_v = float(p_ref[k]) - p, float(v_ref[k])
        phases: tuple[tuple[float, float], ...] = ()
        if abs(gap) > on_reference[0] or abs(v - target_v) > on_reference[1]:
            phases = catch_up_plan(gap, v, target_v, a, top)
        elapsed = 0.0
        for duration, accel in (*phases, (math.inf, None)):  # the plan, then on the reference
            step = min(duration, length - elapsed)
            if step <= 0.0:
                continue
            if accel is None:  # on the reference (round-off of the plan removed)
                p, v, accel = float(p_ref[k]) + target_v * elapsed, target_v, 0.0
            rows.append((start + elapsed, p, v, accel))
            if not math.isfinite(step):
                break
            p, v, elapsed = p + v * step + 0.5 * accel * step * step, v + accel * step, elapsed + step
            if elapsed >= length:
                break
    table = np.array(rows)
    # Of breakpoints closer than the merge tolerance keep the last (its state is exact): a plan's phase
    # that short changes the velocity by at most a x 2e-9 s.
    table = table[np.concatenate((np.diff(table[:, 0]) > _merge_tolerance(table[:, 0]), [True]))]
    if table.shape[0] < 2:
        table = np.vstack([table, table + np.array([1.0, 0.0, 0.0, 0.0])])
    return PiecewiseCommand(check_time_grid(table[:, 0]), table[:, 1:].T.copy(), continuous_orders=2)


def command_has_slopes(command: PiecewiseCommand) -> bool:
    """Whether any piece of a degree-2 command accelerates (else its velocity is a staircase)."""
    return command.degree > 2 or bool(np.any(command.derivative(2) != 0.0))
