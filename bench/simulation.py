"""Benchmark: 100k samples through one mode, ours against one exact recurrence and scipy.signal.lsim.

Run with `make bench`; the figures go in docs/benchmarks.md. Every figure is a median of several repeats taken
in the same run, interleaved (ours, the recurrence, ours, ...), and reported as ratios, so that the
load of a shared machine cancels.

- Ours: ``simulate(plant, PiecewiseCommand.from_samples(t, position, 0))``, from the samples (what
  /v1/simulate receives) to the load's position, velocity and acceleration; a first-order hold on the
  position, which is what lsim does. Also with a first-order hold on the acceleration (how STAP profiles
  are simulated: two more exact integrals) and on a jittered grid, where neither reference applies.
- One exact recurrence: ``scipy.signal.lfilter(b, a, position)`` with (b, a) the exact first-order-hold
  discretisation of the mode at the grid's step, ``scipy.signal.cont2discrete(..., method="foh")`` (built
  with ``expm``) of ``plant.state_space()``, as a transfer function (``ss2tf``): 100k steps of a
  second-order direct form, the load position only. Its (b, a) are computed outside the timing.
- ``scipy.signal.lsim(system, position, t)`` (linear interpolation of the input: the same hold).

The disagreement is max |ours - lsim| over the load position, relative to max |lsim's load position|.

Allocator: glibc returns freed blocks above its mmap threshold to the system and raises that threshold
after the first large block is freed (mallopt(3), M_MMAP_THRESHOLD); a serving process has done so with
its first large response body. Here one 20 MB block is freed first, so that every measurement runs in
that state rather than paying page faults that a server does not pay.
"""

from __future__ import annotations

import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from scipy import signal

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from models.commands import PiecewiseCommand
from models.metrics import metrics
from models.plants import ModePlant
from models.simulation import simulate

SAMPLES = 100_000
REPEATS = 25
LSIM_REPEATS = 3


def timed(fn: Callable[[], object]) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def medians_ms(functions: dict[str, Callable[[], object]], repeats: int) -> dict[str, float]:
    """Median wall time of each function, the functions interleaved in every repeat (after one warm-up)."""
    for fn in functions.values():
        fn()
    times: dict[str, list[float]] = {name: [] for name in functions}
    for _ in range(repeats):
        for name, fn in functions.items():
            times[name].append(timed(fn))
    return {name: 1e3 * statistics.median(values) for name, values in times.items()}


def main() -> None:
    block = np.ones(2_500_000)  # 20 MB, freed: see the module docstring (allocator)
    del block
    plant = ModePlant(5.0, 0.05)
    t = np.linspace(0.0, 10.0, SAMPLES)
    step_s = float(t[1] - t[0])
    acc = np.sin(2 * np.pi * 0.3 * t) * np.exp(-0.1 * t)
    pos = np.array(PiecewiseCommand.from_samples(t, acc, 2).derivative(0))
    rng = np.random.default_rng(0)
    tn = t + rng.uniform(-0.3, 0.3, SAMPLES) * step_s  # a jittered grid
    tn[0], tn[-1] = 0.0, 10.0
    ss = plant.state_space()
    system = signal.StateSpace(ss.a, ss.b, ss.c, ss.d)
    ad, bd, cd, dd, _ = signal.cont2discrete((ss.a, ss.b, ss.c, ss.d), step_s, method="foh")
    num, den = signal.ss2tf(ad, bd, cd, dd)
    b, a = num[0], den

    def ours(times: np.ndarray, values: np.ndarray, order: int) -> object:
        response = simulate(plant, PiecewiseCommand.from_samples(times, values, order))
        return response.load_position, response.load_velocity, response.load_acceleration

    fast = medians_ms(
        {
            "ours": lambda: ours(t, pos, 0),
            "recurrence": lambda: signal.lfilter(b, a, pos),
            "ours_acceleration": lambda: ours(t, acc, 2),
            "ours_nonuniform": lambda: ours(tn, np.sin(tn), 2),
            "ours_metrics": lambda: metrics(simulate(plant, PiecewiseCommand.from_samples(t, acc, 2))),
        },
        REPEATS,
    )
    slow = medians_ms({"lsim": lambda: signal.lsim(system, pos, t)}, LSIM_REPEATS)

    ours_pos = simulate(plant, PiecewiseCommand.from_samples(t, pos, 0)).load_position
    lsim_pos = signal.lsim(system, pos, t)[1]
    recurrence_pos = signal.lfilter(b, a, pos)
    scale = float(np.max(np.abs(lsim_pos)))
    print(
        f"{SAMPLES} samples, one mode (5 Hz, zeta 0.05), "
        f"medians of {REPEATS} interleaved repeats (lsim {LSIM_REPEATS}):"
    )
    rows = [
        ("ours, first-order hold on position (pos, vel, acc)", fast["ours"]),
        ("one exact recurrence (lfilter, FOH, position only)", fast["recurrence"]),
        ("ours, first-order hold on acceleration", fast["ours_acceleration"]),
        ("ours, acceleration, non-uniform grid", fast["ours_nonuniform"]),
        ("ours, acceleration + all metrics", fast["ours_metrics"]),
        ("scipy.signal.lsim, same position input", slow["lsim"]),
    ]
    for name, ms in rows:
        print(f"  {name:52s} {ms:9.2f} ms")
    print(f"  ours / recurrence (target <= 3):             {fast['ours'] / fast['recurrence']:7.2f}")
    print(f"  ours, acceleration hold / recurrence:        {fast['ours_acceleration'] / fast['recurrence']:7.2f}")
    print(f"  lsim / ours (target >= 100):                 {slow['lsim'] / fast['ours']:7.1f}")
    print(f"  max |ours - lsim| / max |lsim| (<= 1e-9):    {np.max(np.abs(ours_pos - lsim_pos)) / scale:.1e}")
    print(f"  max |recurrence - lsim| / max |lsim|:        {np.max(np.abs(recurrence_pos - lsim_pos)) / scale:.1e}")


if __name__ == "__main__":
    main()
