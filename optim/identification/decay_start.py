"""Where a free decay starts when nothing says so: after the excitation, found by the fits themselves.

A record with neither a command column nor ``start_s`` is fitted from its largest excursion, which falls inside the
excitation when the excitation lasts longer than a fraction of a period (a knock of 2 x 20 ms on a 42 Hz mode:
43.06 Hz with zeta 0.31, its interval excluding the truth). The forced part is not a sum of damped sinusoids, so a fit
that starts inside it is biased, while one that starts in the free decay is not. Two tests tell them apart:

- the onset: ``ModalIdentification.onset_misfit``, the residual of the window's first 8 to 128 samples against the
  noise (a misfit at level 1e-3 where it exceeds 1);
- the agreement with the fit SHIFT samples later (a Hausman test): both are unbiased in a free decay, and the later
  one, on fewer samples, is the noisier, so their difference has the variance of the later estimate less the
  earlier's (Hausman 1978; at least MIN_VARIANCE_GAIN of the earlier's). Each mode's f_n and zeta must agree within
  AGREE_Z of that standard deviation. A fit that a forced sample biases differs by far more than its own interval
  while its onset still passes (knocks of bench/identify_coverage.py: 1.3 % on f from 6 samples inside a knock).

The start is the earliest sample after the largest excursion whose fit passes both, found by doubling the offset
(0, 1, 2, 4, ... samples, at most STEPS / 2 periods of the record's lowest spectral peak) and then bisecting between
the last offset that failed and the first that passed (a start past the excitation passes, and so do later ones):
about 2 log2 of that span fits, each made once, at most MAX_START_FITS, each on at most SEARCH_VALUES samples x
signals from the excursion (a 13 s record took 155 s to search on all of it; its decay is gone after a second). The
answer fits the whole record from the start found. Where none passes, the largest excursion's fit is kept, with a
warning.

Ref: J. A. Hausman, Specification tests in econometrics, Econometrica 46 (1978) 1251-1271.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from models.errors import InvalidParameter
from optim.identification.modal import MIN_DETECTION_SNR, ModalIdentification, identify_modes
from optim.identification.record import Record

__all__ = ["AGREE_Z", "MAX_START_FITS", "SHIFT", "STEPS", "identify_free_decay"]

STEPS = 8  # half periods of the lowest spectral peak: the latest start tried after the largest excursion (4 periods)
SHIFT = 8  # samples between a fit and the later one it must agree with
AGREE_Z = 3.5  # standard deviations of their difference (two-sided 5e-4 per quantity)
MIN_VARIANCE_GAIN = 0.1  # the later fit's variance exceeds the earlier's by at least this share of it
MAX_START_FITS = 24  # fits the search makes at most; beyond, none passes
# samples x signals each of its fits takes at most (8192 samples of three axes, 2.6 s at 3200 Hz)
SEARCH_VALUES = 24_576


def _disagreement(early: ModalIdentification, late: ModalIdentification) -> float:
    """The largest |difference| / its standard deviation, over the modes of ``early`` that ``late`` also holds
    (within 5 %), of f_n and zeta (the module's Hausman test); infinite where a mode of ``early`` clear of the noise
    (detection SNR twice the least reported) has none in ``late``: a mode does not vanish or move 5 % in SHIFT samples,
    a fit absorbing the forced motion does (a "mode" sliding from 103 to 177 Hz as the start left a knock)."""
    worst = 0.0
    for mode in early.modes:
        near = min(late.modes, key=lambda m: abs(m.natural_frequency_hz - mode.natural_frequency_hz))
        if abs(near.natural_frequency_hz - mode.natural_frequency_hz) > 0.05 * mode.natural_frequency_hz:
            if mode.detection_snr >= 2.0 * MIN_DETECTION_SNR:
                return math.inf
            continue
        pairs = (
            (mode.natural_frequency_hz, near.natural_frequency_hz, mode.natural_frequency_std_hz,
             near.natural_frequency_std_hz),
            (mode.damping_ratio, near.damping_ratio, mode.damping_ratio_std, near.damping_ratio_std),
        )  # fmt: skip
        for a, b, std_a, std_b in pairs:
            variance = max(std_b * std_b - std_a * std_a, MIN_VARIANCE_GAIN * std_a * std_a)
            worst = max(worst, abs(a - b) / math.sqrt(variance)) if variance > 0 else math.inf
    return worst


def _part(record: Record, start_s: float, end_s: float) -> Record:
    """The record's samples between ``start_s`` and ``end_s`` (the record itself where that is all of it after
    ``start_s``), without its command (a record with a command is not searched)."""
    time_s = np.asarray(record.time_s)
    if end_s >= float(time_s[-1]):
        return record
    low, high = int(np.searchsorted(time_s, start_s)), int(np.searchsorted(time_s, end_s, side="right"))
    return Record(time_s[low:high], np.atleast_2d(np.asarray(record.signals))[:, low:high], record.names)


def _earliest_passing(passes: Callable[[int], ModalIdentification | None], last: int) -> ModalIdentification | None:
    """The fit from the earliest offset in 0..``last`` that passes, by doubling (0, 1, 2, 4, ...) then bisection."""
    failed, offset = -1, 0
    found: tuple[int, ModalIdentification] | None = None
    while offset <= last:
        fit = passes(offset)
        if fit is not None:
            found = (offset, fit)
            break
        failed, offset = offset, max(1, 2 * offset)
    if found is None:
        return None
    while found[0] - failed > 1:
        mid = (failed + found[0]) // 2
        fit = passes(mid)
        if fit is None:
            failed = mid
        else:
            found = (mid, fit)
    return found[1]


def identify_free_decay(record: Record, *, max_modes: int = 4, start_s: float | None = None) -> ModalIdentification:
    """optim.identification.modal.identify_modes, from the free decay's start found as the module says where the
    record has no command and no ``start_s``."""
    first = identify_modes(record, max_modes=max_modes, start_s=start_s)
    if start_s is not None or record.command is not None:
        return first
    dt = 1.0 / first.sample_rate_hz
    signals = np.atleast_2d(np.asarray(record.signals))
    span = max(SEARCH_VALUES // signals.shape[0], 4 * SHIFT)  # samples the search fits, from the excursion
    last = min(int(0.5 * STEPS / min(m.peak_frequency_hz for m in first.modes) / dt), span // 2)
    part = _part(record, first.window_start_s - 0.5 * dt, first.window_start_s + span * dt)
    fits: dict[int, ModalIdentification | None] = {0: first} if part is record else {}

    def fit_at(offset: int) -> ModalIdentification | None:
        if offset not in fits and len(fits) >= MAX_START_FITS:
            return None  # (the work is bounded: counted in fits, never timed)
        if offset not in fits:
            try:
                fits[offset] = identify_modes(
                    part, max_modes=max_modes, start_s=first.window_start_s + (offset - 0.5) * dt
                )
            except InvalidParameter:  # (too little left, or no clear vibration from there: a later start may fit)
                fits[offset] = None
        return fits[offset]

    def passes(offset: int) -> ModalIdentification | None:
        fit = fit_at(offset)
        if fit is None or fit.onset_misfit > 1.0:
            return None
        later = fit_at(offset + SHIFT)
        return fit if later is None or _disagreement(fit, later) <= AGREE_Z else None

    fit = _earliest_passing(passes, last)
    if fit is first or (fit is not None and fit.window_start_s <= first.window_start_s + 0.5 * dt):
        return first
    if fit is not None:
        if part is not record:  # the answer fits the whole record from the start found
            fit = identify_modes(record, max_modes=max_modes, start_s=fit.window_start_s - 0.5 * dt)
        note = (
            f"the fit starts {fit.window_start_s - first.window_start_s:.4g} s after the largest excursion: from "
            "there its first samples leave the noise alone and it agrees with the fit from "
            f"{SHIFT} samples later (from the excursion, the excitation was still on)"
        )
        return ModalIdentification(
            **{**vars(fit), "window_source": "residual_at_noise", "warnings": (*fit.warnings, note)}
        )
    note = (
        f"no fit from the largest excursion up to {STEPS / 2:g} periods later leaves its first samples to the noise "
        f"and agrees with the fit {SHIFT} samples later (from the excursion, its first samples' misfit is "
        f"{first.onset_misfit:.3g} times the noise's bound): the excitation may still be on where the fit starts, or "
        "the record is no free decay (give start_s, or the command as a column)"
    )
    return ModalIdentification(**{**vars(first), "warnings": (*first.warnings, note)})
