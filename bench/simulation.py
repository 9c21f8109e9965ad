"""Benchmark: 100k samples through a second-order mode, ours against scipy.signal.lsim.

Run with `make bench`; the figures go in README.md. Both simulate the same input, a first-order
hold on the position (what lsim does); ours also with a first-order hold on the acceleration
(its usual use) and on a non-uniform grid, where lsim has no equivalent.
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

import numpy as np
from scipy import signal

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from models.commands import PiecewiseCommand
from models.plants import ModePlant
from models.simulation import metrics, simulate

SAMPLES = 100_000


def median_ms(fn, repeats: int) -> float:
    fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return 1e3 * statistics.median(times)


def main() -> None:
    plant = ModePlant(5.0, 0.05)
    t = np.linspace(0.0, 10.0, SAMPLES)
    acc = np.sin(2 * np.pi * 0.3 * t) * np.exp(-0.1 * t)
    by_acc = PiecewiseCommand.from_samples(t, acc, 2)
    pos = by_acc.derivative(0)
    by_pos = PiecewiseCommand.from_samples(t, pos, 0)
    rng = np.random.default_rng(0)
    tn = t + rng.uniform(-0.3, 0.3, SAMPLES) * (t[1] - t[0])  # a jittered grid
    tn[0], tn[-1] = 0.0, 10.0
    ss = plant.state_space()
    system = signal.StateSpace(ss.a, ss.b, ss.c, ss.d)

    ours_pos = simulate(plant, by_pos).load_position
    lsim_pos = signal.lsim(system, pos, t)[1]

    # Every timing starts from the samples, as a request does: build the command, then simulate.
    def ours(times: np.ndarray, values: np.ndarray, order: int) -> None:
        simulate(plant, PiecewiseCommand.from_samples(times, values, order))

    rows = [
        ("ours, first-order hold on position", median_ms(lambda: ours(t, pos, 0), 30)),
        ("ours, first-order hold on acceleration", median_ms(lambda: ours(t, acc, 2), 30)),
        ("ours, acceleration, non-uniform grid", median_ms(lambda: ours(tn, np.sin(tn), 2), 10)),
        (
            "ours, acceleration + all metrics",
            median_ms(lambda: metrics(simulate(plant, PiecewiseCommand.from_samples(t, acc, 2))), 10),
        ),
        ("scipy.signal.lsim, same position input", median_ms(lambda: signal.lsim(system, pos, t), 5)),
    ]
    print(f"{SAMPLES} samples, one mode (5 Hz, zeta 0.05), median wall time:")
    for name, ms in rows:
        print(f"  {name:42s} {ms:9.2f} ms")
    gap = np.max(np.abs(ours_pos - lsim_pos)) / np.max(np.abs(lsim_pos))
    print(f"  largest difference from lsim, relative: {gap:.1e}")


if __name__ == "__main__":
    main()
