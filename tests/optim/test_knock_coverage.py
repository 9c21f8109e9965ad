"""Issue 27's seeded Monte-Carlo check, in the suite: knock records in Klipper's accelerometer CSV, identified as
POST /v1/identify does (app.services.identify.identify_record_csv, no parameters), against their known truth.

The records are tests/printer_records.knock_case's seeds 400-459 (one or two modes at 20-120 Hz, the second up to
200 Hz, zeta 0.02-0.15, noise 0-30 % of the free decay's peak), which no rule of optim.identification was tuned on
(bench/identify_coverage.py: tuned on seeds 0-199, checked on 200-399 and 600-799, where the 95 % intervals held the
true f_n for 90.2-91.8 % of the modes found and zeta for 88.8-95.7 %).

What is asked, and why those numbers:

- A record is refused only where no true mode's detection SNR (sqrt of its free decay's energy over the noise
  variance, from the truth) reaches 15: the fit asks 10 of its estimate, which scatters about the truth by about 1
  (a refusal of a clearer decay means it was not looked for where it rings; before the decay's own spectra, 60 of
  67 records at 20-30 % noise were refused, at true SNRs up to 60). Here 1 of 60 is refused (at 12.6 and 10.4).
- Coverage: of the 74 modes found (of 91), a 92 % rate (the bench's) gives 68 +- 2.3 covered; at least 84 % is
  asked of f_n and of zeta (about the bench's rate less 3 standard deviations of that count). Measured: 90.5 % and
  90.5 %.
- Modes missed (none identified within 5 %, or their record refused) at most 20 % of the true modes: the weak second
  modes (detection SNR under 10) that the fit may not claim. Measured: 17 of 91 (18.7 %; the bench: 11-16 %).

Before the decay's own spectra, the residual's components and the start's tests (23ce762), these seeds fail it: 33 of
60 records refused and 58 of 91 modes missed; its intervals held 87.9 % (f_n) and 84.8 % (zeta) of the 33 modes it
found, mostly the clear ones.
"""

from __future__ import annotations

import numpy as np

from app.schemas.identify import MeasurementParams
from app.services.identify import identify_record_csv
from models.errors import InvalidParameter
from tests.printer_records import KNOCK_END_S, RATE_HZ, Modes, estimate_of, knock, knock_case, toolhead

SEEDS = range(400, 460)
MIN_COVERED = 0.84
MAX_MISSED = 0.20
CLEAR_SNR = 15.0


def _true_detection_snr(modes: Modes, share: float) -> list[float]:
    """Each mode's sqrt(sum of its noise-free free decay squared) / the noise's std (knock_case's noise)."""
    command = knock(RATE_HZ, 1.0)
    after = int(KNOCK_END_S * RATE_HZ)
    noise = share * float(np.max(np.abs(toolhead(command, RATE_HZ, modes)[after:])))
    return [float(np.sqrt(np.sum(toolhead(command, RATE_HZ, (m,))[after + 1 :] ** 2))) / noise for m in modes]


def test_knock_intervals_cover_the_truth_and_only_unclear_records_are_refused() -> None:
    found = covered_f = covered_zeta = total = 0
    for seed in SEEDS:
        modes, share, text = knock_case(seed, "klipper_raw")
        try:
            fitted = identify_record_csv(text, MeasurementParams(), 600_000).result.modes
        except InvalidParameter:
            assert max(_true_detection_snr(modes, share)) < CLEAR_SNR, seed
            total += len(modes)
            continue
        for f, zeta, _ in modes:
            total += 1
            near = estimate_of(fitted, f)
            if near is None:
                continue
            found += 1
            covered_f += near.natural_frequency_ci_hz[0] <= f <= near.natural_frequency_ci_hz[1]
            covered_zeta += near.damping_ratio_ci[0] <= zeta <= near.damping_ratio_ci[1]
    assert total - found <= MAX_MISSED * total, (total, found)
    assert covered_f >= MIN_COVERED * found, (covered_f, found)
    assert covered_zeta >= MIN_COVERED * found, (covered_zeta, found)
