"""Benchmark: a batch of 1,000 nominal time-optimal moves through ``vibfree.synthesize_many`` (issue 25's target:
at most 5 s on the 2-core machine), one process against ``processes=2``, in one run.

``python bench/time_optimal_batch.py [moves] [rounds]``: README-like moves (the 40 Hz mode within 5 m/s and
10 m/s^2, seeded displacements 0.02-0.3 m). The API is imported and warmed by one design first, so that every
figure is the batch itself. Rounds alternate one process and two; the first two-process round includes the pool's
start (a fork server importing the API, then its workers), the later ones reuse the kept pool. Every answer of
the two-process batch is checked byte for byte against the one-process answer of the same move (less its wall
times, ``solve_time_s``).
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from vibfree.cli import one_blas_thread

one_blas_thread()  # as the service's workers (docs/deployment.md), before numpy loads BLAS

import numpy as np  # noqa: E402
import orjson  # noqa: E402

MOVES = 1000
ROUNDS = 3
SEED = 25


def moves(count: int) -> list[dict[str, Any]]:
    displacements = np.random.default_rng(SEED).uniform(0.02, 0.3, count)
    mode = {"kind": "mode", "natural_frequency_hz": 40.0}
    limits = {"max_velocity": 5.0, "max_acceleration": 10.0}
    return [{"plant": mode, "displacement": float(d), "limits": limits} for d in displacements]


def without_times(value: Any) -> Any:
    """An answer without its wall times (every ``solve_time_s``): what must be the same in every process."""
    if isinstance(value, dict):
        return {k: without_times(v) for k, v in value.items() if k != "solve_time_s"}
    if isinstance(value, list | tuple):
        return [without_times(v) for v in value]
    return value


def main() -> None:
    import vibfree

    count = int(sys.argv[1]) if len(sys.argv) > 1 else MOVES
    rounds = int(sys.argv[2]) if len(sys.argv) > 2 else ROUNDS
    batch = moves(count)
    vibfree.synthesize("time-optimal", batch[0])  # the API imported and warm
    seconds: dict[int, list[float]] = {1: [], 2: []}
    answers: dict[int, list[bytes]] = {}
    for _ in range(rounds):
        for processes in (1, 2):
            began = time.perf_counter()
            designs = vibfree.synthesize_many("time-optimal", batch, processes=processes)
            seconds[processes].append(time.perf_counter() - began)
            assert all(isinstance(d, vibfree.Synthesis) for d in designs), "a move was refused"
            answers[processes] = [
                orjson.dumps(without_times(d.answer), option=orjson.OPT_SERIALIZE_NUMPY)
                for d in designs
                if isinstance(d, vibfree.Synthesis)
            ]
    same = sum(a == b for a, b in zip(answers[1], answers[2], strict=True))
    one, two = statistics.median(seconds[1]), statistics.median(seconds[2][1:] or seconds[2])
    print(f"{count} moves, {rounds} rounds; the same bytes with two processes as with one: {same} of {count}")
    print("| what | seconds | per move | ratio to one process |")
    print("|---|---|---|---|")
    print(f"| one process (median) | {one:.2f} | {1e3 * one / count:.2f} ms | 1.00 |")
    print(f"| two processes, first (with the pool's start) | {seconds[2][0]:.2f} | | {seconds[2][0] / one:.2f} |")
    print(f"| two processes, pool kept (median) | {two:.2f} | {1e3 * two / count:.2f} ms | {two / one:.2f} |")


if __name__ == "__main__":
    main()
