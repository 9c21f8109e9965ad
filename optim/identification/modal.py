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

The fit starts from the peaks of the decay's spectra over its first n, n/2, n/4, ... samples, each signal over its
own noise (``spectrum.decay_peaks``): a well-damped decay rings for a small part of a long record. Where the fit's
residual then shows a bin 10 dB over its median, away from the modes fitted, a component starts there and the fit
runs again (each residual peak once, at most MAX_REJECTED rejected): it is kept in the fit from a detection SNR of 5,
reported as a mode from 10, as the spectrum's peaks are. A mode left out biases the others' fits with intervals that
stay narrow (bench/identify_coverage.py: 25 of the 34 intervals that missed the truth, on 200 knock records, before).

The steps are ``optim.identification.record`` (the grid, the free vibration's start), ``.spectrum`` (Welch's
spectrum, its peaks) and ``.damped_fit`` (the fit and its covariance); ``identify_modes`` runs them.

Refs: P. D. Welch, IEEE Trans. Audio Electroacoust. 15 (1967) 70-73; scipy.signal.welch, find_peaks;
G. Golub and V. Pereyra, SIAM J. Numer. Anal. 10 (1973) 413-432 (variable projection).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.stats import chi2
from scipy.stats import t as student_t

from models.errors import InvalidParameter
from optim.identification.damped_fit import damped_basis, fit_covariance, fit_damped_sinusoids, mode_statistics
from optim.identification.record import Record, free_vibration_start, uniform_record
from optim.identification.spectrum import (
    Spectrum,
    contrast_spectrum,
    decay_peaks,
    decay_spans,
    peak_at,
    record_spectrum,
)

__all__ = [
    "CONFIDENCE",
    "MAX_FIT_VALUES",
    "MAX_MODES",
    "FittedMode",
    "IdentifiedMode",
    "ModalIdentification",
    "identify_modes",
    "interval_fields",
]

CONFIDENCE = 0.95
MAX_MODES = 6
MIN_FIT_SAMPLES = 32
# samples x signals the fit takes: its Jacobians hold ~800 B per value (6 modes), so 105 MiB at the peak here
# (tracemalloc), where the 200000 rows x 16 signals a CSV may hold took 2.2 GB, and minutes, in the HTTP process.
MAX_FIT_VALUES = 131_072
ONSET_SPANS = (8, 16, 32, 64, 128)  # the window's first samples where a fit's misfit at its start is looked for
ONSET_ALPHA = 1e-3  # their test's level (Bonferroni over spans and signals)
LOW_R_SQUARED = 0.5  # below: a warning
RESIDUAL_PEAK_RATIO = 10.0  # a residual's bin over its median tried as a mode (white noise's highest of ~1000 bins is
# ~7 times its median); the refit keeps it only at MIN_DETECTION_SNR
MIN_DETECTION_SNR = 10.0  # a mode's energy over the noise's, in rms (20 dB): weaker modes are not reported
# a component tried at a residual's peak is kept in the fit from this detection SNR (below MIN_DETECTION_SNR, not
# reported as a mode): a mode left out biases the others by up to its own SNR in standard errors, one fitted to noise
# only widens their intervals
MIN_NUISANCE_SNR = 5.0
MAX_REJECTED = 2  # residual peaks the fit may reject before the search stops (each costs a fit)
# a mode tried at a residual's peak is kept only below zeta 0.3 (s / w_d < 0.31): more damped, it dies within a period
# and mimics the forced part of a fit started inside its excitation (a 93 Hz zeta 0.61 "mode" absorbed a knock's end)
MAX_ADDED_DECAY = 0.3 / math.sqrt(1.0 - 0.3**2)
# ... and with an energy at least 1e-3 of the strongest mode's (30 dB, spectrum.PEAK_RELATIVE: a noise-free record's
# residual is rounding, which a mode "fits" far above its rms)
MIN_ADDED_SHARE = math.sqrt(1e-3)
FEW_PERIODS = 5.0
NYQUIST_FRACTION = 0.8  # modes or spectral energy above 0.8 f_Nyquist: aliasing risk
ALIAS_ENERGY_FRACTION = 0.01


@dataclass(frozen=True)
class FittedMode:
    """A mode's estimate with its 95 % intervals: what a design needs of it (a free decay's IdentifiedMode and a
    spectrum's SpectralMode add what each fit knows)."""

    natural_frequency_hz: float
    damping_ratio: float
    natural_frequency_ci_hz: tuple[float, float]
    damping_ratio_ci: tuple[float, float]
    natural_frequency_std_hz: float
    damping_ratio_std: float


def interval_fields(f_hz: float, std_hz: float, zeta: float, std_zeta: float, quantile: float) -> dict[str, Any]:
    """FittedMode's intervals and standard errors: estimate +- quantile x standard error (zeta's low end at 0)."""
    return {
        "natural_frequency_ci_hz": (f_hz - quantile * std_hz, f_hz + quantile * std_hz),
        "damping_ratio_ci": (max(zeta - quantile * std_zeta, 0.0), zeta + quantile * std_zeta),
        "natural_frequency_std_hz": std_hz,
        "damping_ratio_std": std_zeta,
    }


@dataclass(frozen=True)
class IdentifiedMode(FittedMode):
    damped_frequency_hz: float
    decay_rate_1_s: float
    peak_frequency_hz: float  # the Welch peak that started the fit
    amplitude: tuple[float, ...]  # per signal, at the fit window's start (signal units)
    signal_to_noise: float  # sqrt(sum_c (A_c / sigma_c)^2): the amplitude over the noise's std
    detection_snr: float  # sqrt(the mode's energy in the window / the noise variance)
    periods: float  # damped periods in the fit window
    periods_above_noise: float  # damped periods until the envelope falls to the noise's std
    samples_per_period: float


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
    onset_misfit: float  # the fit's residual over its first samples against the noise (see _onset_misfit): > 1, the
    # fit starts inside the excitation
    warnings: tuple[str, ...] = field(default=())


def _onset_misfit(residual: NDArray[np.float64]) -> float:
    """The largest, over each signal and its first m samples (m in ONSET_SPANS), of sum residual^2 / noise variance
    over chi^2_m's 1 - ONSET_ALPHA / tests quantile. A fit started inside its excitation leaves its misfit where the
    forced motion was, at the window's start, where a residual over the whole window dilutes it; the fit's own
    leverage, highest there, makes the white noise's statistic smaller than chi^2_m: above 1 is a misfit at level
    ONSET_ALPHA. ``residual``: (signals, samples), each of unit noise variance."""
    variance = np.maximum(np.mean(residual**2, axis=1), 1e-300)
    cumulative = np.cumsum(residual**2, axis=1) / variance[:, None]
    spans = [m for m in ONSET_SPANS if m <= residual.shape[1] // 4]
    tests = max(1, len(spans) * residual.shape[0])
    return max(
        (float(np.max(cumulative[:, m - 1])) / float(chi2.isf(ONSET_ALPHA / tests, m)) for m in spans), default=0.0
    )


def _residual_peak(
    t: NDArray[np.float64], residual: NDArray[np.float64], near_hz: list[float]
) -> tuple[float, float] | None:
    """The residual's strongest spectral bin over its span's median, among its spectra over its first n, n/2, ...
    samples (optim.identification.spectrum.decay_peaks' spans), more than 5 % from ``near_hz`` (the modes fitted and
    the peaks tried) and at least RESIDUAL_PEAK_RATIO over the median: where a mode the record's spectrum hid (two
    well-damped modes in one wide peak, a weak mode under a strong one's skirt) would be; its absence biases the others'
    fits with intervals that stay narrow. (frequency Hz, half-power damping estimate) or None."""
    rate = 1.0 / float(t[1] - t[0])
    best: tuple[float, tuple[float, float]] | None = None
    for length in decay_spans(residual.shape[1]):
        spectrum = contrast_spectrum(residual[:, :length], rate)
        f, p = spectrum.frequency_hz, spectrum.psd
        ratio = p / max(float(np.median(p)), 1e-300)
        ratio[:2] = 0.0
        for g in near_hz:
            ratio[np.abs(f - g) <= 0.05 * g] = 0.0
        k = int(np.argmax(ratio))
        if ratio[k] >= RESIDUAL_PEAK_RATIO and (best is None or ratio[k] > best[0]):
            best = (float(ratio[k]), peak_at(f, p, k, spectrum.resolution_hz))
    return None if best is None else best[1]


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
    peaks = decay_peaks(window, rate, max_modes)
    if not peaks:  # no peak 15 dB up: the strongest bin, if 10 dB up, is tried (the fit's detection SNR decides)
        strongest = _residual_peak(t, window - np.mean(window, axis=1, keepdims=True), [])
        if strongest is None:
            raise InvalidParameter(
                names[0] if len(names) == 1 else "signals",
                f"{len(names)} signals",
                "the spectrum shows no peak 10 dB above its noise floor: the record holds no clear vibration",
            )
        peaks = [strongest]
    scale = np.where(live, np.std(window, axis=1), 1.0)[:, None]
    y = (window - np.median(window, axis=1, keepdims=True)) / scale
    y = y[live]
    warnings: list[str] = []
    if not np.all(live):
        warnings.append(
            "constant signals ignored: " + ", ".join(name for name, ok in zip(names, live, strict=True) if not ok)
        )
    nyquist = rate / 2.0
    added: list[float] = []  # frequencies of residual peaks already added (each tried once)
    rejected = 0  # of them, those the fit did not keep
    fitted_before: dict[tuple[tuple[float, float], ...], tuple[NDArray[np.float64], NDArray[np.float64]]] = {}
    while True:
        try:  # (a fit from the same peaks is made once: a rejected residual peak goes back to the fit before it)
            key = tuple(peaks)
            if key not in fitted_before:
                fitted_before[key] = fit_damped_sinusoids(t, y, peaks, nyquist)
            params, weights = fitted_before[key]
        except (ValueError, np.linalg.LinAlgError, FloatingPointError) as exc:  # a degenerate record
            if added and added[-1] in (p[0] for p in peaks):  # the residual's last peak: tried, and no mode
                peaks = [p for p in peaks if p[0] != added[-1]]
                rejected += 1
                continue
            if len(peaks) > 1:  # the two nearest peaks (one mode's peak split by the noise) fitted as one
                k = int(np.argmin([peaks[i + 1][0] / peaks[i][0] for i in range(len(peaks) - 1)]))
                warnings.append(
                    f"the peaks at {peaks[k][0]:.4g} and {peaks[k + 1][0]:.4g} Hz could not be fitted as two modes "
                    f"({exc}): fitted as one"
                )
                peaks = [p for i, p in enumerate(peaks) if i != k + 1]
                continue
            raise InvalidParameter(
                "signals", f"{len(names)} signals", f"the fit failed on this record ({exc})"
            ) from None
        coef, cov, variance, dof = fit_covariance(t, y * weights[:, None], params)
        modes_stats = []
        for k in range(len(peaks)):
            s, w = float(params[2 * k]), float(params[2 * k + 1])
            a, b = coef[2 * k, :], coef[2 * k + 1, :]
            snr = float(math.sqrt(float(np.sum(a * a + b * b)) / variance))
            # the mode's energy in the window over the noise variance: sum_t A^2 e^(-2 s t) / 2 / variance
            energy = 0.5 * snr**2 * float(np.sum(np.exp(np.clip(-2.0 * s * t, -700.0, 700.0))))
            modes_stats.append((s, w, snr, math.sqrt(energy)))
        top_detection = max(stats[3] for stats in modes_stats)
        weak = [
            k
            for k, (s, w, _, detection) in enumerate(modes_stats)
            if (detection < MIN_DETECTION_SNR and peaks[k][0] not in added)
            or (
                peaks[k][0] in added
                and (
                    detection < MIN_NUISANCE_SNR
                    or s > MAX_ADDED_DECAY * w
                    or detection < MIN_ADDED_SHARE * top_detection
                )
            )
        ]
        if not weak:
            residual = (y * weights[:, None]) - (damped_basis(t, params) @ coef).T
            near = [w / (2 * math.pi) for _, w, _, _ in modes_stats] + added
            more = (  # (each residual peak tried once, at most max_modes of them: the work is bounded)
                None
                if len(peaks) >= max_modes or len(added) >= max_modes or rejected >= MAX_REJECTED
                else _residual_peak(t, residual, near)
            )
            if more is None:
                break
            added.append(more[0])
            peaks = sorted([*peaks, more])
            continue
        if len(peaks) == 1:
            raise InvalidParameter(
                "signals",
                f"{len(names)} signals",
                f"the best damped sinusoid ({modes_stats[0][1] / (2 * math.pi):.4g} Hz) carries an energy only "
                f"{modes_stats[0][3]:.2g} times the noise's (in rms, over the record; at least {MIN_DETECTION_SNR:g} "
                "needed): no free vibration clearly above the noise",
            )
        dropped = peaks[weak[0]]
        peaks = [p for i, p in enumerate(peaks) if i != weak[0]]
        if dropped[0] in added:  # a residual's peak tried as a mode, and not one: no news
            rejected += 1
            continue
        warnings.append(
            f"the spectral peak at {dropped[0]:.4g} Hz fits no mode clearly above the noise "
            f"(detection SNR {modes_stats[weak[0]][3]:.2g} < {MIN_DETECTION_SNR:g}): dropped"
        )
    fitted = damped_basis(t, params) @ coef
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
        if detection < MIN_DETECTION_SNR:  # a residual's component kept in the fit, not reported as a mode
            warnings.append(
                f"a weak component at {w / (2 * math.pi):.4g} Hz (detection SNR {detection:.2g} < "
                f"{MIN_DETECTION_SNR:g}) is fitted, so that it biases no mode, but not reported as a mode"
            )
            continue
        fn, zeta, std_fn, std_zeta = mode_statistics(s, w, cov[2 * k : 2 * k + 2, 2 * k : 2 * k + 2])
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
            **interval_fields(fn, std_fn, zeta, std_zeta, quantile),
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
    excess = np.maximum(spectrum.psd - float(np.median(spectrum.psd)), 0.0)  # above the noise floor: white noise
    total = float(np.sum(excess))  # fills every band, 20 % of it above 0.8 f_Nyquist, and warned on every knock
    alias = float(np.sum(excess[top])) / total if total > 0 else 0.0
    if alias > ALIAS_ENERGY_FRACTION:
        warnings.append(
            f"{100 * alias:.2g} % of the spectrum's power above its noise floor lies above {NYQUIST_FRACTION:g} x the "
            f"Nyquist frequency "
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
        onset_misfit=_onset_misfit(res.T),
        warnings=tuple(warnings),
    )


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
