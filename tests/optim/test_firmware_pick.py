"""The firmware's shaper from a spectrum (optim.families.input_shaped.firmware_pick): robust over a frequency
interval, never worse than its reference by Klipper's criteria.

The spectrum is analytic, so a shift of the resonances is exact: p(f) = sum of two resonance peaks (42 Hz zeta 0.07
and 71 Hz zeta 0.10, |H|^2 of a mode times f^2) plus a floor, on 0.2 Hz bins to 200 Hz, normalised as Klipper
normalises. Shifted by r, the resonances are p(f / r): computed directly, not through the shaper's scaled times
the code uses.
"""

from __future__ import annotations

import numpy as np
import pytest

from optim.families.input_shaped import calibration as cal
from optim.families.input_shaped.firmware import klipper_impulses
from optim.families.input_shaped.firmware_pick import firmware_pick

FREQUENCY_HZ = np.arange(0.0, 200.0, 0.2)


def spectrum(ratio: float = 1.0) -> np.ndarray:
    f = FREQUENCY_HZ / ratio
    total = np.full_like(f, 20.0)
    for fn, zeta, gain in ((42.0, 0.07, 1.0), (71.0, 0.10, 0.5)):
        r = f / fn
        total += gain * 1e4 * r**2 * (1 + (2 * zeta * r) ** 2) / ((1 - r**2) ** 2 + (2 * zeta * r) ** 2)
    return cal.normalized(FREQUENCY_HZ, total)


def test_a_shift_of_the_resonances_is_the_shaper_scaled_in_time():
    """The robust vibrations at r (the shaper's times x r against p) against the shaper as it is against p(f / r),
    for shifts of -5 % and +5 %: equal to the two Riemann sums' difference (bins 0.2 Hz, peaks several Hz wide:
    within 1e-3 of the spectrum's share)."""
    scores = cal.evaluate("mzv", klipper_impulses, FREQUENCY_HZ, spectrum(), candidates_hz=np.array([40.0, 44.0]))
    for ratio in (0.95, 1.05):
        scaled = cal.robust_vibrations(scores, np.array([0, 1], dtype=np.intp), FREQUENCY_HZ, spectrum(), [ratio])
        direct = cal.evaluate(
            "mzv", klipper_impulses, FREQUENCY_HZ, spectrum(ratio), candidates_hz=np.array([40.0, 44.0])
        )
        assert np.maximum(direct.vibrations, scores.vibrations) == pytest.approx(scaled, abs=1e-3)
        assert np.any(direct.vibrations > scores.vibrations + 1e-3)  # (the shift matters: the check is not empty)


@pytest.mark.parametrize("robust_first", [False, True])
@pytest.mark.parametrize("target", ["klipper", "reprapfirmware", "marlin"])
def test_the_pick_is_the_most_robust_of_those_no_worse_than_its_reference(target, robust_first):
    """By brute force over every candidate of every type of the target: none as fast as the reference and leaving
    no more vibrations (with ``robust_first``, whatever it leaves unshifted) leaves less over the interval. The
    reference is Klipper's pick where the target can match it (always for Klipper: its pick is among the
    candidates), else the target's own pick by Klipper's rules."""
    interval = (0.95, 1.05)
    choice = firmware_pick(FREQUENCY_HZ, spectrum(), target, interval, robust_first=robust_first)
    ratios = list(np.linspace(*interval, 5))
    reference = choice.reference
    assert (reference is choice.klipper) == (not choice.note)
    assert robust_first or (reference is choice.klipper) == choice.dominates
    if target == "klipper":
        assert choice.dominates
    pick = choice.pick
    assert pick.max_accel_mm_s2 >= reference.max_accel_mm_s2 * (1 - 1e-12)
    assert robust_first or pick.vibrations <= reference.vibrations
    least = np.inf
    for scores in choice.candidates:
        quiet = scores.vibrations <= (np.inf if robust_first else reference.vibrations)
        ok = np.flatnonzero((scores.max_accel_mm_s2 >= reference.max_accel_mm_s2 * (1 - 1e-12)) & quiet)
        least = min(
            least, float(np.min(cal.robust_vibrations(scores, ok, FREQUENCY_HZ, spectrum(), ratios), initial=np.inf))
        )
    assert choice.robust_vibrations == least
    if not any(reference.scores is s for s in choice.candidates):  # (Klipper's pick, another firmware's types)
        return
    reference_worst = cal.robust_vibrations(
        reference.scores, np.array([reference.index], dtype=np.intp), FREQUENCY_HZ, spectrum(), ratios
    )
    assert choice.robust_vibrations <= reference_worst[0]


@pytest.mark.parametrize("target", ["klipper", "reprapfirmware", "marlin"])
def test_max_smoothing_bounds_the_pick_and_makes_klippers(target):
    """Klipper's max_smoothing (0.09 mm here): its pick is fit_shaper's under it (as
    tests/optim/test_klipper_calibration.py checks against Klipper's code), and no recommended shaper smooths more
    (nor than that pick, where even it does)."""
    limit = 0.09
    choice = firmware_pick(FREQUENCY_HZ, spectrum(), target, (0.95, 1.05), max_smoothing_mm=limit)
    types = [cal.evaluate(kind, klipper_impulses, FREQUENCY_HZ, spectrum()) for kind in cal.KLIPPER_TYPES]
    klipper, _ = cal.klipper_pick(types, limit)
    assert (choice.klipper.kind, choice.klipper.frequency_hz) == (klipper.kind, klipper.frequency_hz)
    assert klipper.smoothing_mm <= limit
    assert choice.pick.smoothing_mm <= max(limit, choice.reference.smoothing_mm)
    unbounded = firmware_pick(FREQUENCY_HZ, spectrum(), target, (0.95, 1.05))
    assert unbounded.klipper.smoothing_mm > limit  # (the bound binds: the check is not empty)
