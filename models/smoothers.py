"""Trajectory smoothers: chains of FIR filters that turn a step into a smooth move (Biagiotti,
Melchiorri and Moriello 2020, "Damped harmonic smoother for trajectory planning and vibration
suppression"). The filters, F(s) = (c0 + c1 e^(-sT)) R(s) each, are in ``models.smoother_filters``
and re-exported here.

Time domain. A chain applied to a step of height h is one real LTI cascade, 1/s * prod R_i(s), driven
by 2^n impulses (one per subset of filters, at the sum of their durations). Between impulses the state
evolves by the matrix exponential, so the output and all its derivatives are exact to round-off at any
time. The cascade is propagated over a uniform grid by repeated squaring of expm(Ts A) (vectorised; the
Python loop runs over the 2^n pieces between impulses, never over samples). scipy.signal has no
continuous systems with delays, hence this construction; scipy.linalg.expm does the exponentials.

A chain of rectangular filters gives an exact piecewise polynomial (degree n, sec. II). Other chains
contain exponentials and sinusoids: their command is the piecewise Taylor polynomial of degree 7 built
from the exact derivatives at every sample, so the motion between samples is exact to about
(Ts |lambda|)^8 / 8! of the move, and the simulation of it (models.simulation) reproduces the smoother.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import cast

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import expm

from models.commands import MIN_STEP_S, PiecewiseCommand
from models.errors import InvalidParameter
from models.plants import Plant
from models.simulation import modal_form
from models.smoother_filters import (
    DAMPED,
    FILTER_KINDS,
    MAX_DECAY_RATE_1_S,
    MAX_DECAY_TIMES_DURATION,
    MAX_DURATION_S,
    MIN_DURATION_S,
    SINUSOIDAL,
    DiscreteFilter,
    FilterKind,
    Smoother,
    discrete_filter,
    discrete_step_response,
)

__all__ = [
    "DAMPED",
    "FILTER_KINDS",
    "MAX_DECAY_RATE_1_S",
    "MAX_DECAY_TIMES_DURATION",
    "MAX_DURATION_S",
    "MAX_FILTERS",
    "MAX_RATE_TIMES_PERIOD",
    "MAX_REQUESTED_FILTERS",
    "MIN_DURATION_S",
    "SINUSOIDAL",
    "TAYLOR_DEGREE",
    "Chain",
    "DiscreteFilter",
    "FilterKind",
    "Smoother",
    "StepResponse",
    "discrete_filter",
    "discrete_step_response",
    "mode_residuals",
    "refinement",
    "residual_fraction",
    "sample_grid",
    "step_response",
]

MAX_REQUESTED_FILTERS = 6
MAX_FILTERS = MAX_REQUESTED_FILTERS + 3  # with up to three rectangular filters for velocity, acceleration, jerk
TAYLOR_DEGREE = 7  # degree of the sampled command of a non-polynomial chain
# Largest |lambda| Ts for the Taylor command: its remainder (|lambda| Ts)^8/8! per sample keeps the simulated
# residual below 1e-10 of the move (measured on the paper's plant: 1.3e-10 at 0.22, 2.5e-8 at 0.44).
MAX_RATE_TIMES_PERIOD = 0.2


# ------------------------------------------------------------------------------------------
# Chains


@dataclass(frozen=True)
class Chain:
    """Filters in series (any order: they commute). Its step response is the motion profile."""

    filters: tuple[Smoother, ...]

    def __post_init__(self) -> None:
        if not self.filters:
            raise InvalidParameter("filters", [], "a chain needs at least one filter")
        if len(self.filters) > MAX_FILTERS:
            raise InvalidParameter("filters", f"{len(self.filters)} filters", f"at most {MAX_FILTERS} filters")

    @property
    def total_duration_s(self) -> float:
        """T_tot = T_1 + ... + T_n (Sec. II): the step response is at rest after it."""
        return float(sum(f.duration_s for f in self.filters))

    @property
    def is_polynomial(self) -> bool:
        """Only rectangular filters: the step response is piecewise polynomial of degree n (Sec. II)."""
        return all(f.kind == "rectangular" for f in self.filters)

    @property
    def fastest_rate_1_s(self) -> float:
        """max |lambda| over the filters' poles (sigma +- j pi/T, sigma, 0): the time scale of the profile."""
        rates = [
            math.hypot(f.sigma_1_s, f.half_angular_rate_rad_s) if f.kind in SINUSOIDAL else abs(f.sigma_1_s)
            for f in self.filters
        ]
        return max(rates)

    @property
    def continuous_derivatives(self) -> int:
        """Highest m with the step response of class C^m: each M raises continuity by 1, each S by 2."""
        return sum(f.order for f in self.filters) - 1

    def frequency_response(self, s: ArrayLike) -> NDArray[np.complex128]:
        """prod_i F_i(s) at complex s (the chain's transfer function)."""
        s = np.asarray(s, dtype=complex)
        out = np.ones_like(s)
        for f in self.filters:  # a loop over filters
            out = out * f.frequency_response(s)
        return out

    def end_response(self, s: ArrayLike) -> NDArray[np.complex128]:
        """prod_i F_i(s) e^(s T_tot), bounded for Re s <= 0."""
        s = np.asarray(s, dtype=complex)
        out = np.ones_like(s)
        for f in self.filters:
            out = out * f.end_response(s)
        return out

    def impulses(self, displacement: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Times and weights of the impulses that drive the cascade for a step of ``displacement``.

        One per subset of filters (at the sum of their durations), merged when closer than 1 ns.
        """
        n = len(self.filters)
        masks = (np.arange(2**n)[:, None] >> np.arange(n)[None, :]) & 1
        durations = np.array([f.duration_s for f in self.filters])
        coefs = np.array([f.delay_coefficients for f in self.filters])  # (n, 2)
        times = masks @ durations
        weights = displacement * np.prod(np.where(masks == 1, coefs[:, 1], coefs[:, 0]), axis=1)
        order = np.argsort(times, kind="stable")
        times, weights = times[order], weights[order]
        group = np.concatenate(([0], np.cumsum(np.diff(times) > MIN_STEP_S)))
        merged_t = times[np.concatenate(([True], np.diff(group) > 0))]
        # numpy's stubs type bincount as integer, but with float weights it sums them as floats.
        merged_w = cast("NDArray[np.float64]", np.bincount(group, weights=weights))
        return merged_t, merged_w

    @cached_property
    def cascade(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(A, c) of 1/s * prod R_i(s), the first state taking the impulses; y = c x."""
        blocks = [f.realisation() for f in self.filters]
        size = 1 + sum(b[0].shape[0] for b in blocks)
        a = np.zeros((size, size))  # state 0 is the integrator 1/s: its row of A is zero
        prev_c, prev_start, start = np.array([1.0]), 0, 1
        for block_a, block_b, block_c in blocks:  # a loop over filters
            k = block_a.shape[0]
            a[start : start + k, start : start + k] = block_a
            a[start : start + k, prev_start : prev_start + prev_c.size] = np.outer(block_b, prev_c)
            prev_c, prev_start = block_c, start
            start += k
        c = np.zeros(size)
        c[prev_start : prev_start + prev_c.size] = prev_c
        return a, c


# ------------------------------------------------------------------------------------------
# Step response


@dataclass(frozen=True)
class StepResponse:
    """The chain's step response on a time grid: derivatives[m, k] = q^(m)(t_k+) for m = 0..degree."""

    chain: Chain
    displacement: float
    time_s: NDArray[np.float64]
    derivatives: NDArray[np.float64]
    breakpoints_s: NDArray[np.float64]  # where a derivative of order continuous_derivatives + 1 jumps

    @property
    def position(self) -> NDArray[np.float64]:
        row: NDArray[np.float64] = self.derivatives[0]
        return row

    def derivative(self, m: int) -> NDArray[np.float64]:
        row: NDArray[np.float64] = self.derivatives[m] if m < self.derivatives.shape[0] else np.zeros_like(self.time_s)
        return row

    def command(self) -> PiecewiseCommand:
        """The motor command: exact for rectangular chains, Taylor degree 7 from exact derivatives otherwise.

        Orders up to the chain's continuity are declared continuous (``continuous_orders``) so that
        round-off is not read as a jump; for a Taylor command only up to the acceleration, where the
        mismatch between neighbouring samples is O((|lambda| Ts)^6) or smaller. The higher orders' small
        mismatches carry the motion between samples and must reach the simulation.
        """
        continuous = self.chain.continuous_derivatives + 1
        if not self.chain.is_polynomial:
            continuous = min(continuous, 3)
        return PiecewiseCommand(
            self.time_s, self.derivatives, continuous_orders=min(continuous, self.derivatives.shape[0])
        )


def refinement(chain: Chain, sample_period_s: float) -> int:
    """The integer k such that sample_period_s / k keeps the Taylor command exact (|lambda| Ts <= 0.2);
    1 for rectangular chains, whose command is an exact polynomial at any period."""
    if chain.is_polynomial:
        return 1
    return max(1, math.ceil(chain.fastest_rate_1_s * sample_period_s / MAX_RATE_TIMES_PERIOD - 1e-9))


def sample_grid(
    breakpoints_s: NDArray[np.float64], end_s: float, sample_period_s: float, offset_s: float = 0.0
) -> NDArray[np.float64]:
    """offset + k Ts for k = 0, 1, ... up to ``end_s``, with the breakpoints added (as
    PiecewiseCommand.resampled): a grid point closer than 1 ns to a breakpoint is replaced by it."""
    count = max(0, math.floor((end_s - offset_s) / sample_period_s + 1e-9) + 1)
    grid = offset_s + sample_period_s * np.arange(count)
    idx = np.searchsorted(breakpoints_s, grid)
    before = breakpoints_s[np.clip(idx - 1, 0, breakpoints_s.size - 1)]
    after = breakpoints_s[np.clip(idx, 0, breakpoints_s.size - 1)]
    near = np.minimum(np.abs(grid - before), np.abs(grid - after)) < MIN_STEP_S
    merged: NDArray[np.float64] = np.union1d(grid[~near], breakpoints_s)
    return merged


def _powers(phi: NDArray[np.float64], count: int) -> list[NDArray[np.float64]]:
    """phi^(2^m) for 2^m < count, by repeated squaring."""
    out = [phi]
    while 2 ** len(out) < count:
        out.append(out[-1] @ out[-1])
    return out


def _propagate(
    a: NDArray[np.float64], x0: NDArray[np.float64], offset_s: float, count: int, powers: list[NDArray[np.float64]]
) -> NDArray[np.float64]:
    """States at offset + k Ts for k < count from x(0) = x0: expm(offset A) x0, then doubling."""
    x: NDArray[np.float64] = (expm(offset_s * a) @ x0)[:, None]
    level = 0
    while x.shape[1] < count:
        x = np.hstack([x, powers[level] @ x])
        level += 1
    return x[:, :count]


def step_response(
    chain: Chain, displacement: float, sample_period_s: float, degree: int | None = None, offset_s: float = 0.0
) -> StepResponse:
    """The chain fed with a step of ``displacement`` at t = 0, sampled at offset + k Ts on [0, T_tot]
    plus every breakpoint; derivatives up to ``degree`` (default: n for rectangular chains, 7 otherwise)
    are exact to round-off at the samples (see the module docstring)."""
    if not (math.isfinite(displacement) and displacement != 0.0):
        raise InvalidParameter("displacement", displacement, "must be a finite, non-zero number")
    if degree is None:
        degree = len(chain.filters) if chain.is_polynomial else TAYLOR_DEGREE
    times, weights = chain.impulses(displacement)
    end = chain.total_duration_s
    grid = sample_grid(times, end, sample_period_s, offset_s)
    a, c = chain.cascade
    size = a.shape[0]
    readout = np.empty((degree + 1, size))
    row = c.copy()
    for m in range(degree + 1):  # c A^m: the m-th derivative of the output
        readout[m] = row
        row = row @ a
    phi = expm(sample_period_s * a)
    powers = _powers(phi, grid.size)
    states = np.empty((size, grid.size))
    x = np.zeros(size)
    impulse = np.zeros(size)
    position = np.searchsorted(grid, times)
    for p in range(times.size):  # a loop over the pieces between impulses, not over samples
        impulse[0] = weights[p]
        x = x + impulse
        lo = position[p]
        hi = position[p + 1] if p + 1 < times.size else grid.size
        states[:, lo] = x
        if hi - lo > 1:
            states[:, lo + 1 : hi] = _propagate(a, x, grid[lo + 1] - grid[lo], hi - lo - 1, powers)
        if p + 1 < times.size:
            x = expm((times[p + 1] - times[p]) * a) @ x
    derivatives = readout @ states
    # After the last impulse the output rests at the displacement; write it exactly.
    derivatives[:, -1] = 0.0
    derivatives[0, -1] = displacement
    if not np.all(np.isfinite(derivatives)):
        raise InvalidParameter("filters", "out of range", "the smoother's output overflows double precision")
    return StepResponse(chain, displacement, grid, derivatives, times)


# ------------------------------------------------------------------------------------------
# Residual vibration in closed form


def mode_residuals(chain: Chain, plant: Plant, displacement: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Residual amplitude of each complex mode when the chain's step response ends, in closed form,
    and the same for the unfiltered step (at t = 0).

    After the end t_e the load is G(0) h + sum_j 2 Re[r_j F(p_j) h/p_j e^(p_j t)] (residues r_j of the load
    transfer function G at its poles p_j), so the envelope at t_e is 2 |r_j h/p_j| |F(p_j) e^(p_j t_e)|.
    """
    num, den = plant.load_transfer_function()
    modal = modal_form(num, den, 1)
    osc = modal.oscillatory
    poles, residues = modal.poles[osc], modal.residues[osc]
    unfiltered = 2.0 * np.abs(residues / poles) * abs(displacement)
    return unfiltered * np.abs(chain.end_response(poles)), unfiltered


def residual_fraction(chain: Chain, pole: complex) -> float:
    """|F(p) e^(p T_tot)|: the residual left on a mode with pole p as a fraction of the unfiltered step's
    (the percent residual vibration of Sec. IV, divided by 100)."""
    return float(np.abs(chain.end_response(np.array([pole]))[0]))
