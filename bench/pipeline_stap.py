"""Benchmark: a 1k-sample STAP closed form in-process, stage by stage (medians), against its whole.

The request is the API's example ``section_3_k1`` (Cusimano Sec. 3: 150 rad/s on a 40 Hz mode, k_j = 1,
a sensitivity curve of 201 ratios) with ``sample_period_s`` 3e-4 s: 1003 samples. The whole is what a
request costs without HTTP: ``StapIn.model_validate``, ``body.to_problem``, ``optim.synthesis.synthesize``,
``app.presenters.answer_body``. The stages are the same calls the pipeline makes, timed one by one on the same inputs
(their sum differs from the whole by the cost of the pipeline's glue and by noise). The target: the whole
<= 1.5 ms, so that HTTP may add 1.5 ms to the 3 ms of the acceptance.
"""

from __future__ import annotations

import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from app.examples.stap import EXAMPLES
from app.presenters import answer_body
from app.schemas.stap import FAMILY, StapIn
from app.settings import Settings
from models.simulation import simulate
from optim.synthesis import grid_of, metrics_of, nominal_percentage_vibration, synthesize

REPEATS = 200
PERIOD_S = 3e-4


def median_ms(fn: Callable[[], object], repeats: int = REPEATS) -> float:
    fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return 1e3 * statistics.median(times)


def main() -> None:
    settings = Settings()
    value: dict[str, Any] = {**EXAMPLES["section_3_k1"]["value"], "sample_period_s": PERIOD_S}

    def whole() -> dict[str, Any]:
        body = StapIn.model_validate(value)
        problem = body.to_problem(settings)
        return answer_body(synthesize(FAMILY, problem, body.options(problem)))

    body = StapIn.model_validate(value)
    problem = body.to_problem(settings)
    options = body.options(problem)
    design = FAMILY.design(problem, options)
    grid = grid_of(problem, design)
    sampled = FAMILY.sample(problem, design, grid.period_s, grid.horizon_s)
    response = simulate(problem.plant, sampled)
    result = synthesize(FAMILY, problem, options)
    stages = {
        "StapIn.model_validate (app)": lambda: StapIn.model_validate(value),
        "body.to_problem (app)": lambda: body.to_problem(settings),
        "family.design (closed form)": lambda: FAMILY.design(problem, options),
        "family.sample (resampled)": lambda: FAMILY.sample(problem, design, grid.period_s, grid.horizon_s),
        "simulate": lambda: simulate(problem.plant, sampled),
        "metrics": lambda: metrics_of(problem, response),
        "sensitivity curve": lambda: FAMILY.sensitivity(problem, design, *_axes(problem)),
        "nominal percentage vibration": lambda: nominal_percentage_vibration(problem, sampled),
        "synthesize (all of optim)": lambda: synthesize(FAMILY, problem, options),
        "answer_body(result) (app)": lambda: answer_body(result),
    }
    print(f"STAP closed form, {sampled.time_s.size} samples, in-process, medians of {REPEATS}:")
    total = median_ms(whole)
    for name, fn in stages.items():
        print(f"  {name:34s} {median_ms(fn):7.3f} ms")
    print(f"  {'whole request (target <= 1.5 ms)':34s} {total:7.3f} ms")


def _axes(problem: Any) -> tuple[Any, Any]:
    from optim.synthesis import _sensitivity_axes

    zetas, ratios = _sensitivity_axes(problem, problem.sensitivity)
    return ratios, zetas


if __name__ == "__main__":
    main()
