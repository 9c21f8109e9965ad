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
from numpy.typing import NDArray

from models.commands import PiecewiseCommand
from models.errors import DomainError, Infeasible, InvalidParameter, SolverFailed, SolverTimedOut
from models.plant_base import Mode
from models.sensitivity import band_below, sensitivity
from models.simulation import simulate
from optim.families.time_optimal import Arc, Band, Solution, Spec, Torque, command_of, solve
from optim.families.time_optimal.types import DEFAULT_MAX_PERCENTAGE_VIBRATION, MAX_MODES
from optim.family import BaseFamily, Candidate, Design, Run, SolverSummary, counted
from optim.problem import Problem
from optim.solver import SolverReport
from optim.synthesis import percentage_vibration, rigid_reference

LIMIT_RTOL = 1e-10  # a refined command must meet its limits this tightly (the pipeline refuses above 1e-9)
CHECK_POINTS = 2001  # the independent dense check of a band: at least this many frequencies,
MAX_CHECK_POINTS = 40_001  # about 50 per radian of the residual's phase across it (T dw), at most this many
MAX_TRADEOFF = 8
SEARCH_PERIODS = 20.0  # default max_duration_s: 4 x the rigid time plus this many periods of the slowest mode,
MAX_DURATION_S = 1e4  # and at most this (the schema's bound on max_duration_s)


@dataclass(frozen=True)
class Robustness:
    """A band (ratios to each cancelled mode, or absolute Hz) where V <= max_percentage_vibration, or zero
    residual and zero frequency derivatives up to ``derivative_order`` at the nominal modes."""

    frequency_ratio_range: tuple[float, float] | None = None
    frequency_range_hz: tuple[float, float] | None = None
    max_percentage_vibration: float = DEFAULT_MAX_PERCENTAGE_VIBRATION
    damping_ratio_range: tuple[float, float] | None = None
    derivative_order: int = 0
    zero_residual_at_modes: bool = True  # a band keeps exactly zero residual at the nominal modes too

    @property
    def has_band(self) -> bool:
        return self.frequency_ratio_range is not None or self.frequency_range_hz is not None


@dataclass(frozen=True)
class TimeOptimalOptions:
    robustness: Robustness | None = None
    modes: tuple[int, ...] | None = None
    tradeoff: tuple[float, ...] | None = None
    max_duration_s: float | None = None


@dataclass(frozen=True)
class _TimeOptimalDetail:
    solution: Solution
    modes: tuple[int, ...]
    robustness: Robustness | None
    tradeoff: tuple[dict[str, Any], ...] | None


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


def _zetas(robust: Robustness | None, mode: Mode) -> tuple[float, ...]:
    if robust is None or robust.damping_ratio_range is None:
        return (mode.damping_ratio,)
    lo, hi = robust.damping_ratio_range
    return tuple(sorted({lo, 0.5 * (lo + hi), hi}))


def _bands(problem: Problem, robust: Robustness | None, chosen: tuple[int, ...]) -> tuple[tuple[Band, ...], set[int]]:
    """The bands, and the chosen modes a band covers (exact zero there only if zero_residual_at_modes)."""
    if robust is None or not robust.has_band:
        return (), set()
    modes = problem.plant.modes()
    vmax = robust.max_percentage_vibration
    if robust.frequency_ratio_range is not None:
        lo, hi = robust.frequency_ratio_range
        bands = tuple(
            Band(
                lo * modes[i].natural_frequency_rad_s,
                hi * modes[i].natural_frequency_rad_s,
                _zetas(robust, modes[i]),
                vmax,
            )
            for i in chosen
        )
        return bands, set(chosen)
    assert robust.frequency_range_hz is not None
    lo_w, hi_w = (2 * math.pi * f for f in robust.frequency_range_hz)
    centre = math.sqrt(lo_w * hi_w)
    nearest = min(chosen, key=lambda i: abs(math.log(modes[i].natural_frequency_rad_s / centre)))
    covered = {i for i in chosen if lo_w <= modes[i].natural_frequency_rad_s <= hi_w}
    band = Band(lo_w, hi_w, _zetas(robust, modes[nearest]), vmax)
    return (band,), covered


def _torque(problem: Problem) -> Torque | None:
    inertias = problem.plant.torque_inertias()
    if problem.limits.max_torque_nm is None or inertias is None:
        return None
    return Torque(inertias[0], inertias[1], problem.limits.max_torque_nm, problem.plant.modes()[0].pole)


def spec_of(problem: Problem, options: TimeOptimalOptions, chosen: tuple[int, ...]) -> Spec:
    modes = problem.plant.modes()
    robust = options.robustness
    bands, covered = _bands(problem, robust, chosen)
    keep = robust is None or robust.zero_residual_at_modes  # by default the load settles when the command ends
    zero = tuple(modes[i].pole for i in chosen if keep or i not in covered)
    order = 0 if robust is None else robust.derivative_order
    reference = rigid_reference(problem)
    floor = problem.kinematic_floor_s()
    rigid = float(reference.time_s[-1]) if problem.acceleration_limit is not None else floor
    periods = sum((0.5 + 0.5 * order) * modes[i].damped_period_s for i in chosen)
    slowest = max(modes[i].natural_period_s for i in chosen)
    periods += sum(min(2 * math.pi / b.low_rad_s, 2 * slowest) for b in bands)  # the search doubles it if short
    upper = max(rigid, floor) + periods
    cap = options.max_duration_s or min(MAX_DURATION_S, 4.0 * max(rigid, floor) + SEARCH_PERIODS * slowest)
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
        lp_time_limit_s=problem.solver.max_wall_time_s,
    )


def limits_met(problem: Problem, spec: Spec, arcs: tuple[Arc, ...]) -> bool:
    """The refined command's exact peaks within the limits (the pipeline's own check is 1e-9)."""
    command = command_of(arcs, spec.order, spec.rest_to_rest)
    for m, limit in ((1, spec.max_velocity), (2, spec.max_acceleration), (3, spec.max_jerk)):
        peak = command.peak_abs(m)
        if limit is not None and (peak is None or peak > limit * (1 + LIMIT_RTOL)):
            return False
    end = command.end_index()
    return not (problem.rest_to_rest and abs(command.derivatives[0, end] - spec.move) > 1e-12 * spec.move)


TIGHTENINGS = 3


def excess(problem: Problem, spec: Spec, arcs: tuple[Arc, ...]) -> dict[str, float]:
    """peak / limit > 1 for every limit a grid command breaks beyond the LP's own check: the velocity of a held
    jerk between nodes, the acceleration (a safety net: the nodes are checked), the torque (simulated on 4000
    points and the corners)."""
    command = command_of(arcs, spec.order, spec.rest_to_rest)
    out: dict[str, float] = {}
    peak = command.peak_abs(1)
    if spec.max_velocity is not None and peak is not None and peak > spec.max_velocity * (1 + LIMIT_RTOL):
        out["max_velocity"] = peak / spec.max_velocity
    accel = command.peak_abs(2)
    if spec.max_acceleration is not None and accel is not None and accel > spec.max_acceleration * (1 + LIMIT_RTOL):
        out["max_acceleration"] = accel / spec.max_acceleration
    if spec.torque is not None:
        fine = command.resampled(float(command.time_s[-1]) / 4000)
        torque = simulate(problem.plant, fine).motor_torque_nm
        peak_torque = float(np.max(np.abs(torque))) if torque is not None else 0.0
        if peak_torque > spec.torque.max_torque_nm * (1 + LIMIT_RTOL):
            out["max_torque_nm"] = peak_torque / spec.torque.max_torque_nm
    return out


def solve_within_limits(problem: Problem, spec: Spec) -> Solution:
    """solve, with a limit the grid command breaks between its check points tightened by its excess and solved
    again (at most TIGHTENINGS times); the refined commands are checked exactly by limits_met."""
    current = spec
    solves = iterations = capped_runs = capped_lps = 0
    seconds = 0.0
    for attempt in range(TIGHTENINGS):
        solution = solve(current, partial(limits_met, problem, current), bound_spec=spec)
        solves, iterations = solves + solution.lp_solves, iterations + solution.lp_iterations
        capped_runs, capped_lps = capped_runs + solution.capped_runs, capped_lps + solution.capped_lps
        seconds += solution.solve_time_s
        over = excess(problem, spec, solution.arcs)
        if not over:  # the report counts every solve, the tightened ones too
            return replace(
                solution,
                lp_solves=solves,
                lp_iterations=iterations,
                solve_time_s=seconds,
                capped_runs=capped_runs,
                capped_lps=capped_lps,
            )
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


def _arc_block(arc: Arc, order: int, unit: float) -> dict[str, Any]:
    level = arc.level
    kind = "bang" if abs(abs(level) - unit) <= 1e-9 * unit else ("coast" if level == 0.0 else "partial")
    return {
        "start_s": arc.start_s,
        "duration_s": arc.duration_s,
        "level": level,
        "quantity": "jerk" if order == 3 else "acceleration",
        "kind": kind,
    }


class TimeOptimalFamily(BaseFamily):
    name: ClassVar[str] = "time_optimal"

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
            command = command_of(arcs, spec.order, spec.rest_to_rest)
            tradeoff, row_capped = None, 0
            if options.tradeoff is not None:
                tradeoff, row_capped = self._tradeoff(problem, options, chosen)
        detail = _TimeOptimalDetail(solution, chosen, options.robustness, tradeoff)
        extra: tuple[str, ...] = (
            () if solution.refined else (f"the switching times are the grid's ({solution.refinement})",)
        )
        if solution.capped_lps + row_capped:
            count = solution.capped_lps + row_capped
            rows = f" ({row_capped} in the trade-off rows)" if row_capped else ""
            extra += (
                f"{count} LP{'' if count == 1 else 's'}{rows} stopped at their iteration cap "
                f"({solution.max_lp_iterations} HiGHS iterations per method) and counted as 'no command found' "
                "at their length: a duration may exceed its search grid's optimum",
            )
        # "refined": exact switching times, the shortest command found (no proof of global optimality: see
        # design.lower_bound_s); "grid": the optimum of the search grid. Counts cover every solve, rows too.
        report = SolverSummary.of_tally("refined" if solution.refined else "grid", counts)
        block = _design_block(problem, spec, options, solution, arcs, chosen)
        return Design(command, block, (*notes, *extra), report, detail=detail)

    def _tradeoff(
        self, problem: Problem, options: TimeOptimalOptions, chosen: tuple[int, ...]
    ) -> tuple[tuple[dict[str, Any], ...], int]:
        """One row per half-width h: the minimum duration for the band [1 - h, 1 + h] (h = 0: zero residual),
        and the rows' LPs stopped at their iteration cap. A design for a wider band meets every narrower one, so a
        row never shows more than a wider band's duration (``from_half_width`` says which design it is: band
        designs are grid optima, within a step). A row's failure is its status, but a row that reaches the
        wall-clock last resort fails the design (SolverTimedOut): no answer depends on the machine's load."""
        robust = options.robustness or Robustness()
        solved: dict[float, dict[str, Any]] = {}
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
                solved[h] = {"duration_s": None, "lower_bound_s": None, "status": exc.problem_type, "reason": str(exc)}
                continue
            solved[h] = {"duration_s": s.duration_s, "lower_bound_s": s.lower_bound_s, "status": "ok", "reason": None}
            capped += s.capped_lps
        rows = []
        for h in options.tradeoff or ():
            row = dict(solved[h])
            wider = [w for w in solved if w >= h and solved[w]["duration_s"] is not None]
            source = min(wider, key=lambda w: solved[w]["duration_s"], default=None)
            if source is not None and (row["duration_s"] is None or solved[source]["duration_s"] < row["duration_s"]):
                row.update(duration_s=solved[source]["duration_s"], status="ok", reason=None)
            row["lower_bound_s"] = max(
                (solved[w]["lower_bound_s"] for w in solved if w <= h and solved[w]["lower_bound_s"] is not None),
                default=None,
            )
            rows.append(
                {"half_width": h, "frequency_ratio_range": [1.0 - h, 1.0 + h], **row, "from_half_width": source}
            )
        return tuple(rows), capped

    def finish(self, problem: Problem, design: Design, run: Run) -> dict[str, Any]:
        detail: _TimeOptimalDetail = design.detail
        out: dict[str, Any] = {"design": {"robustness": robustness_report(problem, design, detail)}}
        if detail.tradeoff is not None:
            nominal = next((r["duration_s"] for r in detail.tradeoff if r["half_width"] == 0), None)
            out["tradeoff"] = [
                {**r, "cost_over_nominal": None if not (nominal and r["duration_s"]) else r["duration_s"] / nominal - 1}
                for r in detail.tradeoff
            ]
        return out

    def request_fields(self, options: Any) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if options.robustness is not None:
            out["robustness"] = {
                k: list(v) if isinstance(v, tuple) else v for k, v in vars(options.robustness).items() if v is not None
            }
        if options.modes is not None:
            out["modes"] = list(options.modes)
        if options.tradeoff is not None:
            out["tradeoff"] = list(options.tradeoff)
        if options.max_duration_s is not None:
            out["max_duration_s"] = options.max_duration_s
        return out


def _design_block(
    problem: Problem,
    spec: Spec,
    options: TimeOptimalOptions,
    solution: Solution,
    arcs: tuple[Arc, ...],
    chosen: tuple[int, ...],
) -> dict[str, Any]:
    modes = problem.plant.modes()
    reference = rigid_reference(problem) if problem.acceleration_limit is not None else None
    rigid = None if reference is None else float(reference.time_s[-1])
    bands, covered = _bands(problem, options.robustness, chosen)
    grid = solution.grid
    return {
        "duration_s": solution.duration_s,
        "lower_bound_s": solution.lower_bound_s,
        "lower_bound_method": solution.lower_bound_method,
        "optimality_gap": solution.duration_s / solution.lower_bound_s - 1.0 if solution.lower_bound_s > 0 else None,
        "rigid_duration_s": rigid,
        "cost_over_rigid": None if not rigid else solution.duration_s / rigid - 1.0,
        "held_quantity": "jerk" if spec.order == 3 else "acceleration",
        "arcs": [_arc_block(a, spec.order, spec.scale) for a in arcs],
        "modes": [
            {
                "index": i,
                "natural_frequency_hz": modes[i].natural_frequency_hz,
                "damping_ratio": modes[i].damping_ratio,
                "constraint": "zero_residual_and_band" if i in covered else "zero_residual",
            }
            for i in chosen
        ],
        "derivative_order": spec.derivative_order,
        "max_duration_s": spec.max_duration_s,
        "grid": {
            "step_s": grid.step_s,
            "steps": grid.steps,
            "duration_s": grid.steps * grid.step_s,
            "longest_not_found_s": grid.infeasible_steps * grid.step_s,  # no command found on this grid (no proof)
        },
        "refined": solution.refined,
        "refinement": solution.refinement,
        "search": {
            "lp_solves": solution.lp_solves,
            "lp_iterations": solution.lp_iterations,
            "band_points": solution.cut_frequencies,
            "solve_time_s": solution.solve_time_s,
            "lp_solver": "HiGHS (scipy.optimize.linprog)",
            "max_lp_iterations": solution.max_lp_iterations,  # per LP and method: the caps are work, never time
            "max_lp_solves": solution.max_lp_solves,  # per search (the design, each tightening, each trade-off row)
            "lp_runs_at_iteration_cap": solution.capped_runs,
            "lps_not_found_at_iteration_cap": solution.capped_lps,
        },
        "bands_rad_s": [[b.low_rad_s, b.high_rad_s] for b in bands],
    }


def robustness_report(problem: Problem, design: Design, detail: _TimeOptimalDetail) -> dict[str, Any] | None:
    """The requested band, the achieved one and the worst V inside the request, by models.sensitivity on the
    exact command (CHECK_POINTS frequencies, every damping ratio asked): independent of the LP's weights. One
    entry per band (a ratio range gives one per cancelled mode); the top level is the first."""
    robust = detail.robustness
    if robust is None:
        return None
    command = design.command
    assert command is not None
    modes = problem.plant.modes()
    if robust.frequency_range_hz is not None:
        lo_w, hi_w = (2 * math.pi * f for f in robust.frequency_range_hz)
        centre = math.sqrt(lo_w * hi_w)
        nearest = min(detail.modes, key=lambda i: abs(math.log(modes[i].natural_frequency_rad_s / centre)))
        entries = [_band_entry(problem, command, robust, nearest, lo_w, hi_w)]
    else:
        lo, hi = robust.frequency_ratio_range or (1.0, 1.0)
        entries = [
            _band_entry(
                problem,
                command,
                robust,
                i,
                lo * modes[i].natural_frequency_rad_s,
                hi * modes[i].natural_frequency_rad_s,
            )
            for i in detail.modes
        ]
    requested: dict[str, Any] = {k: (list(v) if isinstance(v, tuple) else v) for k, v in vars(robust).items()}
    first = entries[0]
    return {
        "requested": requested,
        "achieved": first["achieved"],
        "covers_request": all(e["covers_request"] for e in entries),
        "worst_percentage_vibration": max(e["worst_percentage_vibration"] for e in entries),
        "max_percentage_vibration": robust.max_percentage_vibration,
        "bands": entries,
        "check": f"models.sensitivity on the exact command: {CHECK_POINTS} to {MAX_CHECK_POINTS} frequencies over "
        f"each requested band (50 per radian of the residual's phase) x the damping ratios asked (a range: its ends "
        f"and middle); the achieved band on {4 * CHECK_POINTS} more frequencies around it",
    }


def _band_entry(
    problem: Problem, command: PiecewiseCommand, robust: Robustness, index: int, lo_w: float, hi_w: float
) -> dict[str, Any]:
    mode = problem.plant.modes()[index]
    omega, vmax = mode.natural_frequency_rad_s, robust.max_percentage_vibration
    zetas = np.asarray(_zetas(robust, mode))
    lo, hi = lo_w / omega, hi_w / omega
    duration = float(command.time_s[command.end_index()] - command.time_s[0])
    points = int(min(MAX_CHECK_POINTS, max(CHECK_POINTS, math.ceil((hi_w - lo_w) * duration * 50) + 1)))
    inside = np.linspace(lo, hi, points) if hi > lo else np.array([lo])
    worst = float(np.max(_v(problem, command, omega, inside, zetas)))
    wide = np.union1d(np.linspace(max(0.02, lo / 3), min(50.0, max(3 * hi, 3.0)), 4 * CHECK_POINTS), inside)
    achieved = band_below(wide, np.max(_v(problem, command, omega, wide, zetas), axis=0), vmax, centre=0.5 * (lo + hi))
    covers = (
        achieved is not None
        and (achieved[0] is None or achieved[0] <= lo * (1 + 1e-9))
        and (achieved[1] is None or achieved[1] >= hi * (1 - 1e-9))
        and worst <= vmax * (1 + 1e-9)
    )
    ratio_range = None if achieved is None else [achieved[0], achieved[1]]
    return {
        "mode": index,
        "requested_frequency_ratio_range": [lo, hi],
        "achieved": {
            "frequency_ratio_range": ratio_range,
            "frequency_range_hz": None
            if ratio_range is None
            else [None if r is None else r * mode.natural_frequency_hz for r in ratio_range],
            "relative_to_mode": index,
        },
        "covers_request": bool(covers),
        "worst_percentage_vibration": worst,
    }


def _v(
    problem: Problem, command: PiecewiseCommand, omega: float, ratios: NDArray[np.float64], zetas: NDArray[np.float64]
) -> NDArray[np.float64]:
    """V (%) per (damping ratio, frequency ratio) around the mode ``omega`` (optim.synthesis's definition)."""
    amplitude = sensitivity(command, omega, ratios, zetas).amplitude
    return percentage_vibration(problem, amplitude, ratios, zetas, omega)[0]
