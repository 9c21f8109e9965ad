"""Deliberately slow work for the worker-pool tests (importable by spawned workers)."""

from __future__ import annotations

import os
import time

from optim.solver import SolveCaps, SolverReport, ipopt_options, report_of


def sleep_for(seconds: float) -> int:
    """A 'solve' that ignores every cap: only killing its worker stops it."""
    time.sleep(seconds)
    return os.getpid()


def capped_ipopt(wall_time_s: float) -> SolverReport:
    """A 2000-variable Rosenbrock chain at tol 1e-14: IPOPT needs far longer than the cap."""
    import casadi as ca

    n = 2000
    x = ca.MX.sym("x", n)
    objective = ca.sumsqr(1 - x[:-1]) + 100 * ca.sumsqr(x[1:] - x[:-1] ** 2)
    solver = ca.nlpsol(
        "slow", "ipopt", {"x": x, "f": objective}, ipopt_options(SolveCaps(10**6, wall_time_s), **{"ipopt.tol": 1e-14})
    )
    start = time.perf_counter()
    solver(x0=-1.2)
    return report_of(solver, time.perf_counter() - start)


def slow_warm_up(seconds: float = 1.5) -> None:
    """A warm-up long enough to kill a worker in the middle of it."""
    time.sleep(seconds)


def failing_warm_up() -> None:
    """A warm-up that always fails: the pool must retry it with back-off, never spin."""
    raise RuntimeError("warm-up failed on purpose")


def unpicklable_result() -> object:
    """A result that cannot cross the process boundary (a lambda)."""
    return lambda: None


def priority_warm_up(path: str) -> None:
    """A warm-up that writes the worker's niceness during its warm-up to ``path``."""
    with open(path, "w") as file:
        file.write(str(os.getpriority(os.PRIO_PROCESS, 0)))
