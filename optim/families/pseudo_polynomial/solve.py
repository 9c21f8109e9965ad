"""One pseudo-polynomial design at a fixed duration, from a start (Incerti, Secs. IV-V).

"Final energy = 0" (eq. 26 at T) is two equations per mode in n + 1 exponents: for n >= 2 the
zero-energy designs form a curve (PAPER-NOTES). The design is made well-posed by choosing, among them,
the one closest to the initial exponents that IPOPT reaches from them (stage "closest_zero_energy":
minimise |gamma - gamma_0|^2 subject to h_j(T) = 0 and the limits). If none is reached, the energy
is minimised within the limits from the initial exponents and a few fixed spread starts; a
zero-energy result is moved to the closest zero-energy design near it, otherwise the
lowest-energy design is returned (stage "minimum_energy") with its energy ratio. If no minimum-energy
solve converges, the lowest-energy design within the limits met on the way (the initial exponents, the
classical polynomial by default, or a solve's last iterate) is returned as stage "fallback", with the
reason. The starts are a fixed count (1 + SPREAD_STARTS), each capped in IPOPT iterations, so the design is
the same on any machine under any load; a solve that reaches IPOPT's wall-time cap (a last resort) raises
SolverTimedOut, never Infeasible and never a fallback.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from models.errors import Infeasible, SolverTimedOut
from models.plants import Plant
from models.pseudo_polynomial import PseudoPolynomial
from optim.families.pseudo_polynomial.parameters import prepare
from optim.families.pseudo_polynomial.problem import MAX_EXPONENT, MIN_SEPARATION, active_limits, lower_bound
from optim.families.pseudo_polynomial.types import FloatArray, Limits, PseudoPolynomialRequest
from optim.solver import SolverReport, raise_for_status, report_of

__all__ = [
    "SPREAD_STARTS",
    "TIGHTENING_ROUNDS",
    "ZERO_ENERGY",
    "Peaks",
    "PeaksOf",
    "check_limits_possible",
    "law_peaks",
    "overshoot",
    "solve_within",
    "spread_starts",
    "total",
]

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
class Peaks:
    """The peaks the pipeline checks against the limits (None: not checked / not defined)."""

    velocity: float | None = None
    acceleration: float | None = None
    jerk: float | None = None
    torque_nm: float | None = None


PeaksOf = Callable[[PseudoPolynomial], Peaks]


@dataclass(frozen=True)
class _Attempt:
    gamma: FloatArray
    stage: str
    report: SolverReport  # the last solve's status; iterations and time of every solve of the attempt
    energy: float
    residual: float
    solves: int
    note: str = ""  # why a fallback was chosen


def total(ledger: list[SolverReport], status: str) -> SolverReport:
    """One report for every solve in ``ledger``: the given status, the summed iterations and time."""
    return SolverReport(status, sum(r.iterations for r in ledger), sum(r.solve_time_s for r in ledger))


def law_peaks(plant: Plant, limits: Limits) -> PeaksOf:
    """The law's own peaks: |phi^(k)| on 20001 points and a geometric cluster near T; the motor torque
    (only when limited) of the law's command sampled at T/2000, simulated exactly."""

    def peaks(law: PseudoPolynomial) -> Peaks:
        T = law.duration_s
        t = np.concatenate([np.linspace(0.0, T, 20_001), T * (1.0 - np.logspace(-12, -4, 33))])
        values = [float(np.max(np.abs(law.derivative(k, t)))) for k in (1, 2, 3)]
        torque = None
        if limits.max_torque_nm is not None:
            from models.simulation import simulate

            tail = 5 * max(m.natural_period_s for m in plant.modes())
            torque_nm = simulate(plant, law.command(T / 2000, T + tail)).motor_torque_nm
            torque = None if torque_nm is None else float(np.max(np.abs(torque_nm)))
        return Peaks(values[0], values[1], values[2], torque)

    return peaks


def overshoot(limits: Limits, peaks: Peaks) -> dict[str, float]:
    """peak / limit for every requested limit whose checked peak exceeds it."""
    pairs = (
        ("max_velocity", limits.max_velocity, peaks.velocity),
        ("max_acceleration", limits.max_acceleration, peaks.acceleration),
        ("max_jerk", limits.max_jerk, peaks.jerk),
        ("max_torque_nm", limits.max_torque_nm, peaks.torque_nm),
    )
    return {name: peak / limit for name, limit, peak in pairs if limit and peak is not None and peak > limit}


def _scaled(limits: Limits, factors: dict[str, float]) -> Limits:
    return replace(limits, **{name: getattr(limits, name) * f for name, f in factors.items()})


def _solve_at(
    request: PseudoPolynomialRequest,
    start: FloatArray,
    effort: str = "thorough",
    ledger: list[SolverReport] | None = None,
) -> _Attempt:
    """The design at a fixed duration (see the module docstring for the rule):

    1. the zero-energy design closest to the initial exponents, solved from ``start`` (``effort``
       "probe": at most PROBE_ITERATIONS iterations, and a capped iterate within the limits is returned
       as stage "capped", never a design; "polish": QUICK_ITERATIONS, nothing else);
    2. if IPOPT does not reach one (and ``effort`` is not "probe"): minimise the energy from the
       initial exponents and (``effort`` "thorough") from fixed spread starts, keeping the
       lowest-energy design that meets the limits; if its energy is zero to round-off, move it
       to the closest zero-energy design;
    3. if no minimum-energy solve converged: the lowest-energy design within the limits met on the
       way (the initial exponents, or a solve's last iterate), as stage "fallback" with its reason.

    Raises Infeasible when no start yields a design within the limits, SolverTimedOut when a solve
    reaches its wall-time cap. Every solve's report is appended to ``ledger``.
    """
    compiled, p, gamma0 = prepare(request)
    lbg_c, ubg_c, lbg_m, ubg_m = compiled.g_bounds
    lbx, ubx = np.full(gamma0.size, lower_bound(request.order)), np.full(gamma0.size, MAX_EXPONENT)
    iterations, elapsed, solves = 0, 0.0, 0  # elapsed: reported only, never a reason to stop

    def run(solver: Any, x0: FloatArray, lbg: FloatArray, ubg: FloatArray) -> tuple[FloatArray, SolverReport]:
        nonlocal iterations, elapsed, solves
        started = time.perf_counter()
        solution = solver(x0=np.clip(x0, lbx, ubx), p=p, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
        report = report_of(solver, time.perf_counter() - started)
        if ledger is not None:
            ledger.append(report)
        iterations, elapsed, solves = iterations + report.iterations, elapsed + report.solve_time_s, solves + 1
        if report.timed_out:
            raise SolverTimedOut(
                SolverReport(report.status, iterations, elapsed),
                f"IPOPT reached its wall-time cap ({request.caps.max_wall_time_s:g} s) "
                f"at duration {request.duration_s:.6g} s",
            )
        return np.asarray(solution["x"]).ravel(), report

    def attempt(gamma: FloatArray, stage: str, status: str, note: str = "") -> _Attempt:
        gamma = np.clip(gamma, lbx, ubx)  # IPOPT may end a hair outside a bound
        energy, residual, _ = compiled.evaluate(gamma, p)
        return _Attempt(
            gamma, stage, SolverReport(status, iterations, elapsed), float(energy), float(residual), solves, note
        )

    def feasible(gamma: FloatArray) -> bool:
        return float(compiled.violation(np.clip(gamma, lbx, ubx), p)) <= 1e-9

    first = compiled.probe if effort == "probe" else compiled.quick
    gamma, report = run(first, start, lbg_c, ubg_c)
    if report.converged and feasible(gamma):
        return attempt(gamma, "closest_zero_energy", report.status)
    if effort == "probe" and feasible(gamma):
        return attempt(gamma, "capped", report.status)  # the search may polish it (duration_search)
    if effort in ("probe", "polish"):
        raise Infeasible("no zero-energy design reached from the start", field="limits")
    energy_ref = float(p[compiled.layout["energy_ref"]][0])
    best: tuple[float, FloatArray, SolverReport] | None = None
    met: list[tuple[float, FloatArray, str]] = []  # feasible designs met by unconverged solves, and the start
    if feasible(gamma0):
        met.append((float(compiled.evaluate(gamma0, p)[0]), gamma0, "the initial exponents"))
    last: SolverReport | None = None
    for x0 in [gamma0, *(spread_starts(request.order) if effort == "thorough" else [])]:
        candidate, rep = run(compiled.minimum, x0, lbg_m, ubg_m)
        last = rep
        if not feasible(candidate):
            continue
        energy = float(compiled.evaluate(candidate, p)[0])
        if not rep.converged:  # a capped iterate is never a converged design, at most a fallback
            met.append((energy, candidate, f"the last iterate of a minimum-energy solve ({rep.status})"))
            continue
        if best is None or energy < best[0]:
            best = (energy, candidate, rep)
        if energy <= ZERO_ENERGY * energy_ref:
            break
    if best is None:
        if met:
            energy, candidate, what = min(met, key=lambda m: m[0])
            status = last.status if last is not None else report.status
            note = (
                f"no minimum-energy solve converged ({status}); the lowest-energy design within the limits met: {what}"
            )
            return attempt(candidate, "fallback", status, note)
        raise Infeasible(
            f"no pseudo-polynomial command of order {request.order} found that moves {request.displacement:.6g} in "
            f"{request.duration_s:.6g} s within the limits; lengthen duration_s, raise the limits or try another order",
            field="limits",
        )
    energy, candidate, rep = best
    if energy <= ZERO_ENERGY * energy_ref:
        closer, rep_c = run(compiled.closest, candidate, lbg_c, ubg_c)
        if rep_c.converged and feasible(closer):
            return attempt(closer, "closest_zero_energy", rep_c.status)
    return attempt(candidate, "minimum_energy", rep.status)


TIGHTENING_ROUNDS = 4  # re-solves with limits tightened by the measured overshoot
TIGHTENING_SLACK = 1e-6  # each re-solve aims this fraction below the limit


def solve_within(
    request: PseudoPolynomialRequest,
    start: FloatArray,
    effort: str,
    peaks_of: PeaksOf | None,
    ledger: list[SolverReport] | None = None,
) -> _Attempt:
    """``_solve_at``, then the checked peaks (``peaks_of``: what the pipeline checks); where one exceeds
    its limit (the NLP sees the limits on a grid), re-solve from the design with that limit scaled by
    limit / peak, up to ``TIGHTENING_ROUNDS`` times. Raises Infeasible when the limits still do not hold."""
    factors: dict[str, float] = {}
    over: dict[str, float] = {}
    for _ in range(TIGHTENING_ROUNDS + 1):
        trial = replace(request, limits=_scaled(request.limits, factors))
        result = _solve_at(trial, start, effort, ledger)
        if peaks_of is None or not any(active_limits(request.limits)):
            return result
        over = overshoot(
            request.limits, peaks_of(PseudoPolynomial(request.displacement, request.duration_s, tuple(result.gamma)))
        )
        if not over:
            return result
        for name, ratio in over.items():
            factors[name] = factors.get(name, 1.0) / ratio * (1.0 - TIGHTENING_SLACK)
        start = result.gamma
    worst = ", ".join(f"limits.{name} by {100 * (ratio - 1):.3g} %" for name, ratio in over.items())
    raise Infeasible(
        f"the design at {request.duration_s:.6g} s still breaks {worst} on the sampled command after "
        f"{TIGHTENING_ROUNDS} re-solves with tightened limits; lengthen duration_s or shorten sample_period_s",
        field=f"limits.{next(iter(over))}",
    )


def _raise_unless_design(attempt: _Attempt) -> None:
    """A failed closest-zero solve is never a design (a timed-out one raised already); minimum-energy
    and fallback designs are only returned when they were checked to meet the limits (``_solve_at``)."""
    if attempt.stage == "closest_zero_energy":
        raise_for_status(attempt.report)
