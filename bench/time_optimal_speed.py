"""Benchmark: the time-optimal family's in-process speed, this checkout against a reference commit in one run.

``python bench/time_optimal_speed.py REF [rounds]`` checks REF out in a temporary git worktree and alternates
between the two trees, ``rounds`` times (default 3): each round runs one subprocess per tree that designs every
case through ``vibfree.synthesize`` (after the service worker's warm-up, app/warmup.py, and a first call of the
case; then each move once; one BLAS thread, as the service's workers) and prints its seconds per design.
The table gives the p50 over the rounds and moves of each case, the ratio REF / this, the share of designs under
FAST_S (a certified design takes milliseconds, a searched one hundreds: the p50 of a mix says little), and how many
answers differ in duration by more than 1e-9 (they should not be longer: the script reports any that are).

Cases (the issue's speed targets): 20 seeded single-mode moves of bench/time_optimal_random.py without a jerk limit,
20 with one; the README's move (nominal), its robust +-10 % design, bench/time_optimal.py's two- and three-mode
transfer functions (one hard move each), and 20 seeded moves of the random bench's distribution on two and on three
modes (a transfer function, every mode cancelled).
"""

from __future__ import annotations

import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from app.examples.time_optimal import EXAMPLES  # noqa: E402
from bench.time_optimal import product_of_modes  # noqa: E402
from bench.time_optimal_random import random_move  # noqa: E402
from vibfree.cli import SINGLE_THREADED_BLAS  # noqa: E402

FAST_S = 0.05  # the table also gives the share of designs faster than this (a p50 between two clusters says little)
README = EXAMPLES["known_answer"]["value"]  # the README's move, as the OpenAPI example states it
LIMITS = {"max_velocity": 1.0, "max_acceleration": 5.0}
TWO = {"plant": product_of_modes([(5.0, 0.02), (13.0, 0.05)]), "displacement": 0.3, "limits": LIMITS, "modes": [0, 1]}
THREE = {
    "plant": product_of_modes([(5.0, 0.02), (13.0, 0.05), (31.0, 0.03)]),
    "displacement": 0.3,
    "limits": LIMITS,
    "modes": [0, 1, 2],
}


def _modes_moves(rng: Any, count: int, modes: int) -> list[dict[str, Any]]:
    """``count`` moves of bench/time_optimal_random.py's distribution (displacement, limits, the slowest mode)
    on ``modes`` modes, each next one 1.5-4 times faster than the one before, all cancelled."""
    out: list[dict[str, Any]] = []
    while len(out) < count:
        request, found, torque = random_move(rng)
        if torque:
            continue
        hz, zeta = found[0][0] / (2 * math.pi), found[0][1]
        chain = [(hz, zeta)]
        for _ in range(modes - 1):
            chain.append((chain[-1][0] * float(rng.uniform(1.5, 4.0)), float(rng.uniform(0.0, 0.2))))
        plant = product_of_modes(chain)
        out.append({**request, "plant": plant, "modes": list(range(modes))})
    return out


def cases() -> dict[str, list[dict[str, Any]]]:
    import numpy as np

    rng = np.random.default_rng(25)
    plain: list[dict[str, Any]] = []
    jerk: list[dict[str, Any]] = []
    while len(plain) < 20 or len(jerk) < 20:
        request, modes, torque = random_move(rng)
        if torque or len(modes) > 1:
            continue
        target = jerk if "max_jerk" in request["limits"] else plain
        if len(target) < 20:
            target.append(request)
    several = np.random.default_rng(26)  # (a stream of its own: the cases above stay the same moves)
    return {
        "one mode, held acceleration (20 random moves)": plain,
        "one mode, held jerk (20 random moves)": jerk,
        "the README's move": [README],
        "the README's move, robust +-10 %": [{**README, "robustness": {"frequency_ratio_range": [0.9, 1.1]}}],
        "two-mode transfer function (bench/time_optimal.py)": [TWO],
        "three-mode transfer function": [THREE],
        "two modes (20 random moves)": _modes_moves(several, 20, 2),
        "three modes (20 random moves)": _modes_moves(several, 20, 3),
    }


MEASURE = """
import json, sys, time
sys.path.insert(0, '.')
from vibfree import synthesize
cases = json.loads(sys.stdin.read())
try:  # warmed as a service worker warms the family (app/warmup.py: its examples load the compiled kernels)
    from app.settings import Settings
    from app.warmup import example_jobs
    from optim.registry import FAMILIES
    from optim.synthesis import synthesize as design
    for family, problem, options in example_jobs(Settings(workers=1)):
        if family == 'time_optimal':
            design(FAMILIES[family], problem, options)
except ImportError:  # (a reference tree from before the warm-up)
    pass
out = {}
for name, requests in cases.items():
    synthesize('time-optimal', requests[0])
    rows = []
    for request in requests:
        start = time.perf_counter()
        answer = synthesize('time-optimal', request).answer['design']
        rows.append((time.perf_counter() - start, answer['duration_s']))
    out[name] = rows
print(json.dumps(out))
"""


def run(tree: Path, payload: str) -> dict[str, list[list[float]]]:
    """One tree's seconds per design, in a subprocess with one BLAS thread (as the service's workers run:
    docs/deployment.md; with OpenBLAS's threads SLSQP's small solves took 2-30 times longer whenever another
    process ran beside them) unless the environment sets the thread counts."""
    python = ROOT / ".venv" / "bin" / "python"
    env = {**dict.fromkeys(SINGLE_THREADED_BLAS, "1"), **os.environ}
    done = subprocess.run(
        [str(python), "-c", MEASURE], cwd=tree, input=payload, capture_output=True, text=True, check=True, env=env
    )
    result: dict[str, list[list[float]]] = json.loads(done.stdout.strip().splitlines()[-1])
    return result


def main(reference: str, rounds: int = 3) -> int:
    chosen = cases()
    payload = json.dumps(chosen)
    with tempfile.TemporaryDirectory() as tmp:
        ref_tree = Path(tmp) / "ref"
        subprocess.run(["git", "worktree", "add", "-q", "--detach", str(ref_tree), reference], cwd=ROOT, check=True)
        try:
            seconds: dict[str, dict[str, list[float]]] = {"ref": {}, "this": {}}
            durations: dict[str, dict[str, list[float]]] = {"ref": {}, "this": {}}
            for _ in range(rounds):
                for label, tree in (("ref", ref_tree), ("this", ROOT)):
                    for name, rows in run(tree, payload).items():
                        seconds[label].setdefault(name, []).extend(r[0] for r in rows)
                        durations[label][name] = [r[1] for r in rows]
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(ref_tree)], cwd=ROOT, check=False)
    fast_head = f"under {FAST_S * 1e3:.0f} ms, {reference} / this"
    print(f"| case | {reference} p50 | this p50 | ratio | {fast_head} | answers shorter / longer (> 1e-9) |")
    print("|---|---|---|---|---|---|")
    longer = 0
    for name in chosen:
        ref_s, this_s = statistics.median(seconds["ref"][name]), statistics.median(seconds["this"][name])
        pairs = list(zip(durations["ref"][name], durations["this"][name], strict=True))
        shorter = sum(t < r * (1 - 1e-9) for r, t in pairs)
        more = sum(t > r * (1 + 1e-9) for r, t in pairs)
        longer += more
        fast = " / ".join(
            f"{sum(t < FAST_S for t in seconds[k][name]) / len(seconds[k][name]):.0%}" for k in ("ref", "this")
        )
        ratio = f"{ref_s / this_s:.1f}x"
        print(f"| {name} | {ref_s * 1e3:.1f} ms | {this_s * 1e3:.1f} ms | {ratio} | {fast} | {shorter} / {more} |")
    return 1 if longer else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], *(int(a) for a in sys.argv[2:3])))
