"""Modes with 95 % intervals from a resonance test's spectrum: Klipper's PSD of a swept excitation, read from its CSV
or computed from the test's raw record.

The model (per accelerometer axis a, Welch bin F up to 200 Hz):

    P_a(F) = g_a M(F; theta) + n_a,   M(F) = (1/K) sum_k |sum_i s_i Y_ik(F)|^2

- Y_ik is Welch segment k's windowed DFT (Klipper's segments, Kaiser(6), half overlap, each segment's mean removed,
  density scaling) of mode i's response to the test's command (optim.identification.resonance_test), the
  base-excited mode (2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2) simulated exactly at the samples for the command's
  switches between them (models.held_input). The sweep's own distortion of a peak (a mode's ring-down lags the
  sweep) is thus in the model, not a bias.
- theta = (f_i, zeta_i), s_1 = 1 and s_i (i >= 2) the modes' gains relative to the first; g_a and n_a (the axis's
  gain and white-noise floor) are solved linearly for each theta (variable projection).

The Welch estimate's covariance, for white noise of floor n_a and the deterministic response S_k = sqrt(g_a) Y_k
(circular Gaussian noise; c_m = sum_j w_j^2 e^(-2 pi i m j / N) / sum_j w_j^2, the window's bin correlation):

    Cov(P(F), P(F')) = (1/K) [ g_a mean_k 2 Re(Y_kF* Y_kF' c_(F-F')) n_a + n_a^2 |c_(F-F')|^2 ]

plus the same terms between half-overlapping segments k and k + 1, with e_m (the window times itself half a segment
on) and a sign (-1)^F in place of c_m (checked against a Monte-Carlo of the estimate in tests/optim/test_sweep_fit.py),
plus, for a CSV, the variance of its 4 significant digits (uniform rounding: step^2 / 12), and a model error of
MODEL_ERROR of the PSD. The fit is generalised least squares whitened by that covariance's Cholesky factor, the
covariance re-estimated from the fit (WEIGHTINGS passes, the first with rough diagonal weights); the intervals come
from the whitened Jacobian, scaled by max(1, chi^2 / dof).

Modes start at psd_peaks' peaks. While chi^2 fails its test at ALPHA, a mode is added at the bin whose excess over the
fit is largest (more than MATCH from the modes), kept if the F-test of the chi^2 drop passes at ALPHA (at most
MAX_ADDED). A mode whose frequency or damping ends on its bound is not reported (a warning says so).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import solve_triangular
from scipy.optimize import least_squares
from scipy.stats import chi2 as chi_squared
from scipy.stats import f as fisher
from scipy.stats import norm

from models.held_input import base_excited_response
from optim.identification.modal import FittedMode, interval_fields
from optim.identification.resonance_test import ResonanceTest, check_test, command_switches
from optim.identification.sweep_spectrum import MeasuredSpectrum, welch_segments, window_correlation

__all__ = ["SpectralMode", "SweepIdentification", "identify_sweep"]

Array = NDArray[np.float64]
WEIGHTINGS = 3
MODEL_ERROR = 2e-3  # of the PSD: the model's own error (the test's phase against Klipper's segments)
ROUGH_ERROR = 0.1  # the first pass's diagonal weights: 10 % of the PSD and of its median
ALPHA = 1e-3
MATCH = 0.05  # an added mode is at least this (relative) from the others
MAX_ADDED = 2
MAX_EVALUATIONS_PER_PARAMETER = 40  # least-squares evaluations per parameter and pass (units of work)
CACHED_MODES = 16  # mode spectra kept (each K x bins complex values)
MAX_SIMULATIONS = 300  # the test simulated through a mode, per identification (units of work: 25-80 typically)
FREQUENCY_RANGE = (0.8, 1.2)  # of the starting frequency
DAMPING_RANGE = (1e-3, 0.5)
START_DAMPING = (0.01, 0.3)  # the half-power estimate, clipped
ADDED_DAMPING = 0.05
ADDED_GAIN = 0.3
CONFIDENCE = 0.95


@dataclass(frozen=True)
class SpectralMode(FittedMode):
    relative_gain: float  # s_i: the mode's gain over the first mode's
    peak_frequency_hz: float  # where the fit started (a PSD peak, or the bin added)


@dataclass(frozen=True)
class SweepIdentification:
    modes: tuple[SpectralMode, ...]  # lowest frequency first
    reduced_chi_squared: float  # chi^2 / dof of the whitened fit: about 1 when the model holds
    bins: int
    segments: int
    simulations: int  # the test simulated through a mode (units of work)
    warnings: tuple[str, ...] = field(default=())


class _OutOfWork(Exception):
    """MAX_SIMULATIONS, or a pass's evaluations, spent: the fit under way is no optimum."""


class _ModeSpectra:
    """Y_i for (f, zeta): the test simulated through one mode and cut into Welch segments, the last CACHED_MODES
    kept; ``simulations`` counts the work."""

    def __init__(self, test: ResonanceTest, spectrum: MeasuredSpectrum) -> None:
        self.switches = command_switches(test, spectrum.rate_hz, spectrum.samples)
        self.rate_hz = spectrum.rate_hz
        self.segment = spectrum.segment
        self.bins = np.rint(spectrum.frequency_hz * spectrum.segment / spectrum.rate_hz).astype(int)
        self.cache: dict[tuple[float, float], NDArray[np.complex128]] = {}
        self.simulations = 0

    def of(self, f_hz: float, zeta: float) -> NDArray[np.complex128]:
        key = (f_hz, zeta)
        if key not in self.cache:
            if self.simulations >= MAX_SIMULATIONS:
                raise _OutOfWork
            if len(self.cache) >= CACHED_MODES:
                self.cache.pop(next(iter(self.cache)))
            times, levels, samples = self.switches
            response = base_excited_response(f_hz, zeta, self.rate_hz, times, levels, samples)
            self.cache[key] = welch_segments(response, self.segment, self.rate_hz)[:, self.bins]
            self.simulations += 1
        return self.cache[key]

    def combined(self, x: Array, n: int) -> NDArray[np.complex128]:
        """sum_i s_i Y_i for x = (f_1, zeta_1, ..., f_n, zeta_n, s_2, ..., s_n)."""
        total = self.of(float(x[0]), float(x[1])).copy()
        for i in range(1, n):
            total += x[2 * n + i - 1] * self.of(float(x[2 * i]), float(x[2 * i + 1]))
        return total


@dataclass(frozen=True)
class _Fit:
    x: Array
    covariance: Array
    chi_squared: float
    dof: int
    excess: Array  # (bins,): the data over the model in standard deviations, summed over the axes
    active: NDArray[np.bool_]  # the parameters on a bound


def _covariance(
    y: NDArray[np.complex128],
    bins: NDArray[np.intp],
    gain: float,
    floor: float,
    segments: int,
    correlation: tuple[NDArray[np.complex128], NDArray[np.complex128]],
) -> Array:
    """The Welch estimate's covariance over the bins for one axis (see the module), without the rounding: the terms
    of each segment with itself and with its half-overlapping neighbours."""
    c, e = correlation
    count = y.shape[1]
    cov = np.zeros((count, count))
    g = max(gain, 0.0)
    for m in range(min(c.size, count)):
        a, b = y[:, : count - m], y[:, m:]
        same = np.mean(2.0 * np.real(np.conj(a) * b * np.conj(c[m])), axis=0)
        sign = np.where(bins[: count - m] % 2 == 0, 1.0, -1.0)  # (-1)^F
        later = np.sum(2.0 * np.real(np.conj(a[:-1]) * b[1:] * np.conj(e[m])), axis=0) * sign
        earlier = np.sum(2.0 * np.real(np.conj(a[1:]) * b[:-1] * np.conj(e[m])), axis=0) * sign * (-1.0) ** m
        neighbours = (later + earlier) / y.shape[0]
        band = (g * (same + neighbours) * floor + floor**2 * (abs(c[m]) ** 2 + 2.0 * abs(e[m]) ** 2)) / segments
        cov[np.arange(count - m), np.arange(m, count)] = band
        cov[np.arange(m, count), np.arange(count - m)] = band
    return cov


def _whiteners(spectrum: MeasuredSpectrum, y: NDArray[np.complex128] | None, coefs: list[Array]) -> list[Array]:
    """Each axis's Cholesky factor L of the PSD's covariance (rough diagonal weights without a fit)."""
    correlation = window_correlation(spectrum.segment)
    bins = np.rint(spectrum.frequency_hz * spectrum.segment / spectrum.rate_hz).astype(np.intp)
    out = []
    for a, p in enumerate(spectrum.psd):
        model = np.diag(spectrum.rounding_variance[a] + (MODEL_ERROR * p) ** 2 + 1e-300)
        if y is None:
            rough = (ROUGH_ERROR * p) ** 2 + (ROUGH_ERROR * float(np.median(p))) ** 2
            out.append(np.diag(np.sqrt(np.diag(model) + rough)))
        else:
            gain, floor = float(coefs[a][0]), max(float(coefs[a][1]), 0.0)
            covariance = _covariance(y, bins, gain, floor, spectrum.segments, correlation)
            out.append(np.linalg.cholesky(covariance + model))
    return out


def _projection(
    y: NDArray[np.complex128], spectrum: MeasuredSpectrum, whiteners: list[Array]
) -> tuple[list[Array], Array]:
    """(each axis's (g_a, n_a), the whitened residual over the axes) for the combined mode spectra y."""
    m = np.mean(np.abs(y) ** 2, axis=0)
    design = np.column_stack([m, np.ones_like(m)])
    coefs, residual = [], []
    for p, lower in zip(spectrum.psd, whiteners, strict=True):
        a_w = solve_triangular(lower, design, lower=True)
        p_w = solve_triangular(lower, p, lower=True)
        coef, *_ = np.linalg.lstsq(a_w, p_w, rcond=None)
        coefs.append(coef)
        residual.append(a_w @ coef - p_w)
    return coefs, np.concatenate(residual)


def _bounds(starts: list[tuple[float, float]]) -> tuple[Array, Array]:
    n = len(starts)
    low = [v for f, _ in starts for v in (FREQUENCY_RANGE[0] * f, DAMPING_RANGE[0])] + [-10.0] * (n - 1)
    high = [v for f, _ in starts for v in (FREQUENCY_RANGE[1] * f, DAMPING_RANGE[1])] + [10.0] * (n - 1)
    return np.asarray(low), np.asarray(high)


def _fit(spectra: _ModeSpectra, spectrum: MeasuredSpectrum, starts: list[tuple[float, float]], x0: Array) -> _Fit:
    """The GLS fit of len(starts) modes from x0 (see the module): WEIGHTINGS passes, each re-weighting by the last."""
    n = len(starts)
    low, high = _bounds(starts)
    x = np.clip(x0, low, high)
    whiteners = _whiteners(spectrum, None, [])
    solution = None
    for _ in range(WEIGHTINGS):
        solution = least_squares(
            lambda v, w=whiteners: _projection(spectra.combined(v, n), spectrum, w)[1],
            x,
            bounds=(low, high),
            x_scale=np.maximum(np.abs(x), 1e-2),
            diff_step=1e-7,
            method="trf",
            max_nfev=MAX_EVALUATIONS_PER_PARAMETER * x.size,
        )
        x = np.asarray(solution.x, float)
        y = spectra.combined(x, n)
        coefs, _ = _projection(y, spectrum, whiteners)
        whiteners = _whiteners(spectrum, y, coefs)
    assert solution is not None
    if solution.status == 0:  # its evaluations spent: no optimum
        raise _OutOfWork
    y = spectra.combined(x, n)
    coefs, residual = _projection(y, spectrum, whiteners)
    chi2 = float(residual @ residual)
    dof = max(residual.size - x.size - 2 * spectrum.psd.shape[0], 1)
    jac = np.asarray(solution.jac, float)  # the last pass's whitened Jacobian at x
    covariance = np.linalg.pinv(jac.T @ jac) * max(1.0, chi2 / dof)
    m = np.mean(np.abs(y) ** 2, axis=0)
    model = np.array([c[0] * m + c[1] for c in coefs])
    std = np.sqrt(np.array([np.diag(lower @ lower.T) for lower in whiteners]))
    excess = np.sum((spectrum.psd - model) / std, axis=0)
    active = (x <= low + 1e-9 * np.abs(low)) | (x >= high - 1e-9 * np.abs(high))
    return _Fit(x, covariance, chi2, dof, excess, active)


def _misfit(fit: _Fit) -> bool:
    return fit.chi_squared > float(chi_squared.ppf(1.0 - ALPHA, fit.dof))


def _added(fit: _Fit, spectrum: MeasuredSpectrum, starts: list[tuple[float, float]]) -> tuple[float, float] | None:
    """The bin of largest excess over the fit more than MATCH from every mode, as a start, or None."""
    f = spectrum.frequency_hz
    far = np.all([np.abs(f - fit.x[2 * i]) > MATCH * fit.x[2 * i] for i in range(len(starts))], axis=0)
    if not np.any(far & (fit.excess > 0.0)):
        return None
    k = int(np.argmax(np.where(far, fit.excess, -np.inf)))
    return float(f[k]), ADDED_DAMPING


def _better(richer: _Fit, poorer: _Fit) -> bool:
    """The F-test at ALPHA of the chi^2 drop for the 3 parameters a mode adds."""
    if richer.chi_squared >= poorer.chi_squared:
        return False
    ratio = (poorer.chi_squared - richer.chi_squared) / 3.0 / (richer.chi_squared / richer.dof)
    return ratio > float(fisher.ppf(1.0 - ALPHA, 3, richer.dof))


def _with_mode(x: Array, n: int, start: tuple[float, float]) -> Array:
    """x with one more mode at ``start`` (its relative gain ADDED_GAIN)."""
    return np.concatenate([x[: 2 * n], list(start), x[2 * n :], [ADDED_GAIN]])


def _modes(fit: _Fit, starts: list[tuple[float, float]], scale_std: float) -> tuple[list[SpectralMode], list[str]]:
    n = len(starts)
    quantile = float(norm.ppf(0.5 + CONFIDENCE / 2.0))
    modes, warnings = [], []
    for i, (f0, _) in enumerate(starts):
        f, zeta = float(fit.x[2 * i]), float(fit.x[2 * i + 1])
        sf, sz = (math.sqrt(max(float(fit.covariance[k, k]), 0.0)) for k in (2 * i, 2 * i + 1))
        sf = math.hypot(sf, f * scale_std)  # every frequency scales with the bins' spacing
        if fit.active[2 * i] or fit.active[2 * i + 1] or not (math.isfinite(sf) and math.isfinite(sz)):
            warnings.append(
                f"the component started at {f0:.4g} Hz ended on its bounds ({f:.4g} Hz, damping ratio {zeta:.3g}): "
                "not reported as a mode"
            )
            continue
        gain = 1.0 if i == 0 else float(fit.x[2 * n + i - 1])
        modes.append(
            SpectralMode(
                natural_frequency_hz=f,
                damping_ratio=zeta,
                **interval_fields(f, sf, zeta, sz, quantile),
                relative_gain=gain,
                peak_frequency_hz=f0,
            )
        )
    return sorted(modes, key=lambda m: m.natural_frequency_hz), warnings


def identify_sweep(
    spectrum: MeasuredSpectrum, test: ResonanceTest, peaks: list[tuple[float, float]], max_modes: int
) -> SweepIdentification:
    """Modes with 95 % intervals from a resonance test's PSD (see the module), started at ``peaks`` ((Hz, half-power
    damping), at most ``max_modes``)."""
    if spectrum.frequency_hz.size == 0:
        return SweepIdentification((), math.nan, 0, spectrum.segments, 0, ("no bin within the test's band to fit",))
    check_test(test, spectrum.rate_hz)
    top = float(spectrum.frequency_hz[-1])
    warnings = [
        f"the peak at {f:.4g} Hz lies above the test's max_freq ({test.max_freq_hz:g} Hz): not fitted (a test "
        "that swept further needs its sweep_max_freq)"
        for f, _ in peaks
        if f > top
    ]
    inside = [(f, z) for f, z in peaks if f <= top]
    if not inside:
        reason = "no peak within the test's band to fit"
        return SweepIdentification((), math.nan, spectrum.frequency_hz.size, spectrum.segments, 0, (*warnings, reason))
    spectra = _ModeSpectra(test, spectrum)
    starts = [(f, float(np.clip(z, *START_DAMPING))) for f, z in inside[:max_modes]]
    x0 = np.array([v for s in starts for v in s] + [ADDED_GAIN] * (len(starts) - 1))
    try:
        fit = _fit(spectra, spectrum, starts, x0)
    except _OutOfWork:
        reason = (
            f"the fit did not converge within its work ({MAX_SIMULATIONS} simulations of the test, "
            f"{MAX_EVALUATIONS_PER_PARAMETER} evaluations per parameter and pass): no mode is reported"
        )
        count = spectrum.frequency_hz.size
        return SweepIdentification((), math.nan, count, spectrum.segments, MAX_SIMULATIONS, (*warnings, reason))
    for _ in range(MAX_ADDED):
        start = _added(fit, spectrum, starts) if _misfit(fit) and len(starts) < max_modes else None
        if start is None:
            break
        try:
            richer = _fit(spectra, spectrum, [*starts, start], _with_mode(fit.x, len(starts), start))
        except _OutOfWork:
            warnings.append(f"a mode at {start[0]:.4g} Hz was not tried to the end (its work spent)")
            break
        if not _better(richer, fit):
            break
        fit, starts = richer, [*starts, start]
    modes, dropped = _modes(fit, starts, spectrum.frequency_scale_std)
    warnings += dropped
    reduced = fit.chi_squared / fit.dof
    if _misfit(fit):
        warnings.append(
            f"the test's model does not fit the spectrum (chi^2/dof {reduced:.3g}): the intervals are widened by "
            f"sqrt({reduced:.3g}); check the test's settings (sweep_min_freq, sweep_max_freq, sweep_hz_per_sec, "
            "sweeping_period)"
        )
    return SweepIdentification(
        tuple(modes), reduced, spectrum.frequency_hz.size, spectrum.segments, spectra.simulations, tuple(warnings)
    )
