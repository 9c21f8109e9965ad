"""Vibration modes identified from a measured record (one or more signals, e.g. an accelerometer's x, y, z).

The record is put on a uniform grid, the free vibration is located (after the known command ends, or from
the record's largest excursion), its spectrum estimated by Welch's method (``scipy.signal.welch``, a
rectangular window) and its peaks found (``scipy.signal.find_peaks``). The peaks start a nonlinear least-squares fit
(``scipy.optimize.least_squares``) of a sum of damped sinusoids with the decay rates and damped frequencies
shared by every signal and amplitudes, phases and offsets per signal:

    y_c(t) = sum_k e^(-s_k t) (a_ck cos w_k t + b_ck sin w_k t) + d_c

solved by variable projection (the linear coefficients exactly, for each (s, w); Golub and Pereyra 1973).
The signals are weighted by their residual standard deviation (a first fit estimates it), so that each
carries white noise of unit variance. The covariance of (s_k, w_k) is s^2 (J_p^T J_p)^-1 with J_p the
Jacobian of the model in (s, w) projected orthogonally to the linear basis (which accounts for the
estimated amplitudes exactly, the Schur complement of the full Gauss-Newton matrix), and s^2 the pooled
residual variance; (f_n, zeta) follow by the delta method (omega_n = sqrt(s^2 + w^2), zeta = s/omega_n).
The 95 % intervals are estimate +- t_(0.975, dof) standard errors (Student t, dof = samples x signals -
parameters; for these records it equals the normal quantile 1.96 to 3 digits). They assume white noise and
the model above; the record's quality (SNR, periods, sample rate, R^2) says how far that holds.

Refs: P. D. Welch, IEEE Trans. Audio Electroacoust. 15 (1967) 70-73; scipy.signal.welch, find_peaks;
G. Golub and V. Pereyra, SIAM J. Numer. Anal. 10 (1973) 413-432 (variable projection).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.signal import find_peaks, welch
from scipy.stats import t as student_t

from models.errors import InvalidParameter

__all__ = [
    "CONFIDENCE",
    "MAX_FIT_VALUES",
    "MAX_MODES",
    "MAX_SPECTRUM_POINTS",
    "IdentifiedMode",
    "ModalIdentification",
    "Record",
    "Spectrum",
    "free_vibration_start",
    "identify_modes",
    "record_spectrum",
    "spectral_peaks",
    "uniform_record",
]

CONFIDENCE = 0.95
MAX_MODES = 6
MAX_SPECTRUM_POINTS = 2049  # welch's one-sided spectrum of at most 4096-sample segments
MAX_SEGMENT = 4096
MIN_FIT_SAMPLES = 32
# samples x signals the fit takes: its Jacobians hold ~800 B per value (6 modes), so 105 MiB at the peak here
# (tracemalloc), where the 200000 rows x 16 signals a CSV may hold took 2.2 GB, and minutes, in the HTTP process.
MAX_FIT_VALUES = 131_072
LOW_R_SQUARED = 0.5  # below: a warning
MIN_DETECTION_SNR = 10.0  # a mode's energy over the noise's, in rms (20 dB): weaker modes are dropped
FEW_PERIODS = 5.0
PEAK_FLOOR_FACTOR = 30.0  # a peak stands 15 dB above the spectrum's median (noise bins exceed it w.p. 1e-9)
PEAK_RELATIVE = 1e-3  # and at most 30 dB below the highest peak
JITTER_RTOL = 1e-6  # steps within this of their median count as uniform
GAP_RTOL = 0.5  # a step further than this from the median is a gap: refused
NYQUIST_FRACTION = 0.8  # modes or spectral energy above 0.8 f_Nyquist: aliasing risk
ALIAS_ENERGY_FRACTION = 0.01


@dataclass(frozen=True)
class Record:
    """A measured record: sample times (s), one row per signal, their names, and the command if known."""

    time_s: NDArray[np.float64]
    signals: NDArray[np.float64]  # (signals, samples)
    names: tuple[str, ...]
    command: NDArray[np.float64] | None = None
    command_name: str | None = None


@dataclass(frozen=True)
class Spectrum:
    frequency_hz: NDArray[np.float64]
    psd: NDArray[np.float64]  # summed over the signals, (signal units)^2 / Hz
    resolution_hz: float
    segment_samples: int


@dataclass(frozen=True)
class IdentifiedMode:
    natural_frequency_hz: float
    damping_ratio: float
    natural_frequency_ci_hz: tuple[float, float]
    damping_ratio_ci: tuple[float, float]
    natural_frequency_std_hz: float
    damping_ratio_std: float
    damped_frequency_hz: float
    decay_rate_1_s: float
    peak_frequency_hz: float  # the Welch peak that started the fit
    amplitude: tuple[float, ...]  # per signal, at the fit window's start (signal units)
    signal_to_noise: float  # sqrt(sum_c (A_c / sigma_c)^2): the amplitude over the noise's std
    detection_snr: float  # sqrt(the mode's energy in the window / the noise variance)
    periods: float  # damped periods in the fit window
    periods_above_noise: float  # damped periods until the envelope falls to the noise's std
    samples_per_period: float

    def as_dict(self) -> dict[str, object]:
        return {
            "natural_frequency_hz": self.natural_frequency_hz,
            "damping_ratio": self.damping_ratio,
            "natural_frequency_ci_hz": list(self.natural_frequency_ci_hz),
            "damping_ratio_ci": list(self.damping_ratio_ci),
            "natural_frequency_std_hz": self.natural_frequency_std_hz,
            "damping_ratio_std": self.damping_ratio_std,
            "damped_frequency_hz": self.damped_frequency_hz,
            "decay_rate_1_s": self.decay_rate_1_s,
            "peak_frequency_hz": self.peak_frequency_hz,
            "amplitude": list(self.amplitude),
            "signal_to_noise": self.signal_to_noise,
            "detection_snr": self.detection_snr,
            "periods": self.periods,
            "periods_above_noise": self.periods_above_noise,
            "samples_per_period": self.samples_per_period,
        }


@dataclass(frozen=True)
class ModalIdentification:
    modes: tuple[IdentifiedMode, ...]  # lowest frequency first
    spectrum: Spectrum
    sample_rate_hz: float
    window_start_s: float
    window_samples: int
    window_source: str  # "command_end", "start_s" or "largest_excursion"
    r_squared: float
    noise_rms: tuple[float, ...]  # per signal
    offsets: tuple[float, ...]
    degrees_of_freedom: int
    t_quantile: float
    names: tuple[str, ...]
    alias_energy_fraction: float
    resampled: bool
    warnings: tuple[str, ...] = field(default=())


# --- the record ---------------------------------------------------------------------------------------------


def uniform_record(
    time_s: NDArray[np.float64], signals: NDArray[np.float64]
) -> tuple[float, NDArray[np.float64], bool]:
    """(sample period, signals on the uniform grid t_0 + k dt, whether they were interpolated).

    dt is the median step. Steps within 1e-6 of it are taken as uniform (dt: their mean); a record with jitter up
    to 50 % is linearly interpolated onto the grid (numpy.interp); a larger gap or a step <= 0 is refused."""
    steps = np.diff(time_s)
    if steps.size == 0:
        raise InvalidParameter("time_s", f"{time_s.size} samples", "needs at least 2 samples")
    bad = np.flatnonzero(~(steps > 0))
    if bad.size:
        k = int(bad[0]) + 1
        raise InvalidParameter(f"time_s[{k}]", float(time_s[k]), "times must increase strictly")
    dt = float(np.median(steps))
    deviation = np.abs(steps / dt - 1.0)
    worst = int(np.argmax(deviation))
    if deviation[worst] > GAP_RTOL:
        raise InvalidParameter(
            f"time_s[{worst + 1}]",
            float(time_s[worst + 1]),
            f"a step of {steps[worst]:.6g} s against the median {dt:.6g} s: the record has a gap "
            f"(steps must stay within {100 * GAP_RTOL:g} % of the median)",
        )
    if deviation[worst] <= JITTER_RTOL:  # uniform: the mean step, free of the median's rounding
        return float(time_s[-1] - time_s[0]) / steps.size, signals, False
    n = math.floor((time_s[-1] - time_s[0]) / dt + 1e-9) + 1
    grid = time_s[0] + dt * np.arange(n)
    resampled = np.vstack([np.interp(grid, time_s, row) for row in signals])
    return dt, resampled, True


def free_vibration_start(
    record: Record, dt: float, signals: NDArray[np.float64], start_s: float | None
) -> tuple[int, str]:
    """Index where the free vibration starts, and why: the first sample at or after ``start_s``; else
    where the known command last changes; else the record's largest excursion (the sum over the signals
    of the squared deviation from their medians, each over its own variance)."""
    n = signals.shape[1]
    if start_s is not None:
        k = math.ceil((start_s - float(record.time_s[0])) / dt - 1e-9)
        if not 0 <= k < n:
            raise InvalidParameter("start_s", start_s, "must lie within the record's times")
        return k, "start_s"
    if record.command is not None:
        command = record.command
        if command.size != n:  # resampled: the command on the same grid
            grid = float(record.time_s[0]) + dt * np.arange(n)
            command = np.interp(grid, record.time_s, record.command)
        span = float(np.max(command) - np.min(command))
        moving = np.flatnonzero(np.abs(np.diff(command)) > 1e-9 * max(span, 1e-300))
        if span == 0.0 or moving.size == 0:
            return 0, "command_end"  # a command that never moves: the whole record is free
        return int(moving[-1]) + 1, "command_end"
    centred = signals - np.median(signals, axis=1, keepdims=True)
    var = np.var(centred, axis=1, keepdims=True)
    energy = np.sum(centred**2 / np.where(var > 0, var, 1.0), axis=0)
    return int(np.argmax(energy)), "largest_excursion"


# --- the spectrum and its peaks -----------------------------------------------------------------------------


def record_spectrum(signals: NDArray[np.float64], sample_rate_hz: float) -> Spectrum:
    """Welch's PSD of every signal (segments of min(samples, 4096), half overlap, mean removed), summed
    over the signals: at most 2049 frequencies.

    The window is rectangular (boxcar), the practice for a free vibration that decays within the block
    (impact testing: a Hann window would weight the record's start, where the vibration is, by ~0 and hide
    the fast-decaying modes); the decay itself keeps the leakage low."""
    segment = int(min(signals.shape[1], MAX_SEGMENT))
    frequency, psd = welch(signals, fs=sample_rate_hz, window="boxcar", nperseg=segment, detrend="constant", axis=-1)
    total = np.sum(np.atleast_2d(psd), axis=0)
    return Spectrum(np.asarray(frequency, float), np.asarray(total, float), sample_rate_hz / segment, segment)


def spectral_peaks(spectrum: Spectrum, max_modes: int) -> list[tuple[float, float]]:
    """(frequency Hz, half-power damping estimate) of the strongest peaks, lowest frequency first.

    A peak counts when it stands 15 dB (30 times) above the spectrum's median (the noise floor), within 30 dB of the
    highest one, and rises by half its height above its surroundings (find_peaks' prominence); the DC bins
    are skipped. Its frequency is refined by a parabola through the log PSD of its three bins; the damping
    estimate is the half-power bandwidth over twice the frequency (clipped to [0.002, 0.3])."""
    f, p = spectrum.frequency_hz, spectrum.psd
    if p.size < 5 or not np.any(p > 0):
        return []
    floor = float(np.median(p))
    top = float(np.max(p[2:])) if p.size > 2 else 0.0
    height = max(PEAK_FLOOR_FACTOR * floor, PEAK_RELATIVE * top)
    peaks, props = find_peaks(p, height=height, prominence=0.0)
    keep = (peaks >= 2) & (props["prominences"] >= 0.5 * p[peaks])
    peaks = peaks[keep]
    if peaks.size == 0:
        return []
    peaks = peaks[np.argsort(p[peaks])[::-1][:max_modes]]
    out: list[tuple[float, float]] = []
    df = spectrum.resolution_hz
    logp = np.log(np.maximum(p, 1e-300))
    for k in np.sort(peaks):
        shift = 0.0
        if 0 < k < p.size - 1:
            a, b, c = logp[k - 1], logp[k], logp[k + 1]
            denom = a - 2 * b + c
            shift = float(np.clip(0.5 * (a - c) / denom, -0.5, 0.5)) if denom < 0 else 0.0
        frequency = float(f[k] + shift * df)
        half = p[k] / 2.0
        below_left = np.flatnonzero(p[:k] <= half)
        below_right = np.flatnonzero(p[k:] <= half)
        left = int(below_left[-1]) if below_left.size else 0
        right = k + int(below_right[0]) if below_right.size else p.size - 1
        width = float(f[right] - f[left])
        zeta = float(np.clip(width / (2.0 * frequency), 0.002, 0.3)) if frequency > 0 else 0.05
        out.append((frequency, zeta))
    return out


# --- the fit ------------------------------------------------------------------------------------------------


def _basis(t: NDArray[np.float64], params: NDArray[np.float64]) -> NDArray[np.float64]:
    """Columns e^(-s_k t) cos w_k t, e^(-s_k t) sin w_k t for each mode, then 1."""
    s, w = params[0::2], params[1::2]
    env = np.exp(np.clip(-np.outer(t, s), -700.0, 700.0))
    phase = np.outer(t, w)
    columns = np.empty((t.size, 2 * s.size + 1))
    columns[:, 0:-1:2] = env * np.cos(phase)
    columns[:, 1:-1:2] = env * np.sin(phase)
    columns[:, -1] = 1.0
    return columns


def _projected_jacobian(
    t: NDArray[np.float64], basis: NDArray[np.float64], coef: NDArray[np.float64], params: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(samples, signals, parameters): d model / d (s_k, w_k) with the linear coefficients held, projected
    orthogonally to the basis (Kaufman's variable-projection Jacobian; exact for the covariance)."""
    q, _ = np.linalg.qr(basis)
    cos_k, sin_k = basis[:, 0:-1:2], basis[:, 1:-1:2]  # (n, modes)
    a, b = coef[0:-1:2, :], coef[1:-1:2, :]  # (modes, signals)
    tt = t[:, None, None]
    jac = np.empty((t.size, coef.shape[1], params.size))
    jac[:, :, 0::2] = -tt * (cos_k[:, None, :] * a.T[None] + sin_k[:, None, :] * b.T[None])
    jac[:, :, 1::2] = tt * (-sin_k[:, None, :] * a.T[None] + cos_k[:, None, :] * b.T[None])
    flat = jac.reshape(t.size, -1)
    flat -= q @ (q.T @ flat)
    return flat.reshape(jac.shape)


def _projected_fit(
    t: NDArray[np.float64],
    y: NDArray[np.float64],
    x0: NDArray[np.float64],
    lower: NDArray[np.float64],
    upper: NDArray[np.float64],
) -> NDArray[np.float64]:
    """least_squares over the nonlinear parameters (s_k, w_k), the linear coefficients solved exactly."""

    def solve(params: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        basis = _basis(t, params)
        coef = np.asarray(np.linalg.lstsq(basis, y.T, rcond=None)[0], dtype=np.float64)
        return basis, coef

    def residual(params: NDArray[np.float64]) -> NDArray[np.float64]:
        basis, coef = solve(params)
        misfit: NDArray[np.float64] = (basis @ coef - y.T).ravel()
        return misfit

    def jacobian(params: NDArray[np.float64]) -> NDArray[np.float64]:
        basis, coef = solve(params)
        return _projected_jacobian(t, basis, coef, params).reshape(-1, params.size)

    fit = least_squares(
        residual,
        x0=np.clip(x0, lower, upper),
        jac=jacobian,
        bounds=(lower, upper),
        x_scale=np.abs(x0) + 1e-3 * np.max(np.abs(x0)),
        method="trf",
        xtol=1e-12,
        ftol=1e-12,
        gtol=1e-12,
        max_nfev=100 * x0.size,
    )
    return np.asarray(fit.x, dtype=float)


def _covariance(
    t: NDArray[np.float64], y: NDArray[np.float64], params: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], float, int]:
    """(linear coefficients (basis, signals), covariance of (s_k, w_k), pooled residual variance, dof)."""
    basis = _basis(t, params)
    coef = np.asarray(np.linalg.lstsq(basis, y.T, rcond=None)[0], dtype=np.float64)
    res = basis @ coef - y.T
    signals = y.shape[0]
    dof = max(1, y.size - params.size - signals * basis.shape[1])
    variance = float(np.sum(res**2)) / dof
    jac = _projected_jacobian(t, basis, coef, params).reshape(-1, params.size)
    fisher = jac.T @ jac
    try:
        cov = np.linalg.inv(fisher) * variance
    except np.linalg.LinAlgError:
        cov = np.full((params.size, params.size), np.inf)
    return coef, cov, variance, dof


def _mode_statistics(s: float, w: float, cov2: NDArray[np.float64]) -> tuple[float, float, float, float]:
    """(f_n Hz, zeta, std f_n Hz, std zeta) from (s, w) and their 2x2 covariance, by the delta method."""
    wn = math.hypot(s, w)
    zeta = s / wn
    grad_wn = np.array([s / wn, w / wn])
    grad_zeta = np.array([w * w / wn**3, -s * w / wn**3])
    var_wn = float(grad_wn @ cov2 @ grad_wn)
    var_zeta = float(grad_zeta @ cov2 @ grad_zeta)
    std_fn = math.sqrt(var_wn) / (2 * math.pi) if var_wn >= 0 and math.isfinite(var_wn) else math.inf
    std_zeta = math.sqrt(var_zeta) if var_zeta >= 0 and math.isfinite(var_zeta) else math.inf
    return wn / (2 * math.pi), zeta, std_fn, std_zeta


def identify_modes(record: Record, *, max_modes: int = 4, start_s: float | None = None) -> ModalIdentification:
    """The modes of a measured record, with 95 % intervals, its spectrum and its quality (see the module)."""
    signals = np.atleast_2d(np.asarray(record.signals, dtype=float))
    t_abs = np.asarray(record.time_s, dtype=float)
    names = record.names
    dt, signals, resampled = uniform_record(t_abs, signals)
    rate = 1.0 / dt
    start, source = free_vibration_start(record, dt, signals, start_s)
    window = signals[:, start:]
    n = window.shape[1]
    field_name = "command" if source == "command_end" else ("start_s" if source == "start_s" else "time_s")
    if n < MIN_FIT_SAMPLES:
        raise InvalidParameter(
            field_name,
            f"{n} samples",
            f"the free vibration (from {t_abs[0] + start * dt:.6g} s, {source.replace('_', ' ')}) holds {n} samples; "
            f"at least {MIN_FIT_SAMPLES} are needed",
        )
    spread = np.max(window, axis=1) - np.min(window, axis=1)
    live = spread > 0
    if not np.any(live):
        raise InvalidParameter(names[0], "constant", "every signal is constant: the record holds no vibration")
    live_count = int(np.count_nonzero(live))
    if n * live_count > MAX_FIT_VALUES:
        raise InvalidParameter(
            field_name,
            f"{n} samples x {live_count} signals",
            f"the fit takes at most {MAX_FIT_VALUES} values (samples x signals from {t_abs[0] + start * dt:.6g} s, "
            f"{source.replace('_', ' ')}): start later (start_s), send fewer rows (a lower rate) or fewer signals",
        )
    t = np.arange(n, dtype=np.float64) * dt
    spectrum = record_spectrum(window, rate)
    peaks = spectral_peaks(spectrum, max_modes)
    if not peaks:
        raise InvalidParameter(
            names[0] if len(names) == 1 else "signals",
            f"{len(names)} signals",
            "the spectrum shows no peak 15 dB above its noise floor: the record holds no clear vibration",
        )
    scale = np.where(live, np.std(window, axis=1), 1.0)[:, None]
    y = (window - np.median(window, axis=1, keepdims=True)) / scale
    y = y[live]
    warnings: list[str] = []
    if not np.all(live):
        warnings.append(
            "constant signals ignored: " + ", ".join(name for name, ok in zip(names, live, strict=True) if not ok)
        )
    nyquist = rate / 2.0
    while True:
        try:
            params, weights = _fit(t, y, peaks, nyquist)
        except (ValueError, np.linalg.LinAlgError, FloatingPointError) as exc:  # a degenerate record
            raise InvalidParameter(
                "signals", f"{len(names)} signals", f"the fit failed on this record ({exc})"
            ) from None
        coef, cov, variance, dof = _covariance(t, y * weights[:, None], params)
        modes_stats = []
        for k in range(len(peaks)):
            s, w = float(params[2 * k]), float(params[2 * k + 1])
            a, b = coef[2 * k, :], coef[2 * k + 1, :]
            snr = float(math.sqrt(float(np.sum(a * a + b * b)) / variance))
            # the mode's energy in the window over the noise variance: sum_t A^2 e^(-2 s t) / 2 / variance
            energy = 0.5 * snr**2 * float(np.sum(np.exp(np.clip(-2.0 * s * t, -700.0, 700.0))))
            modes_stats.append((s, w, snr, math.sqrt(energy)))
        weak = [k for k, stats in enumerate(modes_stats) if stats[3] < MIN_DETECTION_SNR]
        if not weak:
            break
        if len(peaks) == 1:
            raise InvalidParameter(
                "signals",
                f"{len(names)} signals",
                f"the best damped sinusoid ({modes_stats[0][1] / (2 * math.pi):.4g} Hz) carries an energy only "
                f"{modes_stats[0][3]:.2g} times the noise's (in rms, over the record; at least {MIN_DETECTION_SNR:g} "
                "needed): no free vibration clearly above the noise",
            )
        dropped = peaks[weak[0]]
        warnings.append(
            f"the spectral peak at {dropped[0]:.4g} Hz fits no mode clearly above the noise "
            f"(detection SNR {modes_stats[weak[0]][3]:.2g} < {MIN_DETECTION_SNR:g}): dropped"
        )
        peaks = [p for i, p in enumerate(peaks) if i != weak[0]]
    fitted = _basis(t, params) @ coef
    res = fitted - (y * weights[:, None]).T
    yw = (y * weights[:, None]).T
    ss_tot = float(np.sum((yw - np.mean(yw, axis=0)) ** 2))
    r2 = 1.0 - float(np.sum(res**2)) / ss_tot if ss_tot > 0 else 0.0
    if r2 < LOW_R_SQUARED:
        warnings.append(
            f"the fit explains {100 * max(r2, 0.0):.3g} % of the record's (noise-weighted) variance: the record is "
            "mostly noise (a shorter record after the vibration, or a stronger excitation, helps)"
        )
    quantile = float(student_t.ppf(0.5 + CONFIDENCE / 2.0, dof))
    live_scale = scale[live, 0]
    noise = np.zeros(len(names))
    noise[live] = live_scale / weights * math.sqrt(variance)
    offsets = np.median(window, axis=1)
    offsets[live] += coef[-1, :] * live_scale / weights
    modes: list[IdentifiedMode] = []
    duration = n * dt
    for k, (s, w, snr, detection) in enumerate(modes_stats):
        fn, zeta, std_fn, std_zeta = _mode_statistics(s, w, cov[2 * k : 2 * k + 2, 2 * k : 2 * k + 2])
        if not all(math.isfinite(v) for v in (fn, zeta, std_fn, std_zeta)):
            raise InvalidParameter(
                "signals",
                f"{len(names)} signals",
                f"the fit's covariance is singular near {fn:.4g} Hz: the modes cannot be told apart in this record",
            )
        amp = np.zeros(len(names))
        amp[live] = np.hypot(coef[2 * k, :], coef[2 * k + 1, :]) * live_scale / weights
        fd = w / (2 * math.pi)
        above = fd * math.log(snr) / s if s > 0 and snr > 1 else (math.inf if snr > 1 else 0.0)
        mode = IdentifiedMode(
            natural_frequency_hz=fn,
            damping_ratio=max(zeta, 0.0),
            natural_frequency_ci_hz=(fn - quantile * std_fn, fn + quantile * std_fn),
            damping_ratio_ci=(max(zeta - quantile * std_zeta, 0.0), zeta + quantile * std_zeta),
            natural_frequency_std_hz=std_fn,
            damping_ratio_std=std_zeta,
            damped_frequency_hz=fd,
            decay_rate_1_s=s,
            peak_frequency_hz=peaks[k][0],
            amplitude=tuple(float(v) for v in amp),
            signal_to_noise=snr,
            detection_snr=detection,
            periods=fd * duration,
            periods_above_noise=min(above, fd * duration),
            samples_per_period=rate / fn,
        )
        modes.append(mode)
        warnings.extend(_mode_warnings(mode, nyquist))
    top = spectrum.frequency_hz >= NYQUIST_FRACTION * nyquist
    total = float(np.sum(spectrum.psd))
    alias = float(np.sum(spectrum.psd[top])) / total if total > 0 else 0.0
    if alias > ALIAS_ENERGY_FRACTION:
        warnings.append(
            f"{100 * alias:.2g} % of the spectrum's power lies above {NYQUIST_FRACTION:g} x the Nyquist frequency "
            f"({nyquist:.6g} Hz): aliasing is possible (sample faster or filter before sampling)"
        )
    if resampled:
        warnings.append(
            "the time steps are not uniform: the signals were linearly interpolated onto a uniform grid, which "
            "correlates the noise (the intervals may be slightly optimistic)"
        )
    order = np.argsort([m.natural_frequency_hz for m in modes])
    return ModalIdentification(
        modes=tuple(modes[i] for i in order),
        spectrum=spectrum,
        sample_rate_hz=rate,
        window_start_s=float(t_abs[0] + start * dt),
        window_samples=n,
        window_source=source,
        r_squared=r2,
        noise_rms=tuple(float(v) for v in noise),
        offsets=tuple(float(v) for v in offsets),
        degrees_of_freedom=dof,
        t_quantile=quantile,
        names=names,
        alias_energy_fraction=alias,
        resampled=resampled,
        warnings=tuple(warnings),
    )


def _fit(
    t: NDArray[np.float64], y: NDArray[np.float64], peaks: list[tuple[float, float]], nyquist: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The fit's (s_k, w_k) and the signals' weights (1 / residual std of a first, unweighted fit)."""
    x0 = np.empty(2 * len(peaks))
    for k, (f, zeta) in enumerate(peaks):
        wn = 2 * math.pi * f
        x0[2 * k] = zeta * wn
        x0[2 * k + 1] = wn * math.sqrt(1 - zeta * zeta)
    w0 = x0[1::2]
    lower = np.empty_like(x0)
    upper = np.empty_like(x0)
    # a growing envelope is allowed (and reported), but at most e^20 over the window: no overflow
    lower[0::2], upper[0::2] = -np.minimum(0.05 * w0, 20.0 / max(float(t[-1]), 1e-300)), 2.0 * w0
    lower[1::2], upper[1::2] = 0.5 * w0, np.minimum(1.5 * w0, 2 * math.pi * nyquist)
    params = _projected_fit(t, y, x0, lower, upper)
    basis = _basis(t, params)
    coef = np.asarray(np.linalg.lstsq(basis, y.T, rcond=None)[0], dtype=np.float64)
    std = np.std(basis @ coef - y.T, axis=0)
    weights = 1.0 / np.where(std > 0, std, 1.0)
    if y.shape[0] > 1:
        params = _projected_fit(t, y * weights[:, None], params, lower, upper)
    return params, weights


def _mode_warnings(mode: IdentifiedMode, nyquist: float) -> list[str]:
    out = []
    name = f"mode at {mode.natural_frequency_hz:.4g} Hz"
    if mode.periods_above_noise < FEW_PERIODS:
        out.append(
            f"{name}: fewer than {FEW_PERIODS:g} periods above the noise ({mode.periods_above_noise:.2g}): "
            "its interval rests on little data"
        )
    if mode.natural_frequency_hz > NYQUIST_FRACTION * nyquist:
        out.append(f"{name}: within {100 * (1 - NYQUIST_FRACTION):g} % of the Nyquist frequency: aliasing risk")
    elif mode.samples_per_period < 10:
        out.append(f"{name}: only {mode.samples_per_period:.2g} samples per period (10 or more advised)")
    if mode.decay_rate_1_s < 0:
        out.append(
            f"{name}: the fitted envelope grows (decay rate {mode.decay_rate_1_s:.3g} 1/s): not a free vibration"
        )
    return out
