"""The shortest duration of a pseudo-polynomial design within the limits (``minimize_duration``).

Zero-energy designs do not exist at every duration: for order 2 they appear near whole numbers of
periods of the mode (from about three), so feasibility is not monotone in T and the search scans
durations before bisecting. Incerti designs at a fixed T (Sec. V); this search is the service's own.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from models.errors import Infeasible
from optim.pseudo_polynomial.problem import _oscillatory
from optim.pseudo_polynomial.solve import _Attempt, _solve_at, check_limits_possible
from optim.pseudo_polynomial.types import FloatArray, PseudoPolynomialRequest


def _default_tolerance(request: PseudoPolynomialRequest) -> float:
    """1e-6 of the load's displacement (of the motor's for plants with no position gain)."""
    return 1e-6 * abs(request.displacement) * (abs(request.plant.dc_gain) or 1.0)


def _shortest(request: PseudoPolynomialRequest) -> tuple[float, _Attempt, tuple[tuple[float, bool], ...]]:
    """The shortest duration whose design meets the residual tolerance within the limits.

    Zero-energy designs exist only in windows of duration (for order 2 roughly around whole
    numbers of periods of the mode), so feasibility is not monotone in T: the search steps down
    from the first duration that works, by an eighth of the mode's period (or T/24), to the
    kinematic lower bound, then bisects between the shortest feasible step and the step below it.
    """
    tolerance = request.residual_tolerance or _default_tolerance(request)
    started = time.perf_counter()
    budget = 3.0 * request.caps.max_wall_time_s
    tried: list[tuple[float, bool]] = []

    def attempt(duration: float, start: FloatArray) -> _Attempt | None:
        trial = replace(request, duration_s=duration)
        try:
            check_limits_possible(trial)
            result = _solve_at(trial, start, effort="probe")
        except Infeasible:
            tried.append((duration, False))
            return None
        ok = result.residual <= tolerance and not result.report.timed_out
        tried.append((duration, ok))
        return result if ok else None

    def out_of_time() -> bool:
        return time.perf_counter() - started > budget

    high = request.duration_s
    first = _solve_at(request, np.asarray(request.initial_exponents), effort="thorough")
    ok = first.residual <= tolerance and not first.report.timed_out
    tried.append((high, ok))
    best = first if ok else None
    while best is None:
        if len(tried) > 8 or out_of_time():
            raise Infeasible(
                f"no pseudo-polynomial command of order {request.order} meets the limits with a residual below "
                f"{tolerance:.3g} for durations up to {high:.6g} s",
                field="duration_s",
            )
        high *= 1.25
        best = attempt(high, np.asarray(request.initial_exponents))
    lim, phi = request.limits, abs(request.displacement)
    floor = max(
        [0.0]
        + ([phi / lim.max_velocity] if lim.max_velocity else [])
        + ([2.0 * math.sqrt(phi / lim.max_acceleration)] if lim.max_acceleration else [])
        + ([(32.0 * phi / lim.max_jerk) ** (1 / 3)] if lim.max_jerk else [])
    )
    period = float(np.min(2 * np.pi / np.abs(_oscillatory(request.plant).poles)))
    step = min(period / 8.0, high / 24.0)
    low = floor
    trial = high - step
    while trial > floor and not out_of_time():  # a loop over durations, not samples
        found = attempt(trial, best.gamma)
        if found is not None:
            high, best = trial, found
        elif trial < high - 2.5 * period:
            low = trial
            break  # two and a half periods without a feasible duration: the windows have closed
        trial -= step
    low = max(low, high - step)
    while high - low > 1e-3 * high and not out_of_time():
        mid = 0.5 * (low + high)
        found = attempt(mid, best.gamma)
        if found is not None:
            high, best = mid, found
        else:
            low = mid
    return high, best, tuple(tried)
