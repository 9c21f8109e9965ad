"""What the time-optimal family says of a design: its ``design`` block (arcs, bound, grid, search), the robustness
check on the exact command, and the trade-off rows (optim.results blocks)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from models.commands import PiecewiseCommand
from models.sensitivity import band_below, sensitivity
from optim.families.time_optimal.options import Robustness, TimeOptimalOptions, bands_of, zetas_of
from optim.families.time_optimal.types import Arc, Solution, Spec
from optim.problem import Problem
from optim.results import Block, omitted_when_none
from optim.synthesis import percentage_vibration

CHECK_POINTS = 2001  # the independent dense check of a band: at least this many frequencies,
MAX_CHECK_POINTS = 40_001  # about 50 per radian of the residual's phase across it (T dw), at most this many


@dataclass(frozen=True)
class ArcReport(Block):
    """One constant piece of the held quantity (a bang at the limit, a coast at zero, or a partial level)."""

    start_s: float
    duration_s: float
    level: float
    quantity: str
    kind: str


@dataclass(frozen=True)
class ModeConstraint(Block):
    index: int
    natural_frequency_hz: float
    damping_ratio: float
    constraint: str


@dataclass(frozen=True)
class GridReport(Block):
    step_s: float
    steps: int
    duration_s: float
    longest_not_found_s: float  # no command found on this grid at this length (no proof)


@dataclass(frozen=True)
class SearchReport(Block):
    lp_solves: int
    lp_iterations: int
    band_points: int
    solve_time_s: float
    lp_solver: str
    max_lp_iterations: int  # per LP and method: the caps are work, never time
    max_lp_solves: int  # per search (the design, each tightening, each trade-off row)
    lp_runs_at_iteration_cap: int
    lps_not_found_at_iteration_cap: int


@dataclass(frozen=True)
class AchievedBand(Block):
    frequency_ratio_range: tuple[float | None, float | None] | None
    frequency_range_hz: tuple[float | None, float | None] | None
    relative_to_mode: int


@dataclass(frozen=True)
class BandCheck(Block):
    mode: int
    requested_frequency_ratio_range: tuple[float, float]
    achieved: AchievedBand
    covers_request: bool
    worst_percentage_vibration: float


@dataclass(frozen=True)
class RobustnessReport(Block):
    requested: Robustness
    achieved: AchievedBand
    covers_request: bool
    worst_percentage_vibration: float
    max_percentage_vibration: float
    bands: tuple[BandCheck, ...]
    check: str


@dataclass(frozen=True)
class TimeOptimalReport(Block):
    """The ``design`` block."""

    duration_s: float
    lower_bound_s: float
    lower_bound_method: str
    optimality_gap: float | None
    rigid_duration_s: float | None
    cost_over_rigid: float | None
    held_quantity: str
    arcs: tuple[ArcReport, ...]
    modes: tuple[ModeConstraint, ...]
    derivative_order: int
    max_duration_s: float
    grid: GridReport | None  # None: the grid search found no command (the shaped rigid optimum is the answer)
    method: str  # "refined", "shaped_rigid" or "grid"
    refined: bool  # exact switching times ("refined" or "shaped_rigid")
    refinement: str
    search: SearchReport
    bands_rad_s: tuple[tuple[float, float], ...]
    robustness: RobustnessReport | None = None  # after sampling (optim.results.Finish)


@dataclass(frozen=True)
class TradeoffPoint(Block):
    """The minimum duration for the band [1 - h, 1 + h] (h = 0: zero residual), or why there is none."""

    half_width: float
    frequency_ratio_range: tuple[float, float]
    duration_s: float | None
    lower_bound_s: float | None
    status: str
    reason: str | None
    from_half_width: float | None = None  # the band whose design gives this row's duration
    cost_over_nominal: float | None = None


@dataclass(frozen=True)
class TimeOptimalExtras(Block):
    tradeoff: tuple[TradeoffPoint, ...] | None = omitted_when_none()


def arc_report(arc: Arc, order: int, unit: float) -> ArcReport:
    level = arc.level
    kind = "bang" if abs(abs(level) - unit) <= 1e-9 * unit else ("coast" if level == 0.0 else "partial")
    return ArcReport(arc.start_s, arc.duration_s, level, "jerk" if order == 3 else "acceleration", kind)


def design_report(
    problem: Problem,
    spec: Spec,
    options: TimeOptimalOptions,
    solution: Solution,
    arcs: tuple[Arc, ...],
    chosen: tuple[int, ...],
) -> TimeOptimalReport:
    modes = problem.plant.modes()
    rigid = problem.rigid_minimum_s
    bands, covered = bands_of(problem, options.robustness, chosen)
    grid = solution.grid
    return TimeOptimalReport(
        duration_s=solution.duration_s,
        lower_bound_s=solution.lower_bound_s,
        lower_bound_method=solution.lower_bound_method,
        optimality_gap=solution.duration_s / solution.lower_bound_s - 1.0 if solution.lower_bound_s > 0 else None,
        rigid_duration_s=rigid,
        cost_over_rigid=None if not rigid else solution.duration_s / rigid - 1.0,
        held_quantity="jerk" if spec.order == 3 else "acceleration",
        arcs=tuple(arc_report(a, spec.order, spec.scale) for a in arcs),
        modes=tuple(
            ModeConstraint(
                i,
                modes[i].natural_frequency_hz,
                modes[i].damping_ratio,
                "zero_residual_and_band" if i in covered else "zero_residual",
            )
            for i in chosen
        ),
        derivative_order=spec.derivative_order,
        max_duration_s=spec.max_duration_s,
        grid=None
        if grid is None
        else GridReport(
            grid.step_s, grid.steps, grid.steps * grid.step_s, longest_not_found_s=grid.infeasible_steps * grid.step_s
        ),
        method=solution.method,
        refined=solution.refined,
        refinement=solution.refinement,
        search=SearchReport(
            lp_solves=solution.lp_solves,
            lp_iterations=solution.lp_iterations,
            band_points=solution.cut_frequencies,
            solve_time_s=solution.solve_time_s,
            lp_solver="HiGHS (highspy)",
            max_lp_iterations=solution.max_lp_iterations,
            max_lp_solves=solution.max_lp_solves,
            lp_runs_at_iteration_cap=solution.capped_runs,
            lps_not_found_at_iteration_cap=solution.capped_lps,
        ),
        bands_rad_s=tuple((b.low_rad_s, b.high_rad_s) for b in bands),
    )


def robustness_report(
    problem: Problem, command: PiecewiseCommand, robust: Robustness | None, cancelled: tuple[int, ...]
) -> RobustnessReport | None:
    """The requested band, the achieved one and the worst V inside the request, by models.sensitivity on the
    exact command (CHECK_POINTS frequencies, every damping ratio asked): independent of the LP's weights. One
    entry per band (a ratio range gives one per cancelled mode); the top level is the first."""
    if robust is None:
        return None
    modes = problem.plant.modes()
    if robust.frequency_range_hz is not None:
        lo_w, hi_w = (2 * math.pi * f for f in robust.frequency_range_hz)
        centre = math.sqrt(lo_w * hi_w)
        nearest = min(cancelled, key=lambda i: abs(math.log(modes[i].natural_frequency_rad_s / centre)))
        entries = [band_check(problem, command, robust, nearest, lo_w, hi_w)]
    else:
        lo, hi = robust.frequency_ratio_range or (1.0, 1.0)
        entries = [
            band_check(
                problem,
                command,
                robust,
                i,
                lo * modes[i].natural_frequency_rad_s,
                hi * modes[i].natural_frequency_rad_s,
            )
            for i in cancelled
        ]
    first = entries[0]
    return RobustnessReport(
        requested=robust,
        achieved=first.achieved,
        covers_request=all(e.covers_request for e in entries),
        worst_percentage_vibration=max(e.worst_percentage_vibration for e in entries),
        max_percentage_vibration=robust.max_percentage_vibration,
        bands=tuple(entries),
        check=f"models.sensitivity on the exact command: {CHECK_POINTS} to {MAX_CHECK_POINTS} frequencies over "
        f"each requested band (50 per radian of the residual's phase) x the damping ratios asked (a range: its ends "
        f"and middle); the achieved band on {4 * CHECK_POINTS} more frequencies around it",
    )


def band_check(
    problem: Problem, command: PiecewiseCommand, robust: Robustness, index: int, lo_w: float, hi_w: float
) -> BandCheck:
    mode = problem.plant.modes()[index]
    omega, vmax = mode.natural_frequency_rad_s, robust.max_percentage_vibration
    zetas = np.asarray(zetas_of(robust, mode))
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
    hz = (
        None
        if achieved is None
        else (_times(achieved[0], mode.natural_frequency_hz), _times(achieved[1], mode.natural_frequency_hz))
    )
    return BandCheck(
        mode=index,
        requested_frequency_ratio_range=(lo, hi),
        achieved=AchievedBand(achieved, hz, index),
        covers_request=bool(covers),
        worst_percentage_vibration=worst,
    )


def _times(ratio: float | None, hz: float) -> float | None:
    return None if ratio is None else ratio * hz


def _v(
    problem: Problem, command: PiecewiseCommand, omega: float, ratios: NDArray[np.float64], zetas: NDArray[np.float64]
) -> NDArray[np.float64]:
    """V (%) per (damping ratio, frequency ratio) around the mode ``omega`` (optim.synthesis's definition)."""
    amplitude = sensitivity(command, omega, ratios, zetas, problem.rest_to_rest).amplitude
    return percentage_vibration(problem, amplitude, ratios, zetas, omega)[0]
