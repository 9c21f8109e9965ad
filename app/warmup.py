"""The solver workers' warm-up: the families' own problems, then the documented example requests.

``optim.registry.warm_up_all`` builds the shapes each family knows to be common (no limits). The requests
people send first are the documented ones (the routes' OpenAPI examples, which the README's curl lines
repeat), and those have active limits, torque limits and duration searches whose problems the families'
warm-ups do not build: the first such request after readiness paid about 2 s more (issue 15). So each new
worker also runs every example design once, and only then says it is ready. What it builds stays in its
bounded caches (``runtime.cache``, ``VIBFREE_SOLVER_CACHE_SIZE``).
"""

from __future__ import annotations

import contextlib
import logging
import time
from typing import Any

from optim.solver import SolveCaps

log = logging.getLogger(__name__)

#: The OpenAPI examples designed at warm-up, by family (None: every example that runs a solver). Measured
#: in one process, first design / second design (s): pseudo-polynomial shortest_with_limits 0.59 / 0.34
#: (a problem with active limits is built), STAP table_2_torque_limit 0.049 / 0.041 (a torque problem),
#: time-optimal two_inertia_torque 0.91 / 0.83 alone. Time-optimal designs keep nothing between requests but
#: the compiled kernels numba loads at their first use: known_answer loads the LP code and the held
#: acceleration's (1.7 s), jerk_limited the held jerk's (84 ms; after it, a held-jerk move's first design took
#: 3.8 ms instead of 6.8). The others (robust band, trade-off, torque) load nothing more and cost 0.1-0.5 s.
WARM_EXAMPLES: dict[str, tuple[str, ...] | None] = {
    "time_optimal": ("known_answer", "jerk_limited"),
    "pseudo_polynomial": None,
    "stap": None,
}
EXAMPLE_FAMILIES = tuple(WARM_EXAMPLES)


def example_jobs(settings: Any) -> tuple[tuple[str, Any, Any], ...]:
    """(family name, problem, options) of every example of ``EXAMPLE_FAMILIES`` that uses a solver, parsed
    like a request (in the HTTP process: what a worker receives is what a request would send it)."""
    from app.families import BY_NAME
    from optim.registry import FAMILIES

    jobs: list[tuple[str, Any, Any]] = []
    for name in EXAMPLE_FAMILIES:
        entry = BY_NAME[name]
        examples = entry.examples
        family = FAMILIES[name]
        chosen = WARM_EXAMPLES[name]
        for key, example in examples.items():
            if chosen is not None and key not in chosen:
                continue
            try:
                body = entry.request.model_validate(example["value"])
                problem = body.to_problem(settings)
                options = body.options(problem)
            except Exception:  # an example the schema refuses is the docs' test's business, not a start-up failure
                log.warning("example not warmed up", extra={"family": name}, exc_info=True)
                continue
            if family.uses_solver(options):
                jobs.append((name, problem, options))
    return tuple(jobs)


def warm_up_worker(caps: SolveCaps, cache_size: int, jobs: tuple[tuple[str, Any, Any], ...]) -> None:
    """Run in each new solver worker: size its caches, build the families' problems, design each example."""
    from models.errors import DomainError
    from optim.registry import FAMILIES, warm_up_all
    from optim.synthesis import synthesize
    from runtime import cache

    cache.set_size(cache_size)
    warm_up_all(caps)
    started = time.perf_counter()
    for name, problem, options in jobs:
        with contextlib.suppress(DomainError):  # an example whose answer is a 422 still built its problems
            synthesize(FAMILIES[name], problem, options)
    log.info("examples designed", extra={"examples": len(jobs), "seconds": round(time.perf_counter() - started, 3)})
