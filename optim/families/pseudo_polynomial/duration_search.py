"""The shortest duration of a pseudo-polynomial design within the limits (``minimize_duration``).

Zero-energy designs do not exist at every duration: for order 2 they appear near whole numbers of
periods of the mode (from about three), so feasibility is not monotone in T. The search scans whole
periods of the slowest mode upwards from the kinematic floor (no move within the limits is shorter),
(if none is feasible up to EXTRA_PERIODS beyond duration_s, a multi-start solve at duration_s is the
last resort), then refines below the first feasible one: steps of a quarter of a period down to the candidate below
it, and bisection between the shortest feasible step and the infeasible one below it. A probe first
solves the closest zero-energy design without the limits (a problem of two equality constraints, a few
milliseconds) and keeps it when its checked peaks meet the limits; only otherwise does it solve with the
limits imposed. Incerti designs at a fixed T (Sec. V); this search is the service's own.

The search is capped in work: MAX_SEARCH_SOLVES IPOPT solves (checked before each duration probe), each capped in
iterations; reached, it stops with SolverFailed (the family then designs at duration_s, and says so). So its answer
is the same on any machine under any load; IPOPT's wall-time cap is a last resort (SolverTimedOut).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from models.errors import Infeasible, SolverFailed
from models.pseudo_polynomial import PseudoPolynomial
from optim.families.pseudo_polynomial.parameters import oscillatory_modal_form
from optim.families.pseudo_polynomial.problem import active_limits
from optim.families.pseudo_polynomial.solve import (
    PeaksOf,
    _Attempt,
    _solve_at,
    check_limits_possible,
    overshoot,
    solve_within,
    total,
)
from optim.families.pseudo_polynomial.types import FloatArray, Limits, PseudoPolynomialRequest
from optim.solver import SolverReport

__all__ = ["EXTRA_PERIODS", "MAX_SEARCH_SOLVES", "REFINE_STEPS", "SEARCH_METHOD", "Search", "kinematic_floor_s"]

EXTRA_PERIODS = 8  # whole periods scanned beyond duration_s before giving up
MAX_CANDIDATES = 64  # whole-period candidates scanned at most
REFINE_STEPS = 4  # steps per period below the first feasible candidate
BRACKET_RTOL = 1e-3  # the bisection stops when the bracket is this fraction of the duration
# IPOPT solves a search may start (checked before each probe, which may take a few): the tests' searches take at
# most 55 (one that finds nothing), the compare example 15.
MAX_SEARCH_SOLVES = 300

SEARCH_METHOD = (
    "whole periods of the slowest mode scanned upwards from the kinematic floor; below the first feasible one, "
    "steps of 1/4 period down to the candidate below it, then bisection to 0.1 % between the shortest feasible "
    "step and the infeasible one below it. A duration counts as feasible when its closest zero-energy design "
    "(without the limits, or else with them) leaves less than the residual tolerance and its sampled command "
    "meets the limits; other windows of feasible durations below the bracket were not seen by the scan."
)


@dataclass(frozen=True)
class Search:
    """What ``shortest`` found: the duration, its design, every duration tried, the bracket."""

    duration_s: float
    attempt: _Attempt
    tried: tuple[tuple[float, bool], ...]
    longest_infeasible_below_s: float | None


def _default_tolerance(request: PseudoPolynomialRequest) -> float:
    """1e-6 of the load's displacement (of the motor's for plants with no position gain)."""
    return 1e-6 * abs(request.displacement) * (abs(request.plant.dc_gain) or 1.0)


def kinematic_floor_s(request: PseudoPolynomialRequest) -> float:
    """The least duration of any rest-to-rest move within the kinematic limits (bang-bang bounds of
    ``check_limits_possible``: Phi / v_max, 2 sqrt(Phi / a_max), (32 Phi / j_max)^(1/3))."""
    lim, phi = request.limits, abs(request.displacement)
    floors = [phi / lim.max_velocity] if lim.max_velocity else []
    floors += [2.0 * math.sqrt(phi / lim.max_acceleration)] if lim.max_acceleration else []
    floors += [(32.0 * phi / lim.max_jerk) ** (1 / 3)] if lim.max_jerk else []
    return max(floors, default=0.0)


def _candidates(request: PseudoPolynomialRequest, period_s: float) -> list[float]:
    """Whole periods from the kinematic floor up to duration_s (and it), then EXTRA_PERIODS beyond."""
    first = max(1, math.ceil(kinematic_floor_s(request) / period_s - 1e-9))
    last = max(first, math.ceil(request.duration_s / period_s - 1e-9)) + EXTRA_PERIODS
    whole = [k * period_s for k in range(first, min(last, first + MAX_CANDIDATES - 1) + 1)]
    return sorted({*whole, request.duration_s})


def shortest(request: PseudoPolynomialRequest, peaks_of: PeaksOf | None) -> Search:
    """The shortest duration whose design meets the residual tolerance within the limits (module
    docstring). A time-out propagates as SolverTimedOut; no feasible duration found, or MAX_SEARCH_SOLVES
    reached, is SolverFailed (the scan is no proof that none exists)."""
    tolerance = request.residual_tolerance or _default_tolerance(request)
    tried: list[tuple[float, bool]] = []
    ledger: list[SolverReport] = []  # every solve of the search
    free_limits = Limits()

    def meets(trial: PseudoPolynomialRequest, result: _Attempt) -> bool:
        if result.residual > tolerance:
            return False
        if peaks_of is None or not any(active_limits(trial.limits)):
            return True
        return not overshoot(
            trial.limits, peaks_of(PseudoPolynomial(trial.displacement, trial.duration_s, tuple(result.gamma)))
        )

    def probe(duration: float, start: FloatArray, effort: str = "probe") -> _Attempt | None:
        if len(ledger) >= MAX_SEARCH_SOLVES:
            raise SolverFailed(
                total(ledger, "Search_Solve_Cap"),
                f"the duration search reached its cap of {MAX_SEARCH_SOLVES} solves (max_search_solves) at duration "
                f"{duration:.6g} s",
            )
        trial = replace(request, duration_s=duration)
        found: _Attempt | None = None
        outside: FloatArray | None = None  # a zero-energy design that breaks the limits
        try:
            check_limits_possible(trial)
            free = _solve_at(replace(trial, limits=free_limits), start, "probe", ledger)
            if free.stage == "capped" and free.residual <= tolerance:  # near a window's edge: converge it
                free = _solve_at(replace(trial, limits=free_limits), free.gamma, "polish", ledger)
            if meets(trial, free):
                found = free
            elif free.residual <= tolerance:
                outside = free.gamma
        except Infeasible:
            pass
        # The limited problem only where a zero-energy design exists but breaks the limits (where the
        # problem without the limits, its relaxation, finds none, the limited one is not tried).
        if outside is not None or (found is None and effort == "thorough"):
            try:
                limited = solve_within(trial, start if outside is None else outside, effort, peaks_of, ledger)
                converged = limited.stage in ("closest_zero_energy", "minimum_energy")  # a converged solve
                found = limited if converged and limited.residual <= tolerance else None
            except Infeasible:
                pass
        tried.append((duration, found is not None))
        return found

    period = float(np.max(2 * np.pi / np.abs(oscillatory_modal_form(request.plant).poles)))
    initial = np.asarray(request.initial_exponents)
    best: _Attempt | None = None
    below: float | None = None  # the infeasible candidate just below the first feasible one
    high = request.duration_s
    for duration in _candidates(request, period):
        best = probe(duration, initial)
        if best is not None:
            high = duration
            break
        below = duration
    if best is None:  # the multi-start at duration_s, where no closest solve succeeds (order >= 3 from its start)
        best = probe(request.duration_s, initial, "thorough")
        below = max((d for d, _ in tried if d < high), default=None)
    if best is None:  # not a proof that none exists: a solver failure, never "infeasible"
        raise SolverFailed(
            total(ledger, "Search_Found_No_Design"),
            f"the duration search found no pseudo-polynomial command of order {request.order} within the limits "
            f"with a residual below {tolerance:.3g} at whole periods from {kinematic_floor_s(request):.6g} s up to "
            f"{max(d for d, _ in tried):.6g} s (nor the multi-start at {request.duration_s:.6g} s); give a "
            "duration_s to design at, or another order",
        )
    floor = max(kinematic_floor_s(request), below or 0.0, high - period)
    step = period / REFINE_STEPS
    trial = high - step
    while trial > floor * (1 + 1e-12):  # a loop over durations, not samples
        found = probe(trial, best.gamma)
        if found is not None:
            high, best = trial, found
        trial -= step
    failed_below = [d for d, ok in tried if not ok and d < high]
    low = max(failed_below) if failed_below else None
    if low is not None:
        while high - low > BRACKET_RTOL * high:
            mid = 0.5 * (low + high)
            found = probe(mid, best.gamma)
            if found is not None:
                high, best = mid, found
            else:
                low = mid
    summary = replace(best, report=total(ledger, best.report.status), solves=len(ledger))
    return Search(high, summary, tuple(tried), low)
