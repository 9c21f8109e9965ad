"""The time-optimal family: the shortest command that leaves no residual vibration, or whose percentage
vibration stays below a bound over a band of frequencies (optim.families.time_optimal).

Literature: time-optimal rest-to-rest control of flexible systems (Singh and Vadali 1993; Pao and
Singhose 1996, 1998, on the robust and jerk-limited forms), computed as linear programs on a grid as in
Dhanda, Vaughan and Singhose 2009, here with a certificate (a relaxation proven infeasible) and an exact
refinement of the switching times.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import partial
from typing import Any, ClassVar

import numpy as np

from models.errors import DomainError, Infeasible, InvalidParameter, SolverFailed, SolverTimedOut
from models.simulation import simulate
from optim.families.time_optimal import Arc, Solution, Spec, Torque, command_of, solve
from optim.families.time_optimal.arcs import exact_peaks, merged
from optim.families.time_optimal.certify import certificate
from optim.families.time_optimal.options import Robustness, TimeOptimalOptions, bands_of
from optim.families.time_optimal.refine import newton
from optim.families.time_optimal.report import (
    TimeOptimalExtras,
    TimeOptimalReport,
    TradeoffPoint,
    design_report,
    robustness_report,
)
from optim.families.time_optimal.shaped import nominal_shaper, rigid_of, shaped_arcs
from optim.families.time_optimal.types import MAX_MODES
from optim.family import BaseFamily, Candidate, Design, Run, SolverSummary, counted
from optim.problem import Problem
from optim.results import Finish
from optim.solver import SolverReport

LIMIT_RTOL = 1e-10  # a refined command must meet its limits this tightly (the pipeline refuses above 1e-9)
SEARCH_PERIODS = 20.0  # default max_duration_s: 4 x the rigid time plus this many periods of the slowest mode,
MAX_DURATION_S = 1e4  # and at most this (the schema's bound on max_duration_s)


@dataclass(frozen=True)
class _TimeOptimalDetail:
    solution: Solution
    modes: tuple[int, ...]
    robustness: Robustness | None
    tradeoff: tuple[TradeoffPoint, ...] | None


def selected_modes(problem: Problem, options: TimeOptimalOptions) -> tuple[tuple[int, ...], tuple[str, ...]]:
    modes = problem.plant.modes()
    if options.modes is None:
        chosen = tuple(range(min(len(modes), MAX_MODES)))
        notes = (
            (f"the plant has {len(modes)} modes: the lowest {MAX_MODES} are cancelled (list others in modes)",)
            if len(modes) > MAX_MODES
            else ()
        )
        return chosen, notes
    for k, index in enumerate(options.modes):
        if not 0 <= index < len(modes):
            raise InvalidParameter(f"modes[{k}]", index, f"the plant has modes 0..{len(modes) - 1} (lowest first)")
    chosen = tuple(sorted(set(options.modes)))
    if len(chosen) > MAX_MODES:
        raise InvalidParameter("modes", list(options.modes), f"at most {MAX_MODES} modes can be cancelled")
    return chosen, ()


def _torque(problem: Problem) -> Torque | None:
    inertias = problem.plant.torque_inertias()
    if problem.limits.max_torque_nm is None or inertias is None:
        return None
    return Torque(inertias[0], inertias[1], problem.limits.max_torque_nm, problem.plant.modes()[0].pole)


def spec_of(problem: Problem, options: TimeOptimalOptions, chosen: tuple[int, ...]) -> Spec:
    modes = problem.plant.modes()
    robust = options.robustness
    bands, covered = bands_of(problem, robust, chosen)
    keep = robust is None or robust.zero_residual_at_modes  # by default the load settles when the command ends
    zero = tuple(modes[i].pole for i in chosen if keep or i not in covered)
    order = 0 if robust is None else robust.derivative_order
    reference = problem.rigid_reference
    floor = problem.rigid_floor_s  # the proven floor (Ruckig's, jerk included)
    # The search's first guess and its default cap come from the closed-form floor and the jerk-free rigid move, as
    # before issue 25: the grids they give are the ones whose structures refine well (a guess from Ruckig's floor
    # lost 4 % on bench/time_optimal.py's 10 Hz cruise with a jerk limit).
    closed = problem.kinematic_floor_s()
    rigid = float(reference.time_s[-1]) if problem.acceleration_limit is not None else closed
    if problem.in_motion:  # the rest-to-rest forms say little of a move between velocities: Ruckig's does
        rigid = max(rigid, floor)
    periods = sum((0.5 + 0.5 * order) * modes[i].damped_period_s for i in chosen)
    slowest = max(modes[i].natural_period_s for i in chosen)
    periods += slowest * len(bands)  # the same grids for every band width: a narrower band is never longer
    upper = max(rigid, closed) + periods  # GridSearch.grid_optimum starts at least 1 % above the floor
    cap = options.max_duration_s or min(MAX_DURATION_S, 4.0 * max(rigid, closed, floor) + SEARCH_PERIODS * slowest)
    if cap <= floor and options.max_duration_s is not None:
        raise InvalidParameter(
            "max_duration_s", cap, f"must exceed the rigid minimum time within the limits ({floor:.6g} s)"
        )
    if cap <= floor:
        raise Infeasible(
            f"the rigid minimum time within the limits is {floor:.6g} s, beyond the longest command searched "
            f"({MAX_DURATION_S:g} s)",
            problem.move_field,
        )
    start, end = problem.initial_state, problem.final_state
    sign = math.copysign(1.0, problem.move)  # the spec's move is positive: the states in its direction
    return Spec(
        move=abs(problem.move),
        rest_to_rest=problem.rest_to_rest,
        max_velocity=problem.limits.max_velocity,
        max_acceleration=problem.limits.max_acceleration,
        max_jerk=problem.limits.max_jerk,
        torque=_torque(problem),
        zero_poles=zero,
        derivative_order=order,
        bands=bands,
        reference=reference,
        floor_s=floor,
        upper_guess_s=min(upper, cap),
        max_duration_s=cap,
        sufficient_s=options.sufficient_duration_s,
        lp_time_limit_s=problem.solver.max_wall_time_s,
        start_velocity=sign * start.velocity,
        start_acceleration=sign * start.acceleration,
        end_velocity=sign * end.velocity,
        end_acceleration=sign * end.acceleration,
    )


def limits_met(problem: Problem, spec: Spec, arcs: tuple[Arc, ...]) -> bool:
    """The refined command's exact peaks within the limits (the pipeline's own check is 1e-9): in closed form
    (arcs.exact_peaks), independent of the refinement's kernels."""
    peaks = exact_peaks(arcs, spec.order, spec.start_state())
    if not all(math.isfinite(x) for x in (peaks.velocity, peaks.acceleration, peaks.end_position)):
        return False  # (a comparison with NaN is False: it would pass every limit below)
    for peak, limit in (
        (peaks.velocity, spec.max_velocity),
        (peaks.acceleration, spec.max_acceleration),
        (peaks.jerk, spec.max_jerk),
    ):
        if limit is not None and (peak is None or peak > limit * (1 + LIMIT_RTOL)):
            return False
    end_s = arcs[-1].start_s + arcs[-1].duration_s
    scale = spec.position_scale(end_s)  # round-off is relative to the positions passed through
    return not (problem.rest_to_rest and abs(peaks.end_position - spec.move) > 1e-12 * scale)


TIGHTENINGS = 3


def excess(problem: Problem, spec: Spec, arcs: tuple[Arc, ...]) -> dict[str, float]:
    """peak / limit > 1 for every limit a grid command breaks beyond the LP's own check: the velocity of a held
    jerk between nodes, the acceleration (a safety net: the nodes are checked), the torque (simulated on 4000
    points and the corners)."""
    peaks = exact_peaks(arcs, spec.order, spec.start_state())
    out: dict[str, float] = {}
    peak, accel = peaks.velocity, peaks.acceleration
    if spec.max_velocity is not None and peak > spec.max_velocity * (1 + LIMIT_RTOL):
        out["max_velocity"] = peak / spec.max_velocity
    if spec.max_acceleration is not None and accel > spec.max_acceleration * (1 + LIMIT_RTOL):
        out["max_acceleration"] = accel / spec.max_acceleration
    if spec.torque is not None:
        command = command_of(arcs, spec.order, spec.rest_to_rest, spec.start_state())
        fine = command.resampled(float(command.time_s[-1]) / 4000)
        torque = simulate(problem.plant, fine).motor_torque_nm
        peak_torque = float(np.max(np.abs(torque))) if torque is not None else 0.0
        if peak_torque > spec.torque.max_torque_nm * (1 + LIMIT_RTOL):
            out["max_torque_nm"] = peak_torque / spec.torque.max_torque_nm
    return out


SHAPED_TORQUE_ROUNDS = 8  # the shaped rigid optimum's acceleration lowered at most this many times


def shaped_within_torque(problem: Problem, spec: Spec) -> tuple[Arc, ...] | None:
    """With a torque limit, the shaped rigid optimum (optim.families.time_optimal.shaped) whose acceleration is
    lowered by its torque's excess until the motor torque, simulated as ``excess`` does, is within the limit. The
    shaped command's torque J_M a + J_L a_L is the shaper's convex combination of the rigid move's, so it is at
    most the rigid move's peak, which scales with the acceleration: a few rounds suffice. None without a torque
    limit, or if it does not settle within SHAPED_TORQUE_ROUNDS."""
    if spec.torque is None:
        return None
    accel = problem.acceleration_limit
    for _ in range(SHAPED_TORQUE_ROUNDS):
        rigid_spec = replace(spec, torque=None, max_acceleration=accel)
        shaper = nominal_shaper(rigid_spec)
        rigid = rigid_of(rigid_spec, shaper)  # the shaper's delays at the end velocities (a move in motion)
        if rigid is None:
            return None
        arcs = shaped_arcs(rigid, shaper)
        over = excess(problem, spec, arcs)
        if not over and limits_met(problem, spec, arcs):
            return arcs
        if set(over) != {"max_torque_nm"} or accel is None:
            return None
        accel = accel / over["max_torque_nm"] * (1.0 - 1e-6)
    return None


def _with_shaped_torque(problem: Problem, spec: Spec, solution: Solution, valid: bool) -> Solution | None:
    """The torque-limited shaped rigid optimum where it is shorter than ``solution`` or ``solution`` is not
    ``valid`` (it breaks a limit), else ``solution`` if valid, else None. The search's counts and its lower bound
    (of the problem as asked) are kept."""
    arcs = shaped_within_torque(problem, spec)
    if arcs is None or (valid and solution.duration_s <= sum(a.duration_s for a in arcs)):
        return solution if valid else None
    total = sum(a.duration_s for a in arcs)
    note = "the rigid move (Ruckig) at the acceleration its shaped torque allows, shaped by ZV per mode"
    return replace(
        solution,
        arcs=arcs,
        duration_s=total,
        lower_bound_s=min(solution.lower_bound_s, total),
        method="shaped_rigid",
        refinement=note,
    )


def solve_within_limits(problem: Problem, spec: Spec) -> Solution:
    """solve, with a limit the grid command breaks between its check points tightened by its excess and solved
    again (at most TIGHTENINGS times); the refined commands are checked exactly by limits_met. With a torque
    limit the shaped rigid optimum within it answers where it is shorter, or where the tightenings fail."""
    current = spec
    solves = iterations = capped_runs = capped_lps = 0
    seconds = 0.0
    for attempt in range(TIGHTENINGS):
        solution = solve(current, partial(limits_met, problem, current), bound_spec=spec)
        solves, iterations = solves + solution.lp_solves, iterations + solution.lp_iterations
        capped_runs, capped_lps = capped_runs + solution.capped_runs, capped_lps + solution.capped_lps
        seconds += solution.solve_time_s
        over = excess(problem, spec, solution.arcs)
        if not over or attempt == TIGHTENINGS - 1:  # the report counts every solve, the tightened ones too
            counted = replace(
                solution,
                lp_solves=solves,
                lp_iterations=iterations,
                solve_time_s=seconds,
                capped_runs=capped_runs,
                capped_lps=capped_lps,
            )
            best = _with_shaped_torque(problem, spec, counted, valid=not over)
            if best is not None:
                return best
            break
        margin = 1.0 - (1e-6, 1e-3, 1e-2)[attempt]  # a little more each time: the excess moves with the limit
        if "max_velocity" in over and current.max_velocity is not None:
            current = replace(current, max_velocity=current.max_velocity / over["max_velocity"] * margin)
        if "max_acceleration" in over and current.max_acceleration is not None:
            current = replace(current, max_acceleration=current.max_acceleration / over["max_acceleration"] * margin)
        if "max_torque_nm" in over and current.torque is not None:
            torque = replace(
                current.torque, max_torque_nm=current.torque.max_torque_nm / over["max_torque_nm"] * margin
            )
            current = replace(current, torque=torque)
    raise SolverFailed(
        SolverReport("limits_not_met", iterations, seconds),
        f"the grid command still breaks {', '.join(f'limits.{k}' for k in over)} between its check points after "
        f"{TIGHTENINGS} tightenings",
    )


class TimeOptimalFamily(BaseFamily):
    name: ClassVar[str] = "time_optimal"
    moves_in_motion: ClassVar[bool] = True

    def not_applicable(self, problem: Problem) -> str | None:
        if not problem.plant.modes():
            return "the plant has no vibration mode to cancel: the rigid time-optimal move is the answer"
        if (
            problem.limits.max_acceleration is None
            and problem.limits.max_jerk is None
            and problem.limits.max_torque_nm is None
        ):
            return (
                "the minimum-time command is impulsive without a bound on the acceleration: give "
                "limits.max_acceleration (or limits.max_jerk, or limits.max_torque_nm on a two_inertia plant)"
            )
        return None

    def default_options(self, problem: Problem) -> TimeOptimalOptions:
        return TimeOptimalOptions()

    def candidates(self, problem: Problem) -> tuple[Candidate, ...]:
        return (Candidate(self.name, TimeOptimalOptions(), self.name),)

    def uses_solver(self, options: Any) -> bool:
        return True

    def design(self, problem: Problem, options: TimeOptimalOptions) -> Design:
        chosen, notes = selected_modes(problem, options)
        spec = spec_of(problem, options, chosen)
        with counted() as counts:  # every LP: the design's, its tightened re-solves, and every trade-off row's
            solution = solve_within_limits(problem, spec)
            sign = math.copysign(1.0, problem.move)
            arcs = tuple(replace(a, level=sign * a.level) for a in solution.arcs)
            command = command_of(arcs, spec.order, spec.rest_to_rest, tuple(sign * v for v in spec.start_state()))
            tradeoff, row_capped = None, 0
            if options.tradeoff is not None:
                tradeoff, row_capped = self._tradeoff(problem, options, chosen)
        detail = _TimeOptimalDetail(solution, chosen, options.robustness, tradeoff)
        extra: tuple[str, ...] = (
            () if solution.method != "grid" else (f"the switching times are the grid's ({solution.refinement})",)
        )
        if solution.capped_lps + row_capped:
            count = solution.capped_lps + row_capped
            rows = f" ({row_capped} in the trade-off rows)" if row_capped else ""
            extra += (
                f"{count} LP{'' if count == 1 else 's'}{rows} stopped at their iteration cap "
                f"({solution.max_lp_iterations} HiGHS iterations per method) and counted as 'no command found' "
                "at their length: a duration may exceed its search grid's optimum",
            )
        # design.method (optim.families.time_optimal.minimum_time): "refined", exact switching times, the shortest
        # command found (proven the minimum where its switching function certifies it, lower_bound_method says so;
        # else see design.lower_bound_s); "shaped_rigid", the shaped rigid
        # optimum; "grid", the search grid's optimum. Counts cover every solve, rows too.
        report = SolverSummary.of_tally(solution.method, counts)
        block = design_report(problem, spec, options, solution, arcs, chosen)
        return Design(command, block, (*notes, *extra), report, detail=detail)

    def redesign(self, problem: Problem, options: TimeOptimalOptions, previous: Design) -> Design | None:
        """The design of ``problem`` from ``previous``'s arc structure (a design of a nearby problem: another mode,
        the same limits and move) by Newton on its switching times (refine.newton), in milliseconds; None where
        there is no such structure (a band, a grid answer), Newton does not converge or a limit breaks. Its lower
        bound is the switching function's certificate where it proves the command minimum-time, else the rigid
        floor (optim.programs' effective modes: many nearby designs)."""
        detail = previous.detail
        if not isinstance(detail, _TimeOptimalDetail) or detail.solution.method == "grid" or options.robustness:
            return None
        chosen, _ = selected_modes(problem, options)
        spec = spec_of(problem, options, chosen)
        arcs = detail.solution.arcs
        if len(chosen) != len(detail.modes) or spec.order != detail.solution.order:
            return None
        refined = newton(spec, [a.duration_s for a in arcs], [a.level / spec.scale for a in arcs])
        if refined is None or not limits_met(problem, spec, refined.arcs) or excess(problem, spec, refined.arcs):
            return None
        total = sum(a.duration_s for a in refined.arcs)
        proof = certificate(spec, merged(refined.arcs))
        solution = replace(
            detail.solution,
            arcs=refined.arcs,
            duration_s=total,
            lower_bound_s=total if proof is not None else spec.floor_s,
            lower_bound_method=proof.describe()
            if proof is not None
            else "kinematic floor (the rigid time-optimal move)",
            method="refined",
            refinement="Newton on a nearby design's switching times",
            lp_solves=0,
            lp_iterations=0,
            notes=(),
        )
        sign = math.copysign(1.0, problem.move)
        signed = tuple(replace(a, level=sign * a.level) for a in refined.arcs)
        command = command_of(signed, spec.order, spec.rest_to_rest, tuple(sign * v for v in spec.start_state()))
        block = design_report(problem, spec, options, solution, signed, chosen)
        summary = SolverSummary("refined", 0, 0.0, 0)
        return Design(command, block, (), summary, detail=_TimeOptimalDetail(solution, chosen, None, None))

    def _tradeoff(
        self, problem: Problem, options: TimeOptimalOptions, chosen: tuple[int, ...]
    ) -> tuple[tuple[TradeoffPoint, ...], int]:
        """One row per half-width h: the minimum duration for the band [1 - h, 1 + h] (h = 0: zero residual),
        and the rows' LPs stopped at their iteration cap. A design for a wider band meets every narrower one, so a
        row never shows more than a wider band's duration (``from_half_width`` says which design it is: band
        designs are grid optima, within a step). A row's failure is its status, but a row that reaches the
        wall-clock last resort fails the design (SolverTimedOut): no answer depends on the machine's load."""
        robust = options.robustness or Robustness()
        solved: dict[float, TradeoffPoint] = {}
        capped = 0
        for h in sorted(set(options.tradeoff or ())):
            band = Robustness(
                frequency_ratio_range=(1.0 - h, 1.0 + h) if h > 0 else None,
                max_percentage_vibration=robust.max_percentage_vibration,
                damping_ratio_range=robust.damping_ratio_range,
            )
            spec = spec_of(problem, replace(options, robustness=band, tradeoff=None), chosen)
            try:
                s = solve_within_limits(problem, spec)
            except SolverTimedOut:
                raise
            except DomainError as exc:
                solved[h] = TradeoffPoint(h, (1.0 - h, 1.0 + h), None, None, exc.problem_type, str(exc))
                continue
            solved[h] = TradeoffPoint(h, (1.0 - h, 1.0 + h), s.duration_s, s.lower_bound_s, "ok", None)
            capped += s.capped_lps
        durations = {w: row.duration_s for w, row in solved.items() if row.duration_s is not None}
        bounds = {w: row.lower_bound_s for w, row in solved.items() if row.lower_bound_s is not None}
        rows = []
        for h in options.tradeoff or ():
            row = solved[h]
            source = min((w for w in durations if w >= h), key=durations.__getitem__, default=None)
            if source is not None and (row.duration_s is None or durations[source] < row.duration_s):
                row = replace(row, duration_s=durations[source], status="ok", reason=None)
            bound = max((b for w, b in bounds.items() if w <= h), default=None)
            rows.append(replace(row, lower_bound_s=bound, from_half_width=source))
        return tuple(rows), capped

    def finish(self, problem: Problem, design: Design, run: Run) -> Finish:
        detail: _TimeOptimalDetail = design.detail
        assert design.command is not None and isinstance(design.summary, TimeOptimalReport)
        robustness = robustness_report(problem, design.command, detail.robustness, detail.modes)
        extras = TimeOptimalExtras()
        if detail.tradeoff is not None:
            nominal = next((r.duration_s for r in detail.tradeoff if r.half_width == 0), None)
            extras = TimeOptimalExtras(
                tuple(
                    replace(r, cost_over_nominal=r.duration_s / nominal - 1 if nominal and r.duration_s else None)
                    for r in detail.tradeoff
                )
            )
        return Finish(replace(design.summary, robustness=robustness), extras)
