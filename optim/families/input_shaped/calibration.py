"""Klipper's resonance calibration, and a firmware shaper never worse than its pick by its own criteria.

Klipper's criteria (klippy/extras/shaper_calibrate.py at Klipper3d/klipper 84104bbbd, master of 2026-08-07; the
formulas are those of v0.13.0, the selection rules gained a tolerance, a dominance pass and a zv override since),
for a shaper of amplitudes A_i (sum D) and times T_i over a measured acceleration PSD p(f), f <= 200 Hz:

- V(f, zeta) = |sum_i A_i e^(-zeta w (T_last - T_i)) e^(j w_d T_i)| / D, the residual of a damped oscillator
  (``_estimate_shaper``);
- remaining vibrations = sum_f max(V p - p_max / 20, 0) / sum_f max(p - p_max / 20, 0), at its worst over the
  printer's damping ratios 0.075, 0.1 and 0.15 (``_estimate_remaining_vibrations``);
- smoothing (mm) = max(sqrt 2 / D sum_(T_i >= t_s) A_i (scv + a/2 (T_i - t_s)) (T_i - t_s),
  1 / D sum_i A_i a/2 (T_i - t_s)^2) at a = 5000 mm/s^2, t_s = sum A_i T_i / D (``_get_shaper_smoothing``);
- max_accel (mm/s^2): the largest a whose smoothing is <= 0.12 mm (``find_shaper_max_accel``; both terms are
  affine in a, so it is solved in closed form where Klipper bisects to 1e-8 mm/s^2);
- score = smoothing (vibrations^1.5 + 0.2 vibrations + 0.01) (``fit_shaper``).

Candidates: each type from its min_freq (shaper_defs.INPUT_SHAPERS) to 150 Hz (excluded) every 0.2 Hz, shaper
damping 0.1. The arrays are evaluated once; Klipper's pick (``klipper_pick``: fit_shaper's and find_best_shaper's
rules) and the firmware's (optim.families.input_shaped.firmware_pick) are read from them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from models.errors import InvalidParameter
from models.shapers import ImpulseSequence

Array = NDArray[np.float64]
ImpulsesOf = Callable[[str, float, float], ImpulseSequence]

KLIPPER_TYPES = ("zv", "mzv", "ei", "2hump_ei", "3hump_ei")  # AUTOTUNE_SHAPERS, tried in this order
MIN_FREQ_HZ = {"zv": 21.0, "mzv": 23.0, "zvd": 29.0, "ei": 29.0, "2hump_ei": 39.0, "3hump_ei": 48.0}
MAX_SHAPER_FREQ_HZ = 150.0  # MAX_SHAPER_FREQ: the candidates' end (excluded)
FREQ_STEP_HZ = 0.2
MAX_PSD_FREQ_HZ = 200.0  # MAX_FREQ: the PSD's bins above it are not scored
TEST_DAMPING_RATIOS = (0.075, 0.1, 0.15)
SHAPER_DAMPING_RATIO = 0.1  # shaper_defs.DEFAULT_DAMPING_RATIO
VIBRATION_REDUCTION = 20.0  # shaper_defs.SHAPER_VIBRATION_REDUCTION
SMOOTHING_ACCEL_MM_S2 = 5000.0
TARGET_SMOOTHING_MM = 0.12
DEFAULT_SCV_MM_S = 5.0  # calibrate_shaper.py's --scv default (SHAPER_CALIBRATE uses square_corner_velocity)
WINDOW_S = 0.5  # WINDOW_T_SEC: the Welch segment's target length
KAISER_BETA = 6.0
NORMALIZE_BELOW_HZ = 10.0  # 2 MIN_FREQ
MAX_BINS = 1024  # PSD bins up to 200 Hz scored at most (0.2 Hz apart; Klipper's own are 1.6 Hz apart): units of work
CHUNK_VALUES = 1 << 20  # candidates x bins x impulses evaluated at once (16 MiB of complex numbers)


@dataclass(frozen=True)
class Scores:
    """One shaper type's candidates under Klipper's criteria, one entry per frequency (increasing)."""

    kind: str
    frequency_hz: Array
    damping_ratio: float
    impulses: tuple[ImpulseSequence, ...]
    vibrations: Array  # remaining share, 0..1
    smoothing_mm: Array
    max_accel_mm_s2: Array

    @property
    def score(self) -> Array:
        v = self.vibrations
        return self.smoothing_mm * (v**1.5 + 0.2 * v + 0.01)


@dataclass(frozen=True)
class Pick:
    """One candidate: its type's scores and the frequency's index."""

    scores: Scores
    index: int

    @property
    def kind(self) -> str:
        return self.scores.kind

    @property
    def frequency_hz(self) -> float:
        return float(self.scores.frequency_hz[self.index])

    @property
    def vibrations(self) -> float:
        return float(self.scores.vibrations[self.index])

    @property
    def smoothing_mm(self) -> float:
        return float(self.scores.smoothing_mm[self.index])

    @property
    def max_accel_mm_s2(self) -> float:
        return float(self.scores.max_accel_mm_s2[self.index])

    @property
    def score(self) -> float:
        return float(self.scores.score[self.index])

    @property
    def impulses(self) -> ImpulseSequence:
        return self.scores.impulses[self.index]


# --- the PSD -----------------------------------------------------------------------------------------------------


def klipper_psd(time_s: Array, accel: Array) -> tuple[Array, Array]:
    """(frequencies, PSD per axis (axes, bins)) as calc_freq_response computes them: fs = N / (t_last - t_0),
    Welch over segments of 2^bitlen(int(fs WINDOW_S - 1)) samples, half overlap, each segment's mean removed, a
    symmetric Kaiser window (beta 6), density scaling, one-sided (scipy.signal.welch with those settings)."""
    from scipy.signal import welch

    n = time_s.size
    fs = n / float(time_s[-1] - time_s[0])
    segment = 1 << int(fs * WINDOW_S - 1).bit_length()
    if n <= segment:
        raise InvalidParameter(
            "body",
            f"{n} samples",
            f"Klipper's spectrum needs more than one segment of {segment} samples ({WINDOW_S} s)",
        )
    window = np.kaiser(segment, KAISER_BETA)
    frequency, psd = welch(accel, fs=fs, window=window, noverlap=segment // 2, detrend="constant", axis=-1)
    return np.asarray(frequency, float), np.atleast_2d(np.asarray(psd, float))


def _normalization(frequency_hz: Array) -> Array:
    """The factor normalize_to_frequencies multiplies a PSD by: 1 / (f + 0.1), below 10 Hz times
    e^(1 - (10 / (f + 0.1))^2)."""
    factor = 1.0 / (frequency_hz + 0.1)
    low = frequency_hz < NORMALIZE_BELOW_HZ
    factor[low] *= np.exp(1.0 - (NORMALIZE_BELOW_HZ / (frequency_hz[low] + 0.1)) ** 2)
    return factor


def normalized(frequency_hz: Array, psd: Array) -> Array:
    """CalibrationData.normalize_to_frequencies (see _normalization)."""
    return np.asarray(psd * _normalization(frequency_hz), float)


def denormalized(frequency_hz: Array, psd: Array) -> Array:
    """A normalised PSD back to the measured one; 0 where the normalisation left nothing to recover (its factor
    below 1e-300: the lowest bins, e^(1 - 10^4) at 0 Hz)."""
    factor = _normalization(frequency_hz)
    return np.asarray(np.where(factor > 1e-300, psd / np.where(factor > 1e-300, factor, 1.0), 0.0), float)


# --- the criteria, vectorised over candidates (rows) --------------------------------------------------------------


def shaper_response(amplitudes: Array, times_s: Array, zeta: float, frequency_hz: Array) -> Array:
    """V (candidates, bins): the residual of a damped oscillator at each frequency after each candidate's impulses."""
    omega = 2.0 * math.pi * frequency_hz
    omega_d = omega * math.sqrt(1.0 - zeta * zeta)
    lag = times_s[:, -1:] - times_s  # (k, m)
    exponent = -zeta * omega[None, :, None] * lag[:, None, :] + 1j * (omega_d[None, :, None] * times_s[:, None, :])
    total = np.abs(np.sum(amplitudes[:, None, :] * np.exp(exponent), axis=-1))
    return np.asarray(total / np.sum(amplitudes, axis=1, keepdims=True), float)


def worst_response(impulses: ImpulseSequence, frequency_hz: Array) -> Array:
    """A shaper's V at each frequency at its worst over TEST_DAMPING_RATIOS (Klipper's graph's shaper curves)."""
    a = np.asarray(impulses.amplitudes, float)[None, :]
    t = np.asarray(impulses.times_s, float)[None, :]
    return np.asarray(np.max([shaper_response(a, t, z, frequency_hz)[0] for z in TEST_DAMPING_RATIOS], axis=0), float)


def worst_vibrations(amplitudes: Array, times_s: Array, frequency_hz: Array, psd: Array) -> Array:
    """The remaining vibrations at their worst over TEST_DAMPING_RATIOS. Only the bins above p_max / 20 are summed: a
    shaper of positive amplitudes has V <= 1, so the others add 0 to both sums (the same number, 5-10x faster)."""
    threshold = float(np.max(psd)) / VIBRATION_REDUCTION
    every = float(np.sum(np.maximum(psd - threshold, 0.0)))
    above = psd > threshold
    if not np.all(amplitudes >= 0):
        above[:] = True
    bins, p = frequency_hz[above], psd[above]
    worst = np.zeros(amplitudes.shape[0])
    rows = max(1, CHUNK_VALUES // max(1, bins.size * amplitudes.shape[1]))
    for first in range(0, amplitudes.shape[0], rows):  # chunks of candidates: bounded memory
        a, t = amplitudes[first : first + rows], times_s[first : first + rows]
        for zeta in TEST_DAMPING_RATIOS:
            left = np.sum(np.maximum(shaper_response(a, t, zeta, bins) * p - threshold, 0.0), axis=1)
            worst[first : first + rows] = np.maximum(worst[first : first + rows], left / every if every > 0 else 0.0)
    return worst


def _smoothing_terms(amplitudes: Array, times_s: Array, scv_mm_s: float) -> tuple[Array, Array, Array]:
    """(c90, s90, s180): the 90-degree offset is c90 + a s90, the 180-degree one a s180 (mm, a in mm/s^2)."""
    total = np.sum(amplitudes, axis=1)
    shift = np.sum(amplitudes * times_s, axis=1) / total
    tau = times_s - shift[:, None]
    after = tau >= 0.0
    c90 = math.sqrt(2.0) * np.sum(np.where(after, amplitudes * scv_mm_s * tau, 0.0), axis=1) / total
    s90 = math.sqrt(2.0) * np.sum(np.where(after, amplitudes * 0.5 * tau * tau, 0.0), axis=1) / total
    s180 = np.sum(amplitudes * 0.5 * tau * tau, axis=1) / total
    return c90, s90, s180


def smoothing_mm(amplitudes: Array, times_s: Array, accel_mm_s2: float, scv_mm_s: float) -> Array:
    c90, s90, s180 = _smoothing_terms(amplitudes, times_s, scv_mm_s)
    return np.asarray(np.maximum(c90 + accel_mm_s2 * s90, accel_mm_s2 * s180), float)


def max_acceleration(amplitudes: Array, times_s: Array, scv_mm_s: float) -> Array:
    """The largest a with smoothing <= 0.12 mm: min((0.12 - c90) / s90, 0.12 / s180), 0 where c90 > 0.12."""
    c90, s90, s180 = _smoothing_terms(amplitudes, times_s, scv_mm_s)
    with np.errstate(divide="ignore"):
        by90 = np.where(s90 > 0, (TARGET_SMOOTHING_MM - c90) / np.where(s90 > 0, s90, 1.0), np.inf)
        by180 = np.where(s180 > 0, TARGET_SMOOTHING_MM / np.where(s180 > 0, s180, 1.0), np.inf)
    return np.asarray(np.maximum(np.minimum(by90, by180), 0.0), float)


def candidate_frequencies(kind: str, low_hz: float | None = None, high_hz: float = MAX_SHAPER_FREQ_HZ) -> Array:
    """fit_shaper's grid: np.arange(min_freq, 150, 0.2) (end excluded), from ``low_hz`` where a firmware's
    range starts higher; each frequency rounded to 1e-9 Hz (arange's sums drift: 42.19999999999993)."""
    start = max(MIN_FREQ_HZ.get(kind, MIN_FREQ_HZ["zv"]), low_hz or 0.0)
    return np.round(np.arange(start, high_hz, FREQ_STEP_HZ), 9)


def evaluate(
    kind: str,
    impulses_of: ImpulsesOf,
    frequency_hz: Array,
    psd: Array,
    scv_mm_s: float = DEFAULT_SCV_MM_S,
    candidates_hz: Array | None = None,
    damping_ratio: float = SHAPER_DAMPING_RATIO,
) -> Scores:
    """Klipper's criteria for ``kind`` (built by ``impulses_of(kind, f, zeta)``) at each candidate frequency over
    the PSD's bins up to 200 Hz."""
    grid = candidate_frequencies(kind) if candidates_hz is None else candidates_hz
    bins, p = scored_bins(frequency_hz, psd, float(grid[-1]) if grid.size else 0.0)
    sequences = tuple(impulses_of(kind, float(f), damping_ratio) for f in grid)
    a, t = _arrays(sequences)
    return Scores(
        kind=kind,
        frequency_hz=np.asarray(grid, float),
        damping_ratio=damping_ratio,
        impulses=sequences,
        vibrations=worst_vibrations(a, t, bins, p),
        smoothing_mm=smoothing_mm(a, t, SMOOTHING_ACCEL_MM_S2, scv_mm_s),
        max_accel_mm_s2=max_acceleration(a, t, scv_mm_s),
    )


def scored_bins(frequency_hz: Array, psd: Array, top_candidate_hz: float = 0.0) -> tuple[Array, Array]:
    """The bins fit_shaper scores: up to max(200 Hz, the highest candidate); at least 2 and some power there (else
    there is nothing to shape), at most MAX_BINS (a 422 otherwise)."""
    keep = frequency_hz <= max(MAX_PSD_FREQ_HZ, top_candidate_hz)
    if np.count_nonzero(keep) < 2 or not np.max(psd[keep], initial=0.0) > 0:
        raise InvalidParameter(
            "body",
            f"{np.count_nonzero(keep)} bins",
            f"the spectrum holds no power in 2 or more bins up to {MAX_PSD_FREQ_HZ:g} Hz: no vibration to shape",
        )
    if np.count_nonzero(keep) > MAX_BINS:
        raise InvalidParameter(
            "body",
            f"{np.count_nonzero(keep)} bins",
            f"at most {MAX_BINS} PSD bins up to {MAX_PSD_FREQ_HZ:g} Hz are scored (Klipper's are 1.6 Hz apart)",
        )
    return frequency_hz[keep], psd[keep]


def _arrays(sequences: Sequence[ImpulseSequence]) -> tuple[Array, Array]:
    a = np.array([s.amplitudes for s in sequences], dtype=float).reshape(len(sequences), -1)
    t = np.array([s.times_s for s in sequences], dtype=float).reshape(len(sequences), -1)
    return a, t


def robust_vibrations(
    scores: Scores, indices: NDArray[np.intp], frequency_hz: Array, psd: Array, ratios: Sequence[float]
) -> Array:
    """The remaining vibrations of the candidates ``indices`` at their worst over the resonances shifted by each of
    ``ratios`` r = f_true / f_measured (and unshifted): the shaper's times scaled by r (V of times r T at f is V of
    T at r f, so the bins sample the shifted PSD p(f / r) at r f: exact for the firmware's own shaper, Marlin's
    whole-sample delays included)."""
    worst: Array = np.array(scores.vibrations[indices], dtype=float)
    if indices.size == 0:
        return worst
    bins, p = scored_bins(frequency_hz, psd, float(scores.frequency_hz[-1]))
    a, t = _arrays([scores.impulses[int(k)] for k in indices])
    for ratio in ratios:
        worst = np.maximum(worst, worst_vibrations(a, t * ratio, bins, p))
    return worst


# --- the picks ----------------------------------------------------------------------------------------------------


def scanned_from(scores: Scores, max_smoothing_mm: float | None) -> int:
    """The lowest candidate fit_shaper looks at: it scans from the highest frequency down and, with
    ``max_smoothing``, stops at the first (after the highest) whose smoothing exceeds it."""
    if max_smoothing_mm is None or scores.frequency_hz.size < 2:
        return 0
    over = np.flatnonzero(scores.smoothing_mm[:-1] > max_smoothing_mm)
    return int(over[-1]) + 1 if over.size else 0


def klipper_fit(scores: Scores, max_smoothing_mm: float | None = None) -> Pick:
    """fit_shaper's choice for one type: the frequency of least vibrations (scanned from the highest: a tie keeps
    the higher), then the one of least score among those within 1.1 x + 0.0005 of it (scanned from the lowest).
    With ``max_smoothing_mm``, where the scan stops early (scanned_from) the least vibrations found so far, with no
    selection by score (as fit_shaper returns then)."""
    v, score = scores.vibrations, scores.score
    first = scanned_from(scores, max_smoothing_mm)
    best = first + int(v.size - first - 1 - np.argmin(v[first:][::-1]))
    if first > 0:
        return Pick(scores, best)
    selected = best
    for k in range(v.size):
        if v[k] < v[best] * 1.1 + 0.0005 and score[k] < score[selected]:
            selected = k
    return Pick(scores, selected)


def klipper_pick(types: Sequence[Scores], max_smoothing_mm: float | None = None) -> tuple[Pick, list[Pick]]:
    """find_best_shaper's choice over the types in order (its rules without max_vibrations: a type wins on a
    20 % better score, or a 5 % better score with 10 % less smoothing; then any of its frequencies fit_shaper
    looked at with both fewer vibrations and less smoothing; a zv winner gives way to the first type with 10 % fewer
    vibrations), and each type's own pick."""
    best: Pick | None = None
    each: list[Pick] = []
    for scores in types:
        pick = klipper_fit(scores, max_smoothing_mm)
        if (
            best is None
            or pick.score * 1.2 < best.score
            or (pick.score * 1.05 < best.score and pick.smoothing_mm * 1.1 < best.smoothing_mm)
        ):
            best = pick
        for k in range(scanned_from(scores, max_smoothing_mm), scores.frequency_hz.size):
            if scores.vibrations[k] < best.vibrations and scores.smoothing_mm[k] < best.smoothing_mm:
                best = pick = Pick(scores, k)
        each.append(pick)
    assert best is not None, "no shaper type"
    if best.kind == "zv":
        best = next((p for p in each if p.kind != "zv" and p.vibrations * 1.1 < best.vibrations), best)
    return best, each
