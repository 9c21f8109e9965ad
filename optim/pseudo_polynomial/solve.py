"""One pseudo-polynomial design at a fixed duration, from a start (Incerti, Secs. IV-V).

"Final energy = 0" (eq. 26 at T) is two equations per mode in n + 1 exponents: for n >= 2 the
zero-energy designs form a curve (PAPER-NOTES). The design is made well-posed by choosing, among them,
the one closest to the initial exponents that IPOPT reaches from them (stage "closest_zero_energy":
minimise |gamma - gamma_0|^2 subject to h_j(T) = 0 and the limits). If none is reached, the energy
is minimised within the limits from the initial exponents and a few fixed spread starts; a
zero-energy result is moved to the closest zero-energy design near it, otherwise the
lowest-energy design is returned (stage "minimum_energy") with its energy ratio.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from models.errors import Infeasible, SolverFailed
from optim.pseudo_polynomial.problem import MAX_EXPONENT, MIN_SEPARATION, _prepare, lower_bound
from optim.pseudo_polynomial.types import FloatArray, PseudoPolynomialRequest
from optim.solver import SolverReport, raise_for_status, report_of

__all__ = ["SPREAD_STARTS", "ZERO_ENERGY", "check_limits_possible", "spread_starts"]

SPREAD_STARTS = 6  # extra starting points when the closest zero-energy design is not reached
ZERO_ENERGY = 1e-16  # energy ratio below which a design counts as zero-energy (amplitude ratio 1e-8)


def check_limits_possible(request: PseudoPolynomialRequest) -> None:
    """Refuse limits that no motion of this duration can meet, whatever its shape.

    Bang-bang bounds for a rest-to-rest move of Phi in T: the mean speed Phi/T, the least peak
    acceleration 4 Phi/T^2 and the least peak jerk 32 Phi/T^3.
    """
    phi, T, lim = abs(request.displacement), request.duration_s, request.limits
    checks = (
        ("max_velocity", lim.max_velocity, phi / T, "the mean speed displacement/duration"),
        (
            "max_acceleration",
            lim.max_acceleration,
            4 * phi / T**2,
            "4 displacement/duration^2, the least any move needs",
        ),
        ("max_jerk", lim.max_jerk, 32 * phi / T**3, "32 displacement/duration^3, the least any move needs"),
    )
    for name, limit, least, what in checks:
        if limit is not None and limit < least:
            raise Infeasible(
                f"limits.{name} = {limit:.6g} is below {least:.6g}, {what}: no command moves {phi:.6g} in "
                f"{T:.6g} s within it (lengthen duration_s or raise the limit)",
                field=f"limits.{name}",
            )


def spread_starts(order: int, count: int = SPREAD_STARTS) -> list[FloatArray]:
    """Fixed, well-separated starting exponents spread log-uniformly over [lower bound, 40]."""
    rng = np.random.default_rng(1000 + order)
    low = lower_bound(order)
    starts: list[FloatArray] = []
    while len(starts) < count:
        g = np.sort(low * np.exp(rng.uniform(0.0, np.log(40.0 / low), order + 1)))
        if np.min(np.diff(g)) >= 4 * MIN_SEPARATION:
            starts.append(g)
    return starts


@dataclass(frozen=True)
class _Attempt:
    gamma: FloatArray
    stage: str
    report: SolverReport
    energy: float
    residual: float
    solves: int


def _solve_at(request: PseudoPolynomialRequest, start: FloatArray, effort: str = "thorough") -> _Attempt:
    """The design at a fixed duration (see the module docstring for the rule):

    1. the zero-energy design closest to the initial exponents, solved from ``start``;
    2. if IPOPT does not reach one (and ``effort`` is not "probe"): minimise the energy from the
       initial exponents and (``effort`` "thorough") from fixed spread starts, keeping the
       lowest-energy design that meets the limits; if its energy is zero to round-off, move it
       to the closest zero-energy design.

    Raises Infeasible when no start yields a design within the limits.
    """
    compiled, p, gamma0 = _prepare(request)
    lbg_c, ubg_c, lbg_m, ubg_m = compiled.g_bounds
    lbx, ubx = np.full(gamma0.size, lower_bound(request.order)), np.full(gamma0.size, MAX_EXPONENT)
    iterations, elapsed, solves = 0, 0.0, 0

    def run(solver: Any, x0: FloatArray, lbg: FloatArray, ubg: FloatArray) -> tuple[FloatArray, SolverReport]:
        nonlocal iterations, elapsed, solves
        started = time.perf_counter()
        solution = solver(x0=np.clip(x0, lbx, ubx), p=p, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
        report = report_of(solver, time.perf_counter() - started)
        iterations, elapsed, solves = iterations + report.iterations, elapsed + report.solve_time_s, solves + 1
        return np.asarray(solution["x"]).ravel(), report

    def attempt(gamma: FloatArray, stage: str, report: SolverReport) -> _Attempt:
        gamma = np.clip(gamma, lbx, ubx)  # IPOPT may end a hair outside a bound
        energy, residual, _ = compiled.evaluate(gamma, p)
        return _Attempt(
            gamma, stage, SolverReport(report.status, iterations, elapsed), float(energy), float(residual), solves
        )

    def feasible(gamma: FloatArray) -> bool:
        return float(compiled.violation(gamma, p)) <= 1e-9

    gamma, report = run(compiled.probe if effort == "probe" else compiled.quick, start, lbg_c, ubg_c)
    if report.timed_out or (report.converged and feasible(gamma)):
        return attempt(gamma, "closest_zero_energy", report)
    if effort == "probe":
        raise Infeasible("no zero-energy design reached from the start", field="limits")
    energy_ref = float(p[compiled.layout["energy_ref"]][0])
    best: tuple[float, FloatArray, SolverReport] | None = None
    last: SolverReport | None = None
    reached_limits = False
    for x0 in [gamma0, *(spread_starts(request.order) if effort == "thorough" else [])]:
        if elapsed > 2.0 * request.caps.max_wall_time_s:
            break  # the starts so far have used the time a design may take
        candidate, rep = run(compiled.minimum, x0, lbg_m, ubg_m)
        if rep.timed_out:
            report = rep
            break
        last = rep
        reached_limits = reached_limits or feasible(candidate)
        if rep.converged and feasible(candidate):  # a capped iterate is never a design
            energy = float(compiled.evaluate(candidate, p)[0])
            if best is None or energy < best[0]:
                best = (energy, candidate, rep)
            if energy <= ZERO_ENERGY * energy_ref:
                break
    if best is None:
        if report.timed_out:
            return attempt(gamma, "minimum_energy", report)
        if reached_limits and last is not None:  # designs within the limits exist, but no solve converged
            raise SolverFailed(SolverReport(last.status, iterations, elapsed), "no minimum-energy solve converged")
        raise Infeasible(
            f"no pseudo-polynomial command of order {request.order} found that moves {request.displacement:.6g} in "
            f"{request.duration_s:.6g} s within the limits; lengthen duration_s, raise the limits or try another order",
            field="limits",
        )
    energy, candidate, rep = best
    if energy <= ZERO_ENERGY * energy_ref:
        closer, rep_c = run(compiled.closest, candidate, lbg_c, ubg_c)
        if rep_c.converged and feasible(closer):
            return attempt(closer, "closest_zero_energy", rep_c)
    return attempt(candidate, "minimum_energy", rep)


def _raise_unless_design(attempt: _Attempt) -> None:
    """A timed-out or failed closest-zero solve is never a design; a minimum-energy design is
    only returned when it was checked to meet the limits (``_solve_at``)."""
    if attempt.report.timed_out or attempt.stage == "closest_zero_energy":
        raise_for_status(attempt.report)
