"""Exponents of a pseudo-polynomial command chosen by CasADi/IPOPT (Incerti, Secs. IV-V).

The exponents gamma_i of phi(t) = Phi [1 - sum_i C_i (1 - t/T)^gamma_i] (eq. 17, C_i by eq. 22) are
chosen so that the final energy of the load's vibration (eq. 26, through the modal form of eqs. 27-30)
vanishes, within the limits. The package holds:

- ``types``: the request and the design;
- ``problem``: the CasADi problem, built once per shape with named parameters, cached, warmed up;
- ``product_integration``: the weights of the modal integrals' product integration;
- ``parameters``: a request's parameter vector for its problem, and ``evaluate``;
- ``solve``: one design at a fixed duration from a start, and the rule that selects it;
- ``duration_search``: the shortest duration (``minimize_duration``);
- here: the checks of a request and ``design``, the entry point run in a worker process.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import replace

import numpy as np

from models.errors import InvalidParameter, SolverFailed, SolverTimedOut
from models.plants import TwoInertiaPlant
from models.pseudo_polynomial import PseudoPolynomial, check_exponents
from optim.families.pseudo_polynomial.duration_search import SEARCH_METHOD, Search, shortest
from optim.families.pseudo_polynomial.parameters import evaluate, oscillatory_modal_form, parameter_vector, prepare
from optim.families.pseudo_polynomial.problem import (
    CONSTRAINT_INTERVALS,
    LIMIT_MARGIN,
    MAX_EXPONENT,
    MAX_MODES,
    MIN_SEPARATION,
    PROBE_ITERATIONS,
    QUICK_ITERATIONS,
    SEARCH_ITERATIONS,
    SOLVER_CACHE,
    SYMBOLIC_KINDS,
    _build,
    active_limits,
    limit_grid_u,
    lower_bound,
    warm_up,
)
from optim.families.pseudo_polynomial.product_integration import INTERPOLATION_NODES, MAX_PHASE_RAD, product_weights
from optim.families.pseudo_polynomial.solve import (
    SPREAD_STARTS,
    ZERO_ENERGY,
    Peaks,
    PeaksOf,
    _raise_unless_design,
    check_limits_possible,
    law_peaks,
    overshoot,
    solve_within,
    spread_starts,
    total,
)
from optim.families.pseudo_polynomial.types import Limits, PseudoPolynomialDesign, PseudoPolynomialRequest
from optim.solver import SolverReport, tally

__all__ = [
    "CONSTRAINT_INTERVALS",
    "INTERPOLATION_NODES",
    "LIMIT_MARGIN",
    "MAX_EXPONENT",
    "MAX_MODES",
    "MAX_ORDER",
    "MAX_PHASE_RAD",
    "MIN_SEPARATION",
    "PROBE_ITERATIONS",
    "QUICK_ITERATIONS",
    "SEARCH_ITERATIONS",
    "SEARCH_METHOD",
    "SOLVER_CACHE",
    "SPREAD_STARTS",
    "SYMBOLIC_KINDS",
    "ZERO_ENERGY",
    "Limits",
    "Peaks",
    "PeaksOf",
    "PseudoPolynomialDesign",
    "PseudoPolynomialRequest",
    "_build",
    "check_limits_possible",
    "default_exponents",
    "design",
    "evaluate",
    "law_peaks",
    "limit_grid_u",
    "lower_bound",
    "oscillatory_modal_form",
    "overshoot",
    "parameter_vector",
    "prepare",
    "product_weights",
    "spread_starts",
    "warm_up",
]

MAX_ORDER = 6


def default_exponents(order: int) -> tuple[float, ...]:
    """n+1, ..., 2n+1: the classical polynomial with n null derivatives at both ends ((3, 4, 5)
    for n = 2); from 3 up for n = 1, where the lower bound is 3."""
    first = max(order + 1, 3)
    return tuple(float(first + i) for i in range(order + 1))


def _checked(request: PseudoPolynomialRequest) -> tuple[PseudoPolynomialRequest, tuple[float, ...]]:
    """The request with its initial exponents set and sorted, and those exponents; raises on a bad request."""
    if not 1 <= request.order <= MAX_ORDER:
        raise InvalidParameter("order", request.order, f"must lie in 1..{MAX_ORDER}")
    initial = check_exponents(request.initial_exponents or default_exponents(request.order), request.order)
    ordered = sorted(initial)
    if min(b - a for a, b in itertools.pairwise(ordered)) < MIN_SEPARATION:
        raise InvalidParameter(
            "initial_exponents",
            list(initial),
            f"exponents must be at least {MIN_SEPARATION:g} apart (eq. 22 stays well conditioned)",
        )
    if min(initial) < lower_bound(request.order):
        raise InvalidParameter(
            "initial_exponents",
            list(initial),
            f"every exponent must be >= {lower_bound(request.order):g} for order {request.order} (above the order, "
            "and at least 3 so the jerk stays bounded)",
        )
    if request.limits.max_torque_nm is not None and not isinstance(request.plant, TwoInertiaPlant):
        raise InvalidParameter(
            "limits.max_torque_nm",
            request.limits.max_torque_nm,
            f"a {request.plant.kind} plant does not define the motor torque",
        )
    if request.minimize_duration and not any(active_limits(request.limits)):
        raise InvalidParameter(
            "minimize_duration", True, "needs at least one limit (without limits any duration works)"
        )
    check_limits_possible(request)
    initial_exponents = tuple(sorted(initial))
    return replace(request, initial_exponents=initial_exponents), initial_exponents


def design(request: PseudoPolynomialRequest, peaks_of: PeaksOf | None = None) -> PseudoPolynomialDesign:
    """The design for a request (runs in a worker process). ``peaks_of`` gives the peaks checked against
    the limits (the pipeline passes those of the sampled command; default: the law's own, ``law_peaks``).

    Its report counts every solve: a duration search that found nothing before the design at duration_s
    included (``optim.solver.tally``; the ledger of the design alone said ``solves: 8`` after 30)."""
    with tally() as counts:
        result = _design(request, peaks_of)
    return replace(result, solver=replace(result.solver, iterations=counts.iterations), solves=counts.solves)


def _design(request: PseudoPolynomialRequest, peaks_of: PeaksOf | None) -> PseudoPolynomialDesign:
    request, initial = _checked(request)
    energy0, residual0 = evaluate(request, np.asarray(initial))
    peaks_of = peaks_of or law_peaks(request.plant, request.limits)
    started = time.perf_counter()
    below: float | None = None
    search: Search | None = None
    if request.minimize_duration:
        try:
            search = shortest(request, peaks_of)
        except SolverTimedOut:
            raise
        except SolverFailed as exc:  # none found at the scanned durations: the design at duration_s, said so
            missed = str(exc)
    if search is not None:
        duration, attempt, tried, below = (
            search.duration_s,
            search.attempt,
            search.tried,
            search.longest_infeasible_below_s,
        )
        solver, solves = attempt.report, attempt.solves
    else:
        ledger: list[SolverReport] = []
        duration, tried = request.duration_s, ()
        attempt = solve_within(request, np.asarray(initial), "thorough", peaks_of, ledger)
        _raise_unless_design(attempt)
        if request.minimize_duration:
            note = f"{missed}; this is the design at duration_s = {request.duration_s:.6g} s"
            attempt = replace(attempt, note=f"{attempt.note}; {note}" if attempt.note else note)
        solver, solves = total(ledger, attempt.report.status), len(ledger)
    return PseudoPolynomialDesign(
        law=PseudoPolynomial(request.displacement, duration, tuple(attempt.gamma)),
        initial=PseudoPolynomial(request.displacement, request.duration_s, initial),
        initial_energy=energy0,
        final_energy=attempt.energy,
        residual_amplitude=attempt.residual,
        initial_residual_amplitude=residual0,
        selection=attempt.stage,
        solver=replace(solver, solve_time_s=time.perf_counter() - started),
        solves=solves,
        energy_is_physical=request.plant.energy_inertia is not None
        and oscillatory_modal_form(request.plant).poles.size == 1,
        duration_search=tried,
        longest_infeasible_below_s=below,
        fallback_reason=attempt.note,
    )
