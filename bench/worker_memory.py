"""A solver worker's memory after many distinct plants (issue 15: 213 MiB at start, 769 MiB after a scaling run).

For each family (pseudo-polynomial, time-optimal, robust time-optimal) a fresh worker-like process (spawned, warmed
up like a pool worker) designs ``--plants`` distinct plants (one mode, natural frequency spread over
``--low-hz``..``--high-hz``), and its resident set size is read from /proc after the warm-up and every 50 designs.
The documented bound is 450 MiB (docs/deployment.md; 400 before the time-optimal kernels). ``--root`` runs the same
designs on another checkout (e.g. the old main, for a side-by-side run):

    python bench/worker_memory.py                       # this checkout
    python bench/worker_memory.py --root /tmp/old-main  # another one, same designs
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import sys
import time
from typing import Any

BOUND_MIB = 450.0
BODIES = {
    "pseudo_polynomial": lambda f: {
        "plant": {"kind": "mode", "natural_frequency_hz": f, "damping_ratio": 0.02},
        "displacement": 0.1,
        "duration_s": 5.0,  # 15-300 periods: the quadrature tables grow with the periods of the move
    },
    "time_optimal": lambda f: {
        "plant": {"kind": "mode", "natural_frequency_hz": f, "damping_ratio": 0.02},
        "displacement": 0.12,
        "limits": {"max_velocity": 5.0, "max_acceleration": 10.0},
    },
    "robust_time_optimal": lambda f: {
        "plant": {"kind": "mode", "natural_frequency_hz": f, "damping_ratio": 0.02},
        "displacement": 0.12,
        "limits": {"max_velocity": 5.0, "max_acceleration": 10.0},
        "robustness": {"frequency_ratio_range": [0.95, 1.05]},
    },
}


def rss_mib() -> float:
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    raise RuntimeError("no VmRSS")


def _worker(root: str, family_key: str, frequencies: list[float], conn: Any) -> None:
    """A worker: the pool's warm-up, then one design per plant; RSS after the warm-up and every 50 designs."""
    sys.path.insert(0, root)
    from app.schemas.registry import REQUEST_SCHEMAS
    from app.settings import Settings
    from models.errors import DomainError
    from optim.registry import FAMILIES, warm_up_all
    from optim.synthesis import synthesize

    settings = Settings(workers=1)
    try:
        from app.warmup import example_jobs, warm_up_worker  # this branch's warm-up (examples, cache size)

        warm_up_worker(settings.solve_caps, settings.solver_cache_size, example_jobs(settings))
    except ImportError:  # an older checkout: its families' warm-ups
        warm_up_all(settings.solve_caps)
    family = "time_optimal" if family_key.endswith("time_optimal") else family_key
    conn.send(("start", 0, rss_mib(), 0.0))
    failures = 0
    started = time.perf_counter()
    for n, f in enumerate(frequencies, 1):
        body = REQUEST_SCHEMAS[family].model_validate(BODIES[family_key](f))
        problem = body.to_problem(settings)
        try:
            synthesize(FAMILIES[family], problem, body.options(problem))
        except DomainError:
            failures += 1
        if n % 50 == 0 or n == len(frequencies):
            conn.send(("after", n, rss_mib(), time.perf_counter() - started))
    conn.send(("done", failures, rss_mib(), time.perf_counter() - started))


def run(root: str, family_key: str, plants: int, low_hz: float, high_hz: float) -> list[tuple[str, int, float, float]]:
    import numpy as np

    frequencies = [float(f) for f in np.linspace(low_hz, high_hz, plants)]
    context = multiprocessing.get_context("spawn")
    parent, child = context.Pipe()
    process = context.Process(target=_worker, args=(root, family_key, frequencies, child), daemon=True)
    process.start()
    rows = []
    try:
        while True:
            row = parent.recv()
            rows.append(row)
            if row[0] == "done":
                return rows
    finally:
        process.join(5)
        if process.is_alive():
            process.kill()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--root", default=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    parser.add_argument("--plants", type=int, default=200)
    parser.add_argument("--low-hz", type=float, default=3.0)
    parser.add_argument("--high-hz", type=float, default=60.0)
    parser.add_argument("--families", default=",".join(BODIES))
    args = parser.parse_args()
    print(
        f"root {args.root}; {args.plants} plants, one mode at {args.low_hz:g}-{args.high_hz:g} Hz; "
        f"load {os.getloadavg()}"
    )
    for family_key in args.families.split(","):
        rows = run(args.root, family_key, args.plants, args.low_hz, args.high_hz)
        start = rows[0][2]
        end = rows[-1][2]
        trail = ", ".join(f"{n}: {rss:.0f}" for kind, n, rss, _ in rows if kind == "after")
        verdict = "within" if end <= BOUND_MIB else "ABOVE"
        print(
            f"{family_key:22s} start {start:6.0f} MiB  end {end:6.0f} MiB  ({trail})  "
            f"{rows[-1][3]:.1f} s, {rows[-1][1]} refused; {verdict} the {BOUND_MIB:.0f} MiB bound"
        )


if __name__ == "__main__":
    main()
