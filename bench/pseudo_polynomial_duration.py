"""Benchmark: the pseudo-polynomial family's default design of the compare example (issue 11).

The incerti_rest_to_rest example of /v1/compare (app/routers/compare.py): Table III platform, 15 motor
revolutions, v <= 200 rad/s, a <= 700 rad/s^2, the family's default options (minimize_duration). Printed:
the median of its design (target: 300 ms on the 2-core development machine), and as a ratio to the median
of one fixed-duration design in the same run (Table III, 1 s, no limits: one closest zero-energy solve),
so that the figure survives a loaded or a faster machine; the duration found, the bracket and the solves.
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from app.examples.compare import EXAMPLES  # noqa: E402
from models.plants import example_plants  # noqa: E402
from optim.families import pseudo_polynomial as pp  # noqa: E402
from optim.families.pseudo_polynomial.report import PseudoPolynomialReport  # noqa: E402
from optim.problem import Limits, Problem  # noqa: E402
from optim.registry import FAMILIES  # noqa: E402

FAMILY = FAMILIES["pseudo_polynomial"]
RUNS = 21


def median_s(run: object, runs: int = RUNS) -> float:
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        run()  # type: ignore[operator]
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    example = EXAMPLES["incerti_rest_to_rest"]["value"]
    plant = example_plants()["incerti_table_iii"]
    problem = Problem(plant, displacement=example["displacement"], limits=Limits(**example["limits"]))
    options = FAMILY.default_options(problem)
    fixed = pp.PseudoPolynomialRequest(plant, example["displacement"], 1.0)
    pp.warm_up()
    design = FAMILY.design(problem, options)  # builds the limited problem once (not timed)
    reference = median_s(lambda: pp.design(fixed))
    default = median_s(lambda: FAMILY.design(problem, options))
    summary = design.summary
    assert isinstance(summary, PseudoPolynomialReport) and summary.duration_bracket is not None
    assert summary.duration_search is not None
    below = summary.duration_bracket.longest_infeasible_below_s
    print(f"one fixed-duration design (Table III, 1 s, no limits), median of {RUNS}: {1e3 * reference:.1f} ms")
    print(
        f"default design of the compare example (minimize_duration), median of {RUNS}: {1e3 * default:.0f} ms "
        f"= {default / reference:.1f} x the fixed-duration design"
    )
    print(
        f"  duration {summary.duration_s:.6f} s (longest infeasible below: {below:.6f} s), "
        f"{summary.solver.solves} solves, {summary.solver.iterations} iterations, "
        f"{len(summary.duration_search)} durations tried"
    )


if __name__ == "__main__":
    main()
