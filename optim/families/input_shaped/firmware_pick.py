"""The shaper to set in a printer's firmware, from a measured acceleration PSD (the identify use case's
``recommendation`` with a ``target``).

Every type the target firmware runs (its own impulses: optim.families.input_shaped.firmware) is scored at every
0.2 Hz by Klipper's criteria (optim.families.input_shaped.calibration). The reference is the shaper Klipper's
calibration picks on the same PSD. The recommendation is, of the target's candidates whose max_accel is at least the
reference's and whose remaining vibrations are no more than its, the one whose remaining vibrations at their worst
over the identified frequency interval (the resonances shifted by ROBUST_POINTS ratios across it) are least, then
the fastest: never worse than Klipper's pick by Klipper's own criteria, and robust where the measurement is
uncertain. Where no candidate of the target qualifies (a firmware without Klipper's pick's type), the reference is
the target's own pick by Klipper's rules instead, said so.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from models.plants import Mode
from models.shapers import ImpulseSequence
from optim.families.input_shaped import calibration as cal
from optim.families.input_shaped.firmware import (
    KLIPPER_DEFAULT_V_TOL,
    MARLIN_FTM_FS_HZ,
    MARLIN_MIN_SHAPE_FREQ_HZ,
    RRF_FREQUENCY_HZ,
    klipper_impulses,
    marlin_impulses,
    rrf_impulses,
)
from optim.families.input_shaped.firmware_blocks import FirmwareReport, firmware_block
from optim.families.input_shaped.shapers import ShaperDesign

__all__ = ["ROBUST_POINTS", "TARGETS", "FirmwarePick", "firmware_pick", "most_robust", "pick_design"]

TARGETS = ("klipper", "reprapfirmware", "marlin")
ROBUST_POINTS = 5  # resonance shifts evaluated across the interval (its ends and three between)
# each firmware's types under our names (optim.families.input_shaped.shapers) and its own name for them
_RRF = {"zvd": "zvd", "zvdd": "zvdd", "zvddd": "zvddd", "mzv": "mzv", "2hump_ei": "ei2", "3hump_ei": "ei3"}
_KLIPPER = ("zv", "mzv", "zvd", "ei", "2hump_ei", "3hump_ei")
_MARLIN = ("zv", "zvd", "zvdd", "zvddd", "ei", "2hump_ei", "3hump_ei", "mzv")


@dataclass(frozen=True)
class FirmwarePick:
    target: str
    pick: cal.Pick
    firmware_type: str  # the firmware's own name of the pick's type (RRF: ei2, ei3)
    klipper: cal.Pick  # the reference: Klipper's calibration's pick
    klipper_each: tuple[cal.Pick, ...]  # Klipper's pick of each of its types
    reference: cal.Pick  # what the pick is no worse than: Klipper's pick, else the target's own by Klipper's rules
    candidates: tuple[cal.Scores, ...]  # the target's types, scored
    robust_vibrations: float  # the pick's remaining vibrations at their worst over the interval
    interval: tuple[float, float]  # frequency ratio f_true / f_measured the resonances were shifted over
    dominates: bool  # no more vibrations and no lower max_accel than Klipper's pick
    note: str


def _builder(target: str, kind: str) -> cal.ImpulsesOf:
    if target == "reprapfirmware":
        return lambda _, f, z: rrf_impulses(_RRF[kind], f, z)
    if target == "marlin":
        return lambda _, f, z: marlin_impulses(kind, f, z, KLIPPER_DEFAULT_V_TOL)
    return klipper_impulses


def _grid(target: str, kind: str) -> np.ndarray:
    """Klipper's candidates of the type within what the firmware's frequency parameter takes."""
    low, high = {
        "reprapfirmware": RRF_FREQUENCY_HZ,
        "marlin": (MARLIN_MIN_SHAPE_FREQ_HZ, MARLIN_FTM_FS_HZ / 2),
    }.get(target, (0.0, math.inf))
    return cal.candidate_frequencies(kind, low, min(cal.MAX_SHAPER_FREQ_HZ, high))


def _types(target: str) -> tuple[str, ...]:
    return {"reprapfirmware": tuple(_RRF), "marlin": _MARLIN}.get(target, _KLIPPER)


def _target_scores(
    target: str, klipper_types: list[cal.Scores], frequency_hz: np.ndarray, psd: np.ndarray, scv_mm_s: float
) -> list[cal.Scores]:
    """The target's types scored (Klipper's own reused: the same impulses on the same grid)."""
    known = {s.kind: s for s in klipper_types} if target == "klipper" else {}
    scores = [
        known.get(k) or cal.evaluate(k, _builder(target, k), frequency_hz, psd, scv_mm_s, _grid(target, k))
        for k in _types(target)
    ]
    return [s for s in scores if s.frequency_hz.size]


def _qualifying(
    s: cal.Scores, reference: cal.Pick, robust_first: bool, max_smoothing_mm: float | None
) -> NDArray[np.bool_]:
    """The candidates as fast as ``reference``, (unless ``robust_first``) leaving no more vibrations, and (with
    ``max_smoothing_mm``) smoothing no more than it, or than the reference where even it does (fit_shaper keeps its
    highest frequency whatever it smooths)."""
    ok = s.max_accel_mm_s2 >= reference.max_accel_mm_s2 * (1 - 1e-12)
    if not robust_first:
        ok &= s.vibrations <= reference.vibrations
    if max_smoothing_mm is not None:
        ok &= s.smoothing_mm <= max(max_smoothing_mm, reference.smoothing_mm)
    return ok


def most_robust(
    scores: list[cal.Scores],
    reference: cal.Pick,
    frequency_hz: np.ndarray,
    psd: np.ndarray,
    ratios: list[float],
    robust_first: bool,
    max_smoothing_mm: float | None,
) -> tuple[float, float, cal.Pick] | None:
    """Of the candidates _qualifying: the one leaving least over the ratios, then the fastest ((worst vibrations,
    -max_accel, pick)); None where none qualifies. Only those are shifted (each shift costs an evaluation)."""
    best: tuple[float, float, cal.Pick] | None = None
    for s in scores:
        ok = np.flatnonzero(_qualifying(s, reference, robust_first, max_smoothing_mm))
        for k, worst in zip(ok, cal.robust_vibrations(s, ok, frequency_hz, psd, ratios), strict=True):
            key = (float(worst), -float(s.max_accel_mm_s2[k]))
            if best is None or key < best[:2]:
                best = (*key, cal.Pick(s, int(k)))
    return best


def firmware_pick(
    frequency_hz: np.ndarray,
    psd: np.ndarray,
    target: str,
    interval: tuple[float, float] = (1.0, 1.0),
    scv_mm_s: float = cal.DEFAULT_SCV_MM_S,
    robust_first: bool = False,
    max_smoothing_mm: float | None = None,
) -> FirmwarePick:
    """The recommendation of the module's docstring for ``target`` over the (normalised) PSD; with
    ``robust_first`` (an interval the user asked for), the least vibrations over it of the candidates as fast as
    the reference, whatever they leave unshifted (then never worse than the reference over the interval); with
    ``max_smoothing_mm`` (Klipper's max_smoothing), Klipper's pick under it and no candidate smoothing more."""
    klipper_types = [cal.evaluate(kind, klipper_impulses, frequency_hz, psd, scv_mm_s) for kind in cal.KLIPPER_TYPES]
    reference, each = cal.klipper_pick(klipper_types, max_smoothing_mm)
    scores = _target_scores(target, klipper_types, frequency_hz, psd, scv_mm_s)
    ratios = np.linspace(*interval, ROBUST_POINTS).tolist() if interval[0] < interval[1] else []
    note, used = "", reference
    # some candidate of the target is as fast as Klipper's pick and leaves no more vibrations
    matched = any(np.any(_qualifying(s, reference, False, max_smoothing_mm)) for s in scores)
    if not matched:  # the firmware's own pick by Klipper's rules is the reference instead (it qualifies)
        used, _ = cal.klipper_pick(scores, max_smoothing_mm)
        own = used
        note = (
            f"No {target} shaper is both as fast as and no more vibrating than Klipper's pick ({reference.kind} at "
            f"{reference.frequency_hz:.1f} Hz): the reference is the {target} types' own pick by Klipper's rules "
            f"({own.kind} at {own.frequency_hz:.1f} Hz)"
        )
    best = most_robust(scores, used, frequency_hz, psd, ratios, robust_first, max_smoothing_mm)
    assert best is not None  # (a candidate qualifies: the reference itself, or the one that matched it)
    pick = best[2]
    return FirmwarePick(
        target=target,
        pick=pick,
        firmware_type=_RRF[pick.kind] if target == "reprapfirmware" else pick.kind,
        klipper=reference,
        klipper_each=tuple(each),
        reference=used,
        candidates=tuple(scores),
        robust_vibrations=best[0],
        interval=interval,
        dominates=pick.vibrations <= reference.vibrations
        and pick.max_accel_mm_s2 >= reference.max_accel_mm_s2 * (1 - 1e-12),
        note=note,
    )


def pick_design(pick: cal.Pick, reference: str) -> ShaperDesign:
    """The pick as a shaper design (its impulses at its frequency and damping), for its firmware blocks."""
    mode = Mode(2.0 * math.pi * pick.frequency_hz, pick.scores.damping_ratio)
    impulses: ImpulseSequence = pick.impulses
    tolerance = KLIPPER_DEFAULT_V_TOL if pick.kind in ("ei", "2hump_ei", "3hump_ei") else None
    return ShaperDesign(pick.kind, (mode,), impulses, tolerance, "firmware calibration", reference, None)


def firmware_report(pick: cal.Pick, reference: str) -> FirmwareReport:
    """The pick's ``firmware`` blocks (the input-shaped design's ``design.firmware``)."""
    return firmware_block(pick_design(pick, reference))


def each_type(picks: Sequence[cal.Pick]) -> list[dict[str, float | str]]:
    """Klipper's pick of each type, as its log lists them."""
    return [
        {
            "type": p.kind,
            "frequency_hz": p.frequency_hz,
            "remaining_vibration_percent": 100.0 * p.vibrations,
            "smoothing_mm": p.smoothing_mm,
            "max_acceleration": p.max_accel_mm_s2,
        }
        for p in picks
    ]
