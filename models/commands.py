"""Motor commands as piecewise polynomials.

A command is described exactly by its breakpoints t_0 < ... < t_{N-1} and, at each breakpoint,
the right-hand derivatives p^(m)(t_k+) for m = 0..d: on [t_k, t_{k+1}) it is the Taylor polynomial
of degree d built from them. Before t_0 the motor rests at p(t_0); after t_{N-1} the last
polynomial continues (a held velocity for a rest-to-velocity move, rest for a rest-to-rest move).

Sampled commands become piecewise polynomials by holding their highest given derivative: a
first-order hold (piecewise linear, the default) or a zero-order hold (piecewise constant), the
lower derivatives being its exact integrals. A trapezoidal acceleration sampled at its corners is
described exactly by a first-order hold on the acceleration, for example.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from models.errors import InvalidParameter

Hold = Literal["linear", "zero", "cubic"]
DERIVATIVE_NAMES = ("position", "velocity", "acceleration", "jerk")
_JUMP_RELATIVE_TOLERANCE = 64 * np.finfo(float).eps
# Bounds that keep every integral and power of a step finite in double precision.
MAX_ABS_TIME_S = 1e7
MIN_STEP_S = 1e-9
_UNIFORM_GRID_TOLERANCE = 1e-12
_IMPULSE_RELATIVE_TOLERANCE = 1e-9  # a jump below this fraction of its quantity's range is no impulse
MAX_ABS_VALUE = 1e12


def _taylor_step(
    derivatives: NDArray[np.float64], h: NDArray[np.float64], m: int, degree: int, start: int | None = None
) -> NDArray[np.float64]:
    """sum_{n=start..degree} D_n h^(n-m) / (n-m)!, by Horner's rule (start defaults to m)."""
    start = m if start is None else start
    acc: NDArray[np.float64] = derivatives[degree] / math.factorial(degree - m)
    for n in range(degree - 1, start - 1, -1):
        acc = acc * h + derivatives[n] / math.factorial(n - m)
    for _ in range(start - m):
        acc = acc * h
    return acc


def _check_samples(values: ArrayLike, t: NDArray[np.float64], field: str) -> NDArray[np.float64]:
    u = np.asarray(values, dtype=float)
    if u.shape != t.shape:
        raise InvalidParameter(field, f"{u.size} samples", f"must have as many samples as time_s ({t.size})")
    # Two reductions decide (NaN propagates through min and max); the mask only names the first bad sample.
    low, high = float(u.min()), float(u.max())
    if low >= -MAX_ABS_VALUE and high <= MAX_ABS_VALUE:
        return u
    bad = ~np.isfinite(u) | (np.abs(u) > MAX_ABS_VALUE)
    k = int(np.argmax(bad))
    raise InvalidParameter(f"{field}[{k}]", str(u[k]), f"must be finite and within +-{MAX_ABS_VALUE:g}")


def check_time_grid(time_s: ArrayLike, field: str = "time_s") -> NDArray[np.float64]:
    """A finite, strictly increasing grid of at least two samples."""
    return _checked_grid(time_s, field)[0]


def _checked_grid(time_s: ArrayLike, field: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``check_time_grid`` and the steps it computed. A grid whose smallest step is at least MIN_STEP_S
    (NaN fails the comparison) is increasing, so its ends bound it: two passes (diff, min) accept it."""
    t = np.asarray(time_s, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise InvalidParameter(field, f"{t.size} samples", "needs at least 2 samples")
    steps = np.diff(t)
    smallest = float(steps.min())
    ends = max(abs(float(t[0])), abs(float(t[-1])))
    if smallest >= MIN_STEP_S and ends <= MAX_ABS_TIME_S:
        return t, steps
    if not np.all(np.isfinite(t)):
        raise InvalidParameter(field, "non-finite value", "every time must be finite")
    if np.max(np.abs(t)) > MAX_ABS_TIME_S:
        raise InvalidParameter(field, float(np.max(np.abs(t))), f"times must lie within +-{MAX_ABS_TIME_S:g} s")
    if np.any(steps <= 0.0):
        k = int(np.argmax(steps <= 0.0))
        raise InvalidParameter(
            f"{field}[{k + 1}]", float(t[k + 1]), f"times must be strictly increasing (previous is {float(t[k])!r})"
        )
    k = int(np.argmax(steps < MIN_STEP_S))
    raise InvalidParameter(f"{field}[{k + 1}]", float(t[k + 1]), f"samples must be at least {MIN_STEP_S:g} s apart")


@dataclass(frozen=True)
class PiecewiseCommand:
    """A motor command that is a polynomial of degree ``degree`` between breakpoints.

    ``derivatives[m, k]`` is p^(m)(t_k+), the right-hand m-th derivative at breakpoint k. ``motion_before`` is
    (p'(t_0-), p''(t_0-), ...): the motion the command continues, which the load has followed long enough to be in
    its quasi-static state (its free response is zero at t_0-); () is rest.
    """

    time_s: NDArray[np.float64]
    derivatives: NDArray[np.float64]
    continuous_orders: int = 0  # p .. p^(continuous_orders - 1) are continuous after t_0
    motion_before: tuple[float, ...] = ()

    def before(self, m: int) -> float:
        """p^(m)(t_0-): p(t_0) for m = 0, the motion before the command otherwise (0 at rest)."""
        if m == 0:
            return float(self.derivatives[0, 0])
        return self.motion_before[m - 1] if m - 1 < len(self.motion_before) else 0.0

    @property
    def degree(self) -> int:
        return int(self.derivatives.shape[0]) - 1

    @cached_property
    def steps_s(self) -> NDArray[np.float64]:
        steps = np.diff(self.time_s)
        steps.setflags(write=False)
        return steps

    @cached_property
    def is_uniform(self) -> bool:
        """True when t_k = t_0 + k h to within round-off (then one recurrence step fits all)."""
        t = self.time_s
        span = float(t[-1] - t[0])
        deviation = np.arange(t.size, dtype=float)  # t_0 + k h - t_k, in place
        deviation *= span / (t.size - 1)
        deviation += float(t[0])
        deviation -= t
        largest = max(float(deviation.max()), -float(deviation.min()))
        return largest <= _UNIFORM_GRID_TOLERANCE * span

    def derivative(self, m: int) -> NDArray[np.float64]:
        """p^(m) at the breakpoints (right-hand values); zero above the degree."""
        if m <= self.degree:
            row: NDArray[np.float64] = self.derivatives[m]
            return row
        return np.zeros_like(self.time_s)

    @cached_property
    def _max_abs_by_order(self) -> dict[int, float]:
        return {}

    @cached_property
    def _left_limit_by_order(self) -> dict[int, NDArray[np.float64]]:
        return {}

    def max_abs(self, m: int) -> float:
        """max_k |p^(m)(t_k+)| (0 above the degree), computed once per order."""
        cache = self._max_abs_by_order
        if m not in cache:
            row = self.derivative(m)
            cache[m] = max(float(row.max()), -float(row.min())) if m <= self.degree else 0.0
        return cache[m]

    def left_limits(self) -> NDArray[np.float64]:
        """p^(m)(t_k-), from the piece before each breakpoint; ``before(m)`` at t_0."""
        return np.array([self.left_limit(m) for m in range(self.degree + 1)])

    def left_limit(self, m: int) -> NDArray[np.float64]:
        """p^(m)(t_k-) for one order m (computed once)."""
        cache = self._left_limit_by_order
        if m not in cache:
            d = self.degree
            left = np.empty_like(self.time_s)
            left[0] = self.before(m)
            if m == d:  # the top order is constant on each piece
                left[1:] = self.derivatives[d, :-1]
            else:
                left[1:] = _taylor_step(self.derivatives[:, :-1], self.steps_s, m, d)
            left.setflags(write=False)
            cache[m] = left
        return cache[m]

    @cached_property
    def _jumps(self) -> NDArray[np.float64]:
        d = self.degree
        jumps = np.zeros(self.derivatives.shape)  # calloc: rows that stay zero are never written
        # Leaving rest (or the motion before) at t_0; values at round-off level of their own row count as zero.
        first = self.derivatives[1:, 0] - np.array([self.before(m) for m in range(1, d + 1)])
        row_scale = np.max(np.abs(self.derivatives[1:]), axis=1)
        jumps[1:, 0] = np.where(np.abs(first) <= _JUMP_RELATIVE_TOLERANCE * row_scale, 0.0, first)
        for m in range(self.continuous_orders, d + 1):  # loop over derivative orders
            # The top order is constant on each piece: its left limit is the previous right value.
            left = self.derivatives[d, :-1] if m == d else self.left_limit(m)[1:]
            right = self.derivatives[m, 1:]
            diff = jumps[m, 1:]
            np.subtract(right, left, out=diff)
            # |diff| <= noise = tol (|right| + |left|) can only hold where |diff| <= 2 tol max(|right|, |left|):
            # the exact test runs on those candidates only (no temporary of the samples' size in floats).
            largest = self.max_abs(m) if m == d else max(self.max_abs(m), float(left.max()), -float(left.min()))
            bound = 2.0 * _JUMP_RELATIVE_TOLERANCE * largest
            candidates = np.flatnonzero((diff <= bound) & (diff >= -bound))
            if candidates.size:
                noise = _JUMP_RELATIVE_TOLERANCE * (np.abs(right[candidates]) + np.abs(left[candidates]))
                diff[candidates[np.abs(diff[candidates]) <= noise]] = 0.0
        jumps.setflags(write=False)
        return jumps

    def jumps(self) -> NDArray[np.float64]:
        """p^(m)(t_k+) - p^(m)(t_k-): the discontinuities that excite the plant's free response.

        Differences at round-off level are set to zero; so are the orders that are continuous
        by construction (``continuous_orders``).
        """
        return self._jumps

    @cached_property
    def _end_index(self) -> int:
        changed = np.flatnonzero(np.any(self.jumps() != 0.0, axis=0))
        return int(changed[-1]) if changed.size else 0

    def end_index(self) -> int:
        """Index of the last breakpoint where the command changes (its end, for residual metrics)."""
        return self._end_index

    def evaluate(self, m: int, t: ArrayLike) -> NDArray[np.float64]:
        """p^(m)(t) at arbitrary times (right-continuous)."""
        t = np.asarray(t, dtype=float)
        k = np.clip(np.searchsorted(self.time_s, t, side="right") - 1, 0, self.time_s.size - 1)
        tau = t - self.time_s[k]
        out = np.zeros_like(tau)
        for n in range(m, self.degree + 1):
            out += self.derivatives[n, k] * tau ** (n - m) / math.factorial(n - m)
        before = t < self.time_s[0]
        if np.any(before):
            out[before] = self.derivatives[0, 0] if m == 0 else 0.0
        return out

    def evaluate_at_instants(self, t: ArrayLike, orders: int = 4, snap_s: float = MIN_STEP_S) -> NDArray[np.float64]:
        """p, p', ... p^(orders - 1) at instants ``t`` (one row per order) that are breakpoints, or lie within
        ``snap_s`` of one (a corner that replaced a grid instant when the command was resampled): each instant
        is evaluated on the piece of its nearest breakpoint (its Taylor polynomial, exact for the piece that
        starts there), so round-off in an instant's time never evaluates the previous piece at its far end.
        Other instants: as ``evaluate``. One search and one table of tau^j / j! serve every order."""
        t = np.asarray(t, dtype=float)
        k = np.clip(np.searchsorted(self.time_s, t, side="right") - 1, 0, self.time_s.size - 1)
        following = np.minimum(k + 1, self.time_s.size - 1)
        ahead = (self.time_s[following] - t <= snap_s) & (following > k)
        k = np.where(ahead, following, k)
        tau = t - self.time_s[k]
        degree = self.degree
        powers = np.empty((degree + 1, t.size))
        powers[0] = 1.0
        for j in range(1, degree + 1):  # tau^j / j!, by the recurrence (degree <= 7: a loop over orders only)
            powers[j] = powers[j - 1] * tau / j
        at = self.derivatives[:, k]
        out = np.zeros((orders, t.size))
        for m in range(min(orders, degree + 1)):
            out[m] = np.einsum("ji,ji->i", at[m:], powers[: degree + 1 - m])
        before = t < self.time_s[0] - snap_s
        if np.any(before):
            out[:, before] = 0.0
            out[0, before] = self.derivatives[0, 0]
        return out

    @cached_property
    def _peak_by_order(self) -> dict[tuple[int, int | None], float | None]:
        return {}

    def peak_abs(self, m: int, until: int | None = None) -> float | None:
        """max |p^(m)| over [t_0, t_{N-1}] (or [t_0, t_until]), including extrema inside the pieces.

        None when p^(m) is impulsive, i.e. a lower derivative jumps somewhere (including a start
        from rest with a non-zero value). Exact when p^(m) has degree <= 3 inside a piece (its derivative's
        roots are found in closed form); otherwise also sampled at 16 interior points per piece. Computed once
        per (m, until).
        """
        cache = self._peak_by_order
        if (m, until) not in cache:
            cache[m, until] = self._peak_abs(m, until)
        return cache[m, until]

    def _peak_abs(self, m: int, until: int | None) -> float | None:
        if m >= 1:
            jumps = np.abs(self.jumps()[:m])
            scale = np.max(np.abs(self.derivatives[:m]), axis=1, keepdims=True)
            if np.any(jumps > _IMPULSE_RELATIVE_TOLERANCE * scale):
                return None
        if m > self.degree:
            return 0.0
        last = self.time_s.size - 1 if until is None else until
        candidates = [np.abs(self.derivatives[m, : last + 1]), np.abs(self.left_limit(m)[1 : last + 1])]
        h = self.steps_s[:last]
        deg_inside = self.degree - m  # degree of p^(m) within a piece
        coeffs = [self.derivatives[m + 1 + i, :last] / math.factorial(i) for i in range(deg_inside)]
        # Roots tau of p^(m+1)(t_k + tau) = sum_i coeffs[i] tau^i inside (0, h_k).
        roots: list[NDArray[np.float64]] = []
        if deg_inside == 2:
            with np.errstate(divide="ignore", invalid="ignore"):
                roots.append(-coeffs[0] / coeffs[1])
        elif deg_inside == 3:
            c0, c1, c2 = coeffs
            disc = c1 * c1 - 4.0 * c2 * c0
            with np.errstate(divide="ignore", invalid="ignore"):
                sq = np.sqrt(np.where(disc >= 0.0, disc, np.nan))
                roots += [(-c1 + sq) / (2.0 * c2), (-c1 - sq) / (2.0 * c2), -c0 / c1]
        elif deg_inside > 3:
            roots += [h * f for f in np.linspace(0.0, 1.0, 18)[1:-1]]
        if roots:
            tau = np.array(roots)  # (candidates per piece, pieces)
            tau = np.where(np.isfinite(tau) & (tau > 0.0) & (tau < h), tau, np.nan)
            # Horner over the orders (a handful), every piece and candidate at once:
            # p^(m)(t_k + tau) = D_m + tau (D_(m+1) + tau / 2 (D_(m+2) + ...)).
            value = np.broadcast_to(self.derivatives[self.degree, :last], tau.shape)
            for n in range(self.degree - 1, m - 1, -1):
                value = value * tau / (n - m + 1) + self.derivatives[n, :last]
            inside = np.abs(value[np.isfinite(value)])
            candidates.append(inside)
        return float(max(np.max(c) if c.size else 0.0 for c in candidates))

    @classmethod
    def from_samples(
        cls,
        time_s: ArrayLike,
        values: ArrayLike,
        order: int,
        *,
        hold: Hold = "linear",
        slopes: ArrayLike | None = None,
        initial: tuple[float, ...] = (),
        field: str = "profile",
    ) -> PiecewiseCommand:
        """The command whose ``order``-th derivative (0 position .. 3 jerk) is ``values`` between
        samples: held linearly, constantly, or by the cubic Hermite curve through ``values`` with
        derivatives ``slopes`` (hold "cubic": e.g. accelerations with their jerks). ``initial``
        gives p, p', ... at t_0 (default 0); the lower derivatives are exact integrals.

        After the last sample the held quantity keeps its last value.
        """
        t, h = _checked_grid(time_s, f"{field}.time_s")
        u = _check_samples(values, t, f"{field}.{DERIVATIVE_NAMES[order]}")
        for m, value in enumerate(initial):
            if not (math.isfinite(value) and abs(value) <= MAX_ABS_VALUE):
                raise InvalidParameter(
                    f"{field}.{DERIVATIVE_NAMES[m]}[0]", value, f"must be finite and within +-{MAX_ABS_VALUE:g}"
                )
        degree = {"linear": order + 1, "zero": order, "cubic": order + 3}[hold]
        der = np.zeros((degree + 1, t.size)) if hold == "cubic" else np.empty((degree + 1, t.size))
        der[order] = u
        if hold == "linear":
            slope = der[order + 1, :-1]
            np.subtract(u[1:], u[:-1], out=slope)
            slope /= h
            der[order + 1, -1] = 0.0
        elif hold == "cubic":
            if slopes is None:
                raise InvalidParameter(
                    f"{field}.{DERIVATIVE_NAMES[order + 1]}", None, "a cubic hold needs these samples"
                )
            s = _check_samples(slopes, t, f"{field}.{DERIVATIVE_NAMES[order + 1]}")
            secant = np.diff(u) / h
            der[order + 1, :-1] = s[:-1]
            der[order + 2, :-1] = 2.0 * (3.0 * secant - 2.0 * s[:-1] - s[1:]) / h
            der[order + 3, :-1] = 6.0 * (s[:-1] + s[1:] - 2.0 * secant) / h**2
        for m in range(order - 1, -1, -1):
            increments = _taylor_step(der[:, :-1], h, m, degree, start=m + 1)
            start = initial[m] if m < len(initial) else 0.0
            der[m, 0] = start
            np.cumsum(increments, out=der[m, 1:])
            if start != 0.0:
                der[m, 1:] += start
        # Orders that cannot jump after t_0. The cubic hold's slope is continuous inside but drops
        # to zero after the last sample, so its jumps are computed (round-off is zeroed there).
        continuous = {"linear": order + 1, "zero": order, "cubic": order + 1}[hold]
        command = cls(t, der, continuous_orders=continuous)
        h.setflags(write=False)
        command.__dict__["steps_s"] = h  # computed by the grid check
        if hold != "cubic":
            command._max_abs_by_order[order] = max(float(u.max()), -float(u.min()))
        return command

    def resampled(self, period_s: float, end_s: float | None = None) -> PiecewiseCommand:
        """The same command on a uniform grid of ``period_s`` from t_0 to ``end_s`` (default: the
        last breakpoint), with every breakpoint added to the grid so the samples still describe
        it exactly. Breakpoints closer than 1e-9 s to a grid point replace it."""
        t0 = float(self.time_s[0])
        stop = float(self.time_s[-1] if end_s is None else end_s)
        count = int(np.floor((stop - t0) / period_s + 1e-9)) + 1
        grid = t0 + period_s * np.arange(count)
        inside = self.time_s[self.time_s <= stop]
        idx = np.searchsorted(inside, grid)
        before = inside[np.clip(idx - 1, 0, inside.size - 1)]
        after = inside[np.clip(idx, 0, inside.size - 1)]
        near = np.minimum(np.abs(grid - before), np.abs(grid - after)) < MIN_STEP_S
        t = np.union1d(grid[~near], inside)
        if t[-1] < stop:
            t = np.append(t, stop)
        return PiecewiseCommand(t, self._evaluate_orders(t), self.continuous_orders, self.motion_before)

    def _evaluate_orders(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """``evaluate(m, t)`` for every order m (one row each), with one search and one set of powers of
        tau shared by the orders (the same operations per order, so the same numbers)."""
        k = np.clip(np.searchsorted(self.time_s, t, side="right") - 1, 0, self.time_s.size - 1)
        tau = t - self.time_s[k]
        at = self.derivatives[:, k]
        powers = [tau**j for j in range(self.degree + 1)]
        before = t < self.time_s[0]
        out = np.zeros((self.degree + 1, t.size))
        for m in range(self.degree + 1):  # a loop over orders
            row = out[m]
            for n in range(m, self.degree + 1):
                row += at[n] * powers[n - m] / math.factorial(n - m)
            if np.any(before):
                row[before] = self.derivatives[0, 0] if m == 0 else 0.0
        return out

    @classmethod
    def from_derivatives(cls, time_s: ArrayLike, derivatives: ArrayLike) -> PiecewiseCommand:
        """A command given exactly by its right-hand derivatives at its breakpoints."""
        return cls(check_time_grid(time_s), np.atleast_2d(np.asarray(derivatives, dtype=float)))

    @classmethod
    def from_held_steps(
        cls, time_s: ArrayLike, levels: ArrayLike, order: int, initial: tuple[float, ...] = ()
    ) -> PiecewiseCommand:
        """The command whose derivative of ``order`` is ``levels[k]`` on [t_k, t_(k+1)) (the last level holds
        after the last breakpoint), its lower derivatives integrated exactly: a bang-bang or trapezoidal
        acceleration (order 2), a piecewise-constant jerk (order 3). ``initial`` = (p, p', ...) at t_0 (default
        rest), continuing that motion (``motion_before``). Built directly: steps may be shorter than a sampled
        grid allows."""
        t = np.asarray(time_s, dtype=float)
        held = np.asarray(levels, dtype=float)
        h = np.diff(t)
        state = np.zeros((order + 1, t.size))
        state[order] = held
        for m in range(order - 1, -1, -1):  # each derivative from the higher ones, exact over every step
            step = sum(state[n, :-1] * h ** (n - m) / math.factorial(n - m) for n in range(m + 1, order + 1))
            state[m, 1:] = np.cumsum(step)
            if m < len(initial) and initial[m] != 0.0:
                state[m] += initial[m]
        motion = tuple(float(v) for v in initial[1:order]) if any(initial[1:order]) else ()
        return cls(t, state, continuous_orders=order, motion_before=motion)
