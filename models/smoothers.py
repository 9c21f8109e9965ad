"""Trajectory smoothers: FIR filters that turn a step into a smooth move (Biagiotti, Melchiorri and
Moriello 2020, "Damped harmonic smoother for trajectory planning and vibration suppression").

Filters, each of duration T and unit static gain (impulse response on [0, T]):

- ``rectangular`` M (eq. 1): 1/T.
- ``harmonic`` S (eqs. 4-5): (pi/2T) sin(pi t/T).
- ``damped_harmonic`` S_sigma (eqs. 10, 14): K (T/pi) e^(sigma t) sin(pi t/T), K = ((pi/T)^2 + sigma^2)/(1 + e^(sigma T)).
- ``exponential`` M_sigma (the damped rectangular filter of the paper's ref. [20], Sec. V):
  sigma e^(sigma t)/(e^(sigma T) - 1).

Sign convention: the paper's sigma is the exponent of the impulse response (negative for a stable
plant); the service's ``decay_rate_1_s`` is -sigma >= 0, as ``models.plants.Mode.decay_rate_1_s``.

Time domain. Every filter is a delay polynomial times a rational part, F(s) = (c0 + c1 e^(-sT)) R(s):
M = (1 - e^(-sT))/T * 1/s; M_sigma = c (1 - e^(sigma T) e^(-sT)) * 1/(s - sigma); S = (a^2/2)(1 + e^(-sT)) *
1/(s^2 + a^2); S_sigma = K (1 + e^(sigma T) e^(-sT)) * 1/((s - sigma)^2 + a^2), with a = pi/T. A chain applied to
a step of height h is therefore one real LTI cascade, 1/s * prod R_i(s), driven by 2^n impulses (one per
subset of filters, at the sum of their durations). Between impulses the state evolves by the matrix
exponential, so the output and all its derivatives are exact to round-off at any time. The cascade is
propagated over a uniform grid by repeated squaring of expm(Ts A) (vectorised; the Python loop runs over
the 2^n pieces between impulses, never over samples). scipy.signal has no continuous systems with
delays, hence this construction; scipy.linalg.expm does the exponentials.

A chain of rectangular filters gives an exact piecewise polynomial (degree n, sec. II). Other chains
contain exponentials and sinusoids: their command is the piecewise Taylor polynomial of degree 7 built
from the exact derivatives at every sample, so the motion between samples is exact to about
(Ts |lambda|)^8 / 8! of the move, and the simulation of it (models.simulation) reproduces the smoother.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Literal

import numpy as np
from scipy.linalg import expm
from scipy.signal import lfilter

from models.commands import MIN_STEP_S, PiecewiseCommand
from models.errors import InvalidParameter
from models.plants import Plant
from models.simulation import modal_form

FilterKind = Literal["rectangular", "harmonic", "damped_harmonic", "exponential"]
FILTER_KINDS: tuple[str, ...] = ("rectangular", "harmonic", "damped_harmonic", "exponential")
SINUSOIDAL = ("harmonic", "damped_harmonic")
DAMPED = ("damped_harmonic", "exponential")

MAX_DURATION_S = 1e5
MIN_DURATION_S = 1e-6
MAX_DECAY_RATE_1_S = 1e7
# e^(sigma T) and e^(-sigma T) stay far from overflow; a plant with zeta < 0.99 tuned at 3 pi/Omega has 66.
MAX_DECAY_TIMES_DURATION = 200.0
MAX_REQUESTED_FILTERS = 6
MAX_FILTERS = MAX_REQUESTED_FILTERS + 3  # with up to three rectangular filters for velocity, acceleration, jerk
TAYLOR_DEGREE = 7  # degree of the sampled command of a non-polynomial chain
# Largest |lambda| Ts for the Taylor command: its remainder (|lambda| Ts)^8/8! per sample keeps the simulated
# residual below 1e-10 of the move (measured on the paper's plant: 1.3e-10 at 0.22, 2.5e-8 at 0.44).
MAX_RATE_TIMES_PERIOD = 0.2


# ------------------------------------------------------------------------------------------
# Filters


def _phi(z: np.ndarray) -> np.ndarray:
    """expm1(z)/z with its limit 1 at z = 0 (complex, vectorised)."""
    z = np.asarray(z, dtype=complex)
    out = np.ones_like(z)
    nz = z != 0
    with np.errstate(over="ignore", invalid="ignore"):
        out[nz] = np.expm1(z[nz]) / z[nz]
    return out


def _sinusoidal_kernel(u: np.ndarray, duration_s: float) -> np.ndarray:
    """(1 + e^(-uT)) / (u^2 + a^2), a = pi/T: the transform of e^(...) sin(a t) on [0, T] up to a gain.

    Near its removable poles u = +-ja the direct form cancels; there it is written as
    T/(2ja) [phi(-(u - ja)T) - phi(-(u + ja)T)] (1 + e^(-uT) = 1 - e^(-(u -+ ja)T) since aT = pi).
    """
    u = np.asarray(u, dtype=complex)
    t = duration_s
    a = math.pi / t
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        direct = (1.0 + np.exp(-u * t)) / (u * u + a * a)
    near = (np.abs(u - 1j * a) * t < 1.0) | (np.abs(u + 1j * a) * t < 1.0)
    if np.any(near):
        un = u[near]
        direct[near] = t / (2j * a) * (_phi(-(un - 1j * a) * t) - _phi(-(un + 1j * a) * t))
    return direct


@dataclass(frozen=True)
class Smoother:
    """One filter of a chain: its kind, duration T (s) and decay rate -sigma (1/s, >= 0).

    The decay rate applies to ``damped_harmonic`` and ``exponential`` (zero for the others).
    """

    kind: FilterKind
    duration_s: float
    decay_rate_1_s: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in FILTER_KINDS:
            raise InvalidParameter("type", self.kind, f"must be one of {', '.join(FILTER_KINDS)}")
        t = float(self.duration_s)
        if not (math.isfinite(t) and MIN_DURATION_S <= t <= MAX_DURATION_S):
            raise InvalidParameter("duration_s", t, f"must lie in [{MIN_DURATION_S:g}, {MAX_DURATION_S:g}] s")
        d = float(self.decay_rate_1_s)
        if not (math.isfinite(d) and 0.0 <= d <= MAX_DECAY_RATE_1_S):
            raise InvalidParameter("decay_rate_1_s", d, f"must lie in [0, {MAX_DECAY_RATE_1_S:g}] 1/s")
        if d != 0.0 and self.kind not in DAMPED:
            raise InvalidParameter("decay_rate_1_s", d, f"a {self.kind} filter has no decay rate")
        if d * t > MAX_DECAY_TIMES_DURATION:
            raise InvalidParameter(
                "decay_rate_1_s",
                d,
                f"decay_rate_1_s * duration_s = {d * t:.4g} exceeds {MAX_DECAY_TIMES_DURATION:g}: the filter would "
                "be numerically meaningless (plant damping ratio too close to 1)",
            )
        object.__setattr__(self, "duration_s", t)
        object.__setattr__(self, "decay_rate_1_s", d)

    @property
    def sigma_1_s(self) -> float:
        """The paper's sigma_i (eqs. 10-14): the exponent of the impulse response, -decay_rate_1_s."""
        return -self.decay_rate_1_s

    @property
    def half_angular_rate_rad_s(self) -> float:
        """a = pi/T: the frequency of the sinusoidal filters' impulse response (eqs. 4, 14)."""
        return math.pi / self.duration_s

    @property
    def order(self) -> int:
        """Order of the rational part R(s); each filter raises the continuity of its input by it."""
        return 2 if self.kind in SINUSOIDAL else 1

    # --- the factorisation F(s) = (c0 + c1 e^(-sT)) R(s) -----------------------------------
    @property
    def delay_coefficients(self) -> tuple[float, float]:
        """(c0, c1): weights of the delays 0 and T (see the module docstring)."""
        t, sigma = self.duration_s, self.sigma_1_s
        if self.kind == "rectangular" or (self.kind == "exponential" and sigma == 0.0):
            return 1.0 / t, -1.0 / t
        if self.kind == "exponential":
            c = 1.0 / (t * float(_phi(np.array(sigma * t)).real))  # sigma/(e^(sigma T) - 1)
            return c, -c * math.exp(sigma * t)
        a = self.half_angular_rate_rad_s
        if self.kind == "harmonic":
            return 0.5 * a * a, 0.5 * a * a  # eq. (5)
        k = (a * a + sigma * sigma) / (1.0 + math.exp(sigma * t))  # eq. (10)
        return k, k * math.exp(sigma * t)

    def realisation(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(A, b, c) of R(s): 1/(s - sigma), or 1/((s - sigma)^2 + a^2) as [x, x']."""
        sigma = self.sigma_1_s if self.kind in DAMPED else 0.0
        if self.order == 1:
            return np.array([[sigma]]), np.array([1.0]), np.array([1.0])
        a = self.half_angular_rate_rad_s
        return (
            np.array([[0.0, 1.0], [-(sigma * sigma + a * a), 2.0 * sigma]]),
            np.array([0.0, 1.0]),
            np.array([1.0, 0.0]),
        )

    # --- frequency domain ------------------------------------------------------------------
    def frequency_response(self, s: np.ndarray) -> np.ndarray:
        """F(s) at complex s: eqs. (1), (5), (10) and M_sigma(s) = phi((sigma - s)T)/phi(sigma T)."""
        return self._response(np.asarray(s, dtype=complex), shifted=False)

    def end_response(self, s: np.ndarray) -> np.ndarray:
        """F(s) e^(sT): bounded for Re s <= 0, so a residual exp(Re(p) t_end) |F(p)| never overflows."""
        return self._response(np.asarray(s, dtype=complex), shifted=True)

    def _response(self, s: np.ndarray, shifted: bool) -> np.ndarray:
        t, sigma = self.duration_s, self.sigma_1_s
        sign = 1.0 if shifted else -1.0
        if self.kind == "rectangular" or (self.kind == "exponential" and sigma == 0.0):
            return _phi(sign * s * t)  # (1 - e^(-sT))/(sT), or (e^(sT) - 1)/(sT)
        if self.kind == "exponential":
            base = _phi(sign * (s - sigma) * t) / _phi(np.array(sigma * t))
            return base * math.exp(sigma * t) if shifted else base
        a = self.half_angular_rate_rad_s
        if self.kind == "harmonic":
            gain, u = 0.5 * a * a, s
        else:
            gain, u = (a * a + sigma * sigma) / (1.0 + math.exp(sigma * t)), s - sigma
        if shifted:  # F(s) e^(sT) = gain e^(sigma T) (1 + e^(uT))/(u^2 + a^2)
            return gain * math.exp(sigma * t if self.kind == "damped_harmonic" else 0.0) * _sinusoidal_kernel(-u, t)
        return gain * _sinusoidal_kernel(u, t)

    def impulse_response(self, t: np.ndarray) -> np.ndarray:
        """f(t) in closed form (eqs. 4 and 14; sigma e^(sigma t)/(e^(sigma T) - 1) for M_sigma)."""
        t = np.asarray(t, dtype=float)
        inside = (t >= 0.0) & (t <= self.duration_s)
        sigma = self.sigma_1_s
        if self.kind in ("rectangular", "exponential"):
            c0, _ = self.delay_coefficients
            value = c0 * np.exp(sigma * t)
        else:
            a = self.half_angular_rate_rad_s
            if self.kind == "harmonic":
                value = 0.5 * a * np.sin(a * t)  # (pi/2T) sin(pi t/T), eq. (4)
            else:
                k = (a * a + sigma * sigma) / (1.0 + math.exp(sigma * self.duration_s))
                value = k / a * np.exp(sigma * t) * np.sin(a * t)  # eq. (14)
        return np.where(inside, value, 0.0)


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

    def frequency_response(self, s: np.ndarray) -> np.ndarray:
        """prod_i F_i(s) at complex s (the chain's transfer function)."""
        s = np.asarray(s, dtype=complex)
        out = np.ones_like(s)
        for f in self.filters:  # a loop over filters
            out = out * f.frequency_response(s)
        return out

    def end_response(self, s: np.ndarray) -> np.ndarray:
        """prod_i F_i(s) e^(s T_tot), bounded for Re s <= 0."""
        s = np.asarray(s, dtype=complex)
        out = np.ones_like(s)
        for f in self.filters:
            out = out * f.end_response(s)
        return out

    def impulses(self, displacement: float) -> tuple[np.ndarray, np.ndarray]:
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
        merged_w = np.bincount(group, weights=weights)
        return merged_t, merged_w

    @cached_property
    def cascade(self) -> tuple[np.ndarray, np.ndarray]:
        """(A, c) of 1/s * prod R_i(s), the first state taking the impulses; y = c x."""
        blocks = [(np.array([[0.0]]), np.array([1.0]), np.array([1.0]))] + [f.realisation() for f in self.filters]
        size = sum(b[0].shape[0] for b in blocks)
        a = np.zeros((size, size))
        start, prev_c, prev_start = 0, None, 0
        for block_a, block_b, block_c in blocks:  # a loop over filters
            k = block_a.shape[0]
            a[start : start + k, start : start + k] = block_a
            if prev_c is not None:
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
    time_s: np.ndarray
    derivatives: np.ndarray
    breakpoints_s: np.ndarray  # where a derivative of order continuous_derivatives + 1 jumps

    @property
    def position(self) -> np.ndarray:
        return self.derivatives[0]

    def derivative(self, m: int) -> np.ndarray:
        return self.derivatives[m] if m < self.derivatives.shape[0] else np.zeros_like(self.time_s)

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


def sample_grid(breakpoints_s: np.ndarray, end_s: float, sample_period_s: float, offset_s: float = 0.0) -> np.ndarray:
    """offset + k Ts for k = 0, 1, ... up to ``end_s``, with the breakpoints added (as
    PiecewiseCommand.resampled): a grid point closer than 1 ns to a breakpoint is replaced by it."""
    count = max(0, math.floor((end_s - offset_s) / sample_period_s + 1e-9) + 1)
    grid = offset_s + sample_period_s * np.arange(count)
    idx = np.searchsorted(breakpoints_s, grid)
    before = breakpoints_s[np.clip(idx - 1, 0, breakpoints_s.size - 1)]
    after = breakpoints_s[np.clip(idx, 0, breakpoints_s.size - 1)]
    near = np.minimum(np.abs(grid - before), np.abs(grid - after)) < MIN_STEP_S
    return np.union1d(grid[~near], breakpoints_s)


def _powers(phi: np.ndarray, count: int) -> list[np.ndarray]:
    """phi^(2^m) for 2^m < count, by repeated squaring."""
    out = [phi]
    while 2 ** len(out) < count:
        out.append(out[-1] @ out[-1])
    return out


def _propagate(a: np.ndarray, x0: np.ndarray, offset_s: float, count: int, powers: list[np.ndarray]) -> np.ndarray:
    """States at offset + k Ts for k < count from x(0) = x0: expm(offset A) x0, then doubling."""
    x = (expm(offset_s * a) @ x0)[:, None]
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


def mode_residuals(chain: Chain, plant: Plant, displacement: float) -> tuple[np.ndarray, np.ndarray]:
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


# ------------------------------------------------------------------------------------------
# Discrete-time filters for drives (eq. 17)


@dataclass(frozen=True)
class DiscreteFilter:
    """H(z) = gain * sum_i numerator[i] z^-i / sum_i denominator[i] z^-i, at ``sample_period_s``."""

    kind: FilterKind
    samples: int  # N: the filter lasts N Ts
    sample_period_s: float
    numerator: np.ndarray
    denominator: np.ndarray
    gain: float

    @property
    def duration_s(self) -> float:
        return self.samples * self.sample_period_s

    def transfer(self, z: np.ndarray) -> np.ndarray:
        """H(z) at complex z (Horner in z^-1; scipy.signal.freqz only evaluates on the unit circle)."""
        w = 1.0 / np.asarray(z, dtype=complex)
        return self.gain * np.polyval(self.numerator[::-1], w) / np.polyval(self.denominator[::-1], w)

    def filter(self, values: np.ndarray) -> np.ndarray:
        """The filter applied to a sampled signal (from rest), by scipy.signal.lfilter."""
        return lfilter(self.gain * self.numerator, self.denominator, np.asarray(values, dtype=float))


def discrete_filter(smoother: Smoother, sample_period_s: float, samples: int) -> DiscreteFilter:
    """The Z-transform of the impulse response sampled at k Ts, k = 1..N, with unit static gain.

    For S_sigma this is eq. (17): K (z^-1 + e^(sigma N Ts) z^-(N+1)) / (1 - 2 e^(sigma Ts) cos(pi/N) z^-1 +
    e^(2 sigma Ts) z^-2), K = (1 - 2 e^(sigma Ts) cos(pi/N) + e^(2 sigma Ts))/(1 + e^(sigma N Ts)); sigma = 0
    gives S. The same construction gives M_sigma: K (z^-1 - e^(sigma N Ts) z^-(N+1))/(1 - e^(sigma Ts) z^-1),
    K = (1 - e^(sigma Ts))/(1 - e^(sigma N Ts)), and M: (1/N) sum_{k=1..N} z^-k (written as an FIR, which has
    no pole on the unit circle). Being a rectangle-rule sum, each sinusoidal stage leads its continuous
    filter by about half a sample (PAPER-NOTES); the rectangular and exponential ones are exact at the samples.
    Its zeros lie at z = e^(sigma Ts) e^(j (2m+1) pi / N) (sinusoidal) or e^(sigma Ts) e^(j 2 m pi/N): they
    cancel the plant's pole only when N Ts equals the tuned duration.
    """
    n = int(samples)
    ts = float(sample_period_s)
    minimum = 2 if smoother.kind in SINUSOIDAL else 1
    if n < minimum:
        raise InvalidParameter("samples", n, f"a {smoother.kind} filter needs at least {minimum} samples")
    sigma = smoother.sigma_1_s
    num = np.zeros(n + 2)
    if smoother.kind == "rectangular" or (smoother.kind == "exponential" and sigma == 0.0):
        num[1 : n + 1] = 1.0
        return DiscreteFilter(smoother.kind, n, ts, num[: n + 1], np.array([1.0]), 1.0 / n)
    if smoother.kind == "exponential":
        r = math.exp(sigma * ts)
        end = math.exp(sigma * n * ts)
        num[1], num[n + 1] = 1.0, -end
        gain = -math.expm1(sigma * ts) / -math.expm1(sigma * n * ts)
        return DiscreteFilter(smoother.kind, n, ts, num, np.array([1.0, -r]), gain)
    r = math.exp(sigma * ts)
    end = math.exp(sigma * n * ts)
    cos = math.cos(math.pi / n)
    den = np.array([1.0, -2.0 * r * cos, r * r])
    num[1], num[n + 1] = 1.0, end
    gain = float(np.sum(den)) / (1.0 + end)
    return DiscreteFilter(smoother.kind, n, ts, num, den, gain)


def discrete_step_response(
    filters: list[DiscreteFilter] | tuple[DiscreteFilter, ...], displacement: float, count: int
) -> np.ndarray:
    """y[k], k = 0..count-1, of the discrete chain fed with a step of ``displacement`` at k = 0."""
    y = np.full(count, float(displacement))
    for f in filters:  # a loop over filters
        y = f.filter(y)
    return y
