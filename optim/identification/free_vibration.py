"""A vibration mode identified from a recorded free vibration (Biagiotti, Melchiorri and Moriello 2020, Sec. V-A).

Eq. (16) reads the damped period T0 = t2 - t1 and the decay sigma = ln(p2/p1)/T0 off two successive
peaks (``two_peak_estimate``), which tune S_sigma with T = 3/2 T0 (eq. 15). ``identify`` fits instead a
damped sinusoid A e^(sigma t) cos(Omega t + phi) + offset to the whole record by least squares
(scipy.optimize.least_squares), which is far less sensitive to noise than two peaks, and refuses records
that hold no clear free vibration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.signal import find_peaks

from models.commands import check_time_grid
from models.errors import InvalidParameter
from models.plants import Mode

__all__ = [
    "MIN_PERIODS",
    "MIN_RECORD_SAMPLES",
    "MIN_R_SQUARED",
    "MIN_SAMPLES_PER_PERIOD",
    "MIN_SIGNAL_TO_NOISE",
    "Identification",
    "identify",
    "two_peak_estimate",
]


MIN_RECORD_SAMPLES = 16
MIN_PERIODS = 2.0
MIN_R_SQUARED = 0.5
MIN_SIGNAL_TO_NOISE = 3.0
MIN_SAMPLES_PER_PERIOD = 4.0


@dataclass(frozen=True)
class Identification:
    """A damped sinusoid A e^(sigma t) cos(Omega t + phi) + offset fitted to a free vibration."""

    damped_angular_frequency_rad_s: float  # Omega
    decay_rate_1_s: float  # -sigma >= 0
    amplitude: float
    offset: float
    r_squared: float
    rms_residual: float
    periods: float
    signal_to_noise: float
    frequency_std_rad_s: float
    decay_rate_std_1_s: float
    samples: int
    two_peak: tuple[float, float] | None  # (Omega, -sigma) by eq. (16), for comparison
    warnings: tuple[str, ...] = field(default=())

    @property
    def mode(self) -> Mode:
        omega_n = math.hypot(self.decay_rate_1_s, self.damped_angular_frequency_rad_s)
        return Mode(omega_n, self.decay_rate_1_s / omega_n)


def _refuse(reason: str, field_name: str = "signal", value: object = None) -> InvalidParameter:
    return InvalidParameter(field_name, value, reason)


def _initial_frequency(t: NDArray[np.float64], y: NDArray[np.float64]) -> float:
    """The spectral peak of the record resampled on a uniform grid (Hann window, zero-padded FFT,
    parabolic interpolation of the peak)."""
    n = int(min(max(t.size, 64), 1 << 16))
    grid = np.linspace(t[0], t[-1], n)
    u = np.interp(grid, t, y)
    u = (u - np.mean(u)) * np.hanning(n)
    size = 8 * (1 << math.ceil(math.log2(n)))
    spectrum = np.abs(np.fft.rfft(u, size))
    spectrum[0] = 0.0
    peak = int(np.argmax(spectrum))
    k: float = peak  # the peak's bin, interpolated between bins
    if 0 < peak < spectrum.size - 1:
        a, b, c = spectrum[peak - 1], spectrum[peak], spectrum[peak + 1]
        denom = a - 2 * b + c
        k = peak + (0.5 * (a - c) / denom if denom != 0 else 0.0)
    dt = (grid[-1] - grid[0]) / (n - 1)
    return float(2.0 * math.pi * k / (size * dt))


def two_peak_estimate(t: NDArray[np.float64], y: NDArray[np.float64], omega_guess: float) -> tuple[float, float] | None:
    """Eq. (16): T0 = t2 - t1 and sigma = ln(p2/p1)/T0 from the first two successive maxima of the
    record (offset removed by its median); returns (Omega, -sigma) or None when there are no two."""
    dt = float(np.median(np.diff(t)))
    distance = max(1, int(0.6 * (2 * math.pi / omega_guess) / dt))
    centred = y - np.median(y)
    peaks, _ = find_peaks(centred, distance=distance)
    peaks = peaks[centred[peaks] > 0]
    if peaks.size < 2:
        return None
    t1, t2 = t[peaks[0]], t[peaks[1]]
    p1, p2 = centred[peaks[0]], centred[peaks[1]]
    if t2 <= t1 or p2 <= 0:
        return None
    period = t2 - t1
    return 2 * math.pi / period, -math.log(p2 / p1) / period


def _basis(t: NDArray[np.float64], sigma: float, omega: float) -> NDArray[np.float64]:
    envelope = np.exp(np.clip(sigma * t, -700.0, 700.0))
    basis: NDArray[np.float64] = np.column_stack(
        [envelope * np.cos(omega * t), envelope * np.sin(omega * t), np.ones_like(t)]
    )
    return basis


def identify(time_s: NDArray[np.float64], signal: NDArray[np.float64]) -> Identification:
    """Omega and sigma of a free vibration (eq. 16's quantities) by least squares.

    The model y = e^(sigma t) (a cos Omega t + b sin Omega t) + c is linear in (a, b, c): for each
    (sigma, Omega) they are solved exactly (variable projection) and scipy.optimize.least_squares fits
    (sigma, Omega), started from the spectral peak and eq. (16)'s two-peak decay. Standard errors come
    from the full Jacobian at the optimum. A record is refused when it spans fewer than 2 periods, is
    sampled with fewer than 4 samples per period, or holds no oscillation clearly above its noise
    (R^2 < 0.5 or amplitude < 3 times the residual rms).
    """
    t_abs = check_time_grid(np.asarray(time_s, dtype=float), "time_s")
    y = np.asarray(signal, dtype=float)
    if y.shape != t_abs.shape:
        raise InvalidParameter("signal", f"{y.size} samples", f"must have as many samples as time_s ({t_abs.size})")
    if not np.all(np.isfinite(y)) or np.max(np.abs(y)) > 1e12:
        k = int(np.argmax(~np.isfinite(y) | (np.abs(y) > 1e12)))
        raise InvalidParameter(f"signal[{k}]", str(y[k]), "must be finite and within +-1e12")
    if t_abs.size < MIN_RECORD_SAMPLES:
        raise InvalidParameter("time_s", f"{t_abs.size} samples", f"needs at least {MIN_RECORD_SAMPLES} samples")
    t = t_abs - t_abs[0]
    spread = float(np.max(y) - np.min(y))
    if spread == 0.0:
        raise _refuse("the signal is constant: it holds no oscillation", value="constant")
    scale = spread / 2.0
    yn = (y - np.median(y)) / scale
    duration = float(t[-1])
    omega0 = _initial_frequency(t, yn)
    if not omega0 > 0.0:
        raise _refuse("the record holds no oscillation (no spectral peak)", value="no peak")
    peaks = two_peak_estimate(t, yn, omega0)
    decay0 = peaks[1] if peaks is not None and 0.0 <= peaks[1] < 10 * omega0 else 0.1 * omega0 / (2 * math.pi)

    def residual(params: NDArray[np.float64]) -> NDArray[np.float64]:
        basis = _basis(t, params[0], params[1])
        coef, *_ = np.linalg.lstsq(basis, yn, rcond=None)
        misfit: NDArray[np.float64] = basis @ coef - yn
        return misfit

    fits = [
        least_squares(
            residual,
            x0=np.array([-decay0, omega_start]),
            x_scale=np.array([max(decay0, 0.01 * omega0), omega0]),
            bounds=([-50.0 * omega0, 1e-3 * omega0], [10.0 * omega0 / max(duration * omega0, 1.0), 1e3 * omega0]),
            method="trf",
            xtol=1e-14,
            ftol=1e-14,
            gtol=1e-14,
            max_nfev=400,
        )
        for omega_start in (omega0, 0.97 * omega0, 1.03 * omega0)  # a few starts: the cost ripples in Omega
    ]
    best = min(fits, key=lambda fit: fit.cost)  # the first of the lowest cost, as a strict < scan keeps
    sigma, omega = float(best.x[0]), float(best.x[1])
    basis = _basis(t, sigma, omega)
    (a, b, c), *_ = np.linalg.lstsq(basis, yn, rcond=None)
    fitted = basis @ np.array([a, b, c])
    res = yn - fitted
    ss_res = float(np.sum(res**2))
    ss_tot = float(np.sum((yn - np.mean(yn)) ** 2))
    r2 = 1.0 - ss_res / ss_tot if ss_tot > 0 else 0.0
    rms = math.sqrt(ss_res / t.size)
    amplitude = math.hypot(a, b)
    snr = amplitude / rms if rms > 0 else math.inf
    periods = omega * duration / (2 * math.pi)
    samples_per_period = 2 * math.pi / (omega * float(np.median(np.diff(t))))
    # Standard errors from the Jacobian of the full model in (sigma, Omega, a, b, c).
    env = np.exp(np.clip(sigma * t, -700.0, 700.0))
    cos, sin = np.cos(omega * t), np.sin(omega * t)
    osc = a * cos + b * sin
    jac = np.column_stack([t * env * osc, t * env * (-a * sin + b * cos), env * cos, env * sin, np.ones_like(t)])
    dof = max(1, t.size - 5)
    try:
        cov = np.linalg.inv(jac.T @ jac) * ss_res / dof
        sigma_std, omega_std = math.sqrt(max(cov[0, 0], 0.0)), math.sqrt(max(cov[1, 1], 0.0))
    except np.linalg.LinAlgError:
        sigma_std = omega_std = math.inf
    if r2 < MIN_R_SQUARED or snr < MIN_SIGNAL_TO_NOISE:
        raise _refuse(
            f"the record holds no damped oscillation clearly above its noise: the best damped sinusoid "
            f"explains {100 * max(r2, 0.0):.3g} % of its variance (at least {100 * MIN_R_SQUARED:g} % needed) "
            f"with an amplitude {snr:.3g} times the residual rms (at least {MIN_SIGNAL_TO_NOISE:g} needed)",
            value=f"{t.size} samples",
        )
    if samples_per_period < MIN_SAMPLES_PER_PERIOD:
        raise _refuse(
            f"the fitted oscillation ({omega:.6g} rad/s) has only {samples_per_period:.2g} samples per period; "
            f"at least {MIN_SAMPLES_PER_PERIOD:g} are needed (sample faster)",
            "time_s",
            f"{t.size} samples",
        )
    if periods < MIN_PERIODS:
        raise _refuse(
            f"the record spans {periods:.3g} periods of the fitted oscillation ({omega:.6g} rad/s); at least "
            f"{MIN_PERIODS:g} are needed",
            "time_s",
            f"{duration:.6g} s",
        )
    warnings: list[str] = []
    decay = -sigma
    if decay < 0.0:
        if -decay <= 3.0 * sigma_std:
            warnings.append(
                f"the fitted decay rate {decay:.3g} 1/s is negative but within 3 standard errors of 0: set to 0"
            )
            decay = 0.0
        else:
            raise _refuse(
                f"the oscillation grows (decay rate {decay:.4g} 1/s): not the free vibration of a stable plant",
                value=f"{t.size} samples",
            )
    two_peak = None
    if peaks is not None:
        two_peak = (float(peaks[0]), float(peaks[1]))
    return Identification(
        damped_angular_frequency_rad_s=omega,
        decay_rate_1_s=decay,
        amplitude=amplitude * scale,
        offset=float(c * scale + np.median(y)),
        r_squared=r2,
        rms_residual=rms * scale,
        periods=periods,
        signal_to_noise=snr,
        frequency_std_rad_s=omega_std,
        decay_rate_std_1_s=sigma_std,
        samples=int(t.size),
        two_peak=two_peak,
        warnings=tuple(warnings),
    )
