"""Trajectory smoothers' filters (Biagiotti, Melchiorri and Moriello 2020, "Damped harmonic smoother
for trajectory planning and vibration suppression"): one filter, continuous and discrete.

Filters, each of duration T and unit static gain (impulse response on [0, T]):

- ``rectangular`` M (eq. 1): 1/T.
- ``harmonic`` S (eqs. 4-5): (pi/2T) sin(pi t/T).
- ``damped_harmonic`` S_sigma (eqs. 10, 14): K (T/pi) e^(sigma t) sin(pi t/T),
  K = ((pi/T)^2 + sigma^2)/(1 + e^(sigma T)).
- ``exponential`` M_sigma (the damped rectangular filter of the paper's ref. [20], Sec. V):
  sigma e^(sigma t)/(e^(sigma T) - 1).

Sign convention: the paper's sigma is the exponent of the impulse response (negative for a stable
plant); the service's ``decay_rate_1_s`` is -sigma >= 0, as ``models.plants.Mode.decay_rate_1_s``.

Every filter is a delay polynomial times a rational part, F(s) = (c0 + c1 e^(-sT)) R(s):
M = (1 - e^(-sT))/T * 1/s; M_sigma = c (1 - e^(sigma T) e^(-sT)) * 1/(s - sigma); S = (a^2/2)(1 + e^(-sT)) *
1/(s^2 + a^2); S_sigma = K (1 + e^(sigma T) e^(-sT)) * 1/((s - sigma)^2 + a^2), with a = pi/T. Chains of
them and their step responses are in ``models.smoothers``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import lfilter

from models.errors import InvalidParameter

FilterKind = Literal["rectangular", "harmonic", "damped_harmonic", "exponential"]
FILTER_KINDS: tuple[str, ...] = ("rectangular", "harmonic", "damped_harmonic", "exponential")
SINUSOIDAL = ("harmonic", "damped_harmonic")
DAMPED = ("damped_harmonic", "exponential")

MAX_DURATION_S = 1e5
MIN_DURATION_S = 1e-6
MAX_DECAY_RATE_1_S = 1e7
# e^(sigma T) and e^(-sigma T) stay far from overflow; a plant with zeta < 0.99 tuned at 3 pi/Omega has 66.
MAX_DECAY_TIMES_DURATION = 200.0


# ------------------------------------------------------------------------------------------
# Continuous filters


PHI_SERIES_BELOW = 1e-5  # |z| below which expm1(z)/z is its series 1 + z/2 + z^2/6 (next term < 5e-17)


def _phi(z: ArrayLike) -> NDArray[np.complex128]:
    """expm1(z)/z with its limit 1 at z = 0 (complex, vectorised). Near 0 it is the series 1 + z/2 + z^2/6:
    numpy's complex division overflows for a subnormal z (1e-320 / 1e-320 is inf + nan j), which a decay rate of
    a damping ratio near the smallest double gives."""
    z = np.asarray(z, dtype=complex)
    out = np.asarray(1.0 + z / 2.0 + z * z / 6.0, dtype=complex)
    far = np.abs(z) >= PHI_SERIES_BELOW
    with np.errstate(over="ignore", invalid="ignore"):
        out[far] = np.expm1(z[far]) / z[far]
    return out


def _sinusoidal_kernel(u: NDArray[np.complex128], duration_s: float) -> NDArray[np.complex128]:
    """(1 + e^(-uT)) / (u^2 + a^2), a = pi/T: the transform of e^(...) sin(a t) on [0, T] up to a gain.

    Near its removable poles u = +-ja the direct form cancels; there it is written as
    T/(2ja) [phi(-(u - ja)T) - phi(-(u + ja)T)] (1 + e^(-uT) = 1 - e^(-(u -+ ja)T) since aT = pi).
    """
    u = np.asarray(u, dtype=complex)
    t = duration_s
    a = math.pi / t
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        direct: NDArray[np.complex128] = (1.0 + np.exp(-u * t)) / (u * u + a * a)
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

    def realisation(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
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
    def frequency_response(self, s: ArrayLike) -> NDArray[np.complex128]:
        """F(s) at complex s: eqs. (1), (5), (10) and M_sigma(s) = phi((sigma - s)T)/phi(sigma T)."""
        return self._response(np.asarray(s, dtype=complex), shifted=False)

    def end_response(self, s: ArrayLike) -> NDArray[np.complex128]:
        """F(s) e^(sT): bounded for Re s <= 0, so a residual exp(Re(p) t_end) |F(p)| never overflows."""
        return self._response(np.asarray(s, dtype=complex), shifted=True)

    def _response(self, s: NDArray[np.complex128], shifted: bool) -> NDArray[np.complex128]:
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

    def impulse_response(self, t: ArrayLike) -> NDArray[np.float64]:
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
        response: NDArray[np.float64] = np.where(inside, value, 0.0)
        return response


# ------------------------------------------------------------------------------------------
# Discrete-time filters for drives (eq. 17)


@dataclass(frozen=True)
class DiscreteFilter:
    """H(z) = gain * sum_i numerator[i] z^-i / sum_i denominator[i] z^-i, at ``sample_period_s``."""

    kind: FilterKind
    samples: int  # N: the filter lasts N Ts
    sample_period_s: float
    numerator: NDArray[np.float64]
    denominator: NDArray[np.float64]
    gain: float

    @property
    def duration_s(self) -> float:
        return self.samples * self.sample_period_s

    def transfer(self, z: ArrayLike) -> NDArray[np.complex128]:
        """H(z) at complex z (Horner in z^-1; scipy.signal.freqz only evaluates on the unit circle)."""
        w = 1.0 / np.asarray(z, dtype=complex)
        h: NDArray[np.complex128] = (
            self.gain * np.polyval(self.numerator[::-1], w) / np.polyval(self.denominator[::-1], w)
        )
        return h

    def filter(self, values: ArrayLike) -> NDArray[np.float64]:
        """The filter applied to a sampled signal (from rest), by scipy.signal.lfilter."""
        filtered: NDArray[np.float64] = lfilter(
            self.gain * self.numerator, self.denominator, np.asarray(values, dtype=float)
        )
        return filtered


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


def discrete_step_response(filters: Sequence[DiscreteFilter], displacement: float, count: int) -> NDArray[np.float64]:
    """y[k], k = 0..count-1, of the discrete chain fed with a step of ``displacement`` at k = 0."""
    y = np.full(count, float(displacement))
    for f in filters:  # a loop over filters
        y = f.filter(y)
    return y
