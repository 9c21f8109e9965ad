"""Coverage of the 95 % intervals of optim.identification.modal over 50 seeded noisy records
(tests/optim/test_identification_modal has the record: two modes, three axes, 2 kHz, noise std 0.02).

An interval at 95 % covers the truth in about 95 % of records: of 50, the count is binomial(50, 0.95), mean 47.5
and standard deviation 1.5, so 44 or more (the mean minus 2.3 standard deviations) is asked of each of the four
quantities (the seeds are fixed: the test is deterministic). ``python -m tests.optim.test_identification_coverage
N`` prints the coverage over N seeds (docs/identification.md's figures: 200 seeds).
"""

from __future__ import annotations

import sys

import numpy as np

from optim.identification.modal import identify_modes
from optim.identification.record import Record
from tests.optim.test_identification_modal import NAMES, TRUTH, accelerometer_record

SEEDS = 50
MIN_COVERED = 44


def coverage(seeds: range) -> np.ndarray:
    """(2 modes, [f_n, zeta]): how many records' intervals cover the truth."""
    covered = np.zeros((2, 2), dtype=int)
    for seed in seeds:
        t, signals = accelerometer_record(seed=1000 + seed)
        modes = identify_modes(Record(t, signals, NAMES)).modes
        assert len(modes) == 2, seed
        for k, (mode, (f, zeta)) in enumerate(zip(modes, TRUTH, strict=True)):
            covered[k, 0] += mode.natural_frequency_ci_hz[0] <= f <= mode.natural_frequency_ci_hz[1]
            covered[k, 1] += mode.damping_ratio_ci[0] <= zeta <= mode.damping_ratio_ci[1]
    return covered


def test_the_95_percent_intervals_cover_the_truth_in_about_95_percent_of_records():
    covered = coverage(range(SEEDS))
    assert np.all(covered >= MIN_COVERED), covered
    assert np.all(covered <= SEEDS), covered


if __name__ == "__main__":
    n = int(sys.argv[1]) if len(sys.argv) > 1 else SEEDS
    counts = coverage(range(n))
    for k, (f, _zeta) in enumerate(TRUTH):
        print(
            f"mode {f:g} Hz: f_n covered {counts[k, 0]}/{n} = {counts[k, 0] / n:.3f}, "
            f"zeta covered {counts[k, 1]}/{n} = {counts[k, 1] / n:.3f}"
        )
