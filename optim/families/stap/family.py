"""The STAP family (Cusimano 2022): symmetric trapezoidal acceleration with jerk times tuned to the mode.

Rest-to-velocity, or a rest-to-rest move of two STAPs and a cruise at ``limits.max_velocity``.
Closed-form rules and the Fig. 25 flowchart, or IPOPT over (t_a, t_j) (see optim.families.stap).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, ClassVar, Literal

import numpy as np
from numpy.typing import NDArray

from models.errors import NotApplicable
from models.sensitivity import sensitivity
from models.stap import RestToRest, Stap, load_acceleration_oscillation, stap_sensitivity
from optim.families import stap as S
from optim.families.stap.report import StapReport, optimization_report, torque_report
from optim.family import BaseFamily, Candidate, Design, Run, SolverSummary, counted
from optim.problem import Problem
from optim.results import Finish, SensitivityCurve
from optim.solver import SolveCaps
from optim.synthesis import sensitivity_curve

AUTO_RULE = (
    "auto follows the Fig. 25 flowchart (Sec. 4). A design 'meets' when its undamped sensitivity curve (Appendix B) "
    "stays <= residual_tolerance for f_n/f_n,e in [1 - frequency_uncertainty, 1 + frequency_uncertainty]. Without "
    "acceleration_time_s: k_j = 1 (t_j = 1/f_n,e, eq. 50) first; if f_n,e t_a,min >= 1 (eq. 74) it is the trapezoid "
    "t_a = t_a,min + 1/f_n,e (eq. 61), and if it does not meet and int(f_n,e t_a,min) >= 2 (eqs. 63, 75) k_j = 2 is "
    "tried; if f_n,e t_a,min < 1 (eq. 76) it is the triangle t_a = 2/f_n,e (eq. 66, peak by eq. 31), lengthened to "
    "t_a = n/f_n,e, n = 3..10 with k_j = 1 until it meets. The first design that meets is returned, else the one with "
    "the lowest worst case (with a warning). With acceleration_time_s: the delta = 0 zero-vibration jerk time "
    "(eq. 49) with the lowest worst case (smallest k_j on ties); if none fits, the side band (0, 1) with a warning."
)


@dataclass(frozen=True)
class StapOptimization:
    objective: Literal["residual", "worst_case", "residual_and_time"] = "residual"
    damping_ratios: tuple[float, ...] | None = None
    frequency_points: int = 21


@dataclass(frozen=True)
class StapOptions:
    jerk_periods: int | Literal["auto"] = "auto"
    delta: int = 0
    acceleration_time_s: float | None = None
    method: Literal["closed_form", "optimized"] = "closed_form"
    frequency_uncertainty: float = S.DEFAULT_FREQUENCY_UNCERTAINTY
    residual_tolerance: float = S.DEFAULT_RESIDUAL_TOLERANCE
    optimization: StapOptimization | None = None


@dataclass(frozen=True)
class _StapDetail:
    closed: S.StapDesign
    optimized: S.OptimizedDesign | None
    options: StapOptions

    @property
    def kept(self) -> bool:
        """The closed form is the answer (method closed_form, or no solve beat it)."""
        return self.optimized is None or self.optimized.selection == "closed_form_kept"

    @property
    def stap(self) -> Stap:
        return self.closed.stap if self.optimized is None else self.optimized.stap

    @property
    def move(self) -> RestToRest | None:
        return self.closed.move if self.optimized is None else self.optimized.move


def core_request(problem: Problem, options: StapOptions) -> S.StapRequest:
    """The synthesis request: the cruise speed of a rest-to-rest move is limits.max_velocity (signed)."""
    lim = problem.limits
    target = problem.target_velocity
    if problem.displacement is not None and lim.max_velocity is not None:
        target = math.copysign(lim.max_velocity, problem.displacement)
    opt = options.optimization
    return S.check_request(
        S.StapRequest(
            plant=problem.plant,
            target_velocity=target,
            displacement=problem.displacement,
            max_acceleration=lim.max_acceleration,
            max_torque_nm=lim.max_torque_nm,
            jerk_periods=None if options.jerk_periods == "auto" else int(options.jerk_periods),
            delta=options.delta,
            acceleration_time_s=options.acceleration_time_s,
            frequency_uncertainty=options.frequency_uncertainty,
            residual_tolerance=options.residual_tolerance,
            objective=opt.objective if opt else "residual",
            band_damping_ratios=opt.damping_ratios if opt and opt.damping_ratios else None,
            frequency_points=opt.frequency_points if opt else 21,
            caps=problem.solver,
        )
    )


def design_report(problem: Problem, detail: _StapDetail) -> StapReport:
    closed, optimized, options = detail.closed, detail.optimized, detail.options
    stap, move = detail.stap, detail.move
    f = closed.estimated_frequency_hz
    speed = abs(stap.velocity)
    kept = detail.kept
    fixed = closed.fixed_acceleration_time and kept
    if kept or optimized is None:
        a_max, rule, torque = closed.acceleration_limit, closed.rule, torque_report(closed, speed)
        k_j, delta = closed.k_j, closed.delta
    else:
        a_max, torque = problem.limits.max_acceleration, None
        k_j = delta = None
        rule = f"optimized ({optimized.objective}): IPOPT over (t_a, t_j) from the closed-form design ({closed.rule})"
    peak = abs(stap.peak_acceleration)
    total = stap.acceleration_time_s if move is None else move.total_time_s
    return StapReport(
        method=options.method,
        move="rest_to_velocity" if move is None else "rest_to_rest",
        rule=rule,
        auto_rule=AUTO_RULE,
        estimated_frequency_hz=f,
        target_velocity=stap.velocity,
        acceleration_time_s=stap.acceleration_time_s,
        jerk_time_s=stap.jerk_time_s,
        constant_acceleration_time_s=stap.constant_acceleration_time_s,
        min_acceleration_time_s=None if a_max is None else speed / a_max,
        peak_acceleration=peak,
        peak_jerk=None if stap.jerk is None else abs(stap.jerk),
        shape=stap.shape,
        k_j=k_j,
        delta=delta,
        jerk_periods=f * stap.jerk_time_s,
        acceleration_time_periods=f * stap.acceleration_time_s,
        dimensionless_jerk_time=stap.dimensionless_jerk_time,
        acceleration_limit=a_max,
        limit_reached=a_max is not None and abs(peak - a_max) <= S.LIMIT_RTOL * a_max,
        torque_limit=torque,
        load_acceleration_oscillation=float(load_acceleration_oscillation(1.0, f * stap.jerk_time_s)),
        frequency_uncertainty=options.frequency_uncertainty,
        residual_tolerance=options.residual_tolerance,
        band_worst_residual=S.band_worst(stap, f, options.frequency_uncertainty),
        candidates=closed.candidates if fixed else None,
        candidates_truncated=closed.candidates_truncated if fixed else None,
        k_j_max=closed.k_j_max if kept else None,
        delta_f=closed.delta_f if kept else None,
        paper_k_j_max=closed.paper_k_j_max if kept else None,
        paper_delta_f=closed.paper_delta_f if kept else None,
        auto_steps=closed.auto_steps or None,
        displacement=None if move is None else move.displacement,
        cruise_velocity=None if move is None else move.ramp.velocity,
        cruise_time_s=None if move is None else move.cruise_time_s,
        duration_s=total,
        total_time_s=total,
        requested_velocity=None if move is None else closed.requested_velocity,
        velocity_lowered=None if move is None else closed.velocity_lowered,
        optimization=None
        if optimized is None
        else optimization_report(optimized, problem.limits.max_torque_nm is not None),
    )


class StapFamily(BaseFamily):
    name: ClassVar[str] = "stap"

    def default_options(self, problem: Problem) -> StapOptions:
        return StapOptions()

    def candidates(self, problem: Problem) -> tuple[Candidate, ...]:
        """The closed form and ``optimized`` in one group: compare keeps ``optimized`` only where it settles
        first (the optimiser returns the closed form itself when no solve beats it, and ties keep the first)."""
        return (
            Candidate("stap/closed_form", StapOptions(), self.name),
            Candidate("stap/optimized", StapOptions(method="optimized"), self.name),
        )

    def uses_solver(self, options: Any) -> bool:
        return bool(options.method == "optimized")

    def warm_up(self, solver: SolveCaps) -> None:
        S.warm_up(solver)

    def design(self, problem: Problem, options: StapOptions) -> Design:
        torque = problem.limits.max_torque_nm
        if problem.limits.max_acceleration is None and torque is None and options.acceleration_time_s is None:
            raise NotApplicable(
                "a STAP is designed from the acceleration limit: give limits.max_acceleration (or limits.max_torque_nm "
                "on a two_inertia plant), or a fixed acceleration_time_s",
                "limits.max_acceleration",
            )
        core = core_request(problem, options)
        closed = S.design(core)
        with counted():  # a failure's report: every solve of the multistart
            optimized = S.optimize(core, closed) if options.method == "optimized" else None
        detail = _StapDetail(closed, optimized, options)
        stap, move = detail.stap, detail.move
        command = stap.command() if move is None else move.command()
        notes = (
            *(closed.notes if detail.kept else ()),
            *(optimized.notes if optimized is not None else ()),
            *closed.move_notes,
        )
        solver = None if optimized is None else SolverSummary.of(optimized.solver, optimized.solves)
        return Design(command, design_report(problem, detail), notes, solver, detail=detail)

    def finish(self, problem: Problem, design: Design, run: Run) -> Finish:
        detail: _StapDetail = design.detail
        assert isinstance(design.summary, StapReport)
        m = run.metrics
        amplitude = m.residual_velocity_amplitude if detail.move is None else m.residual_amplitude
        residual = amplitude / problem.load_move
        warnings: list[str] = []
        mode = problem.plant.modes()[0]
        if detail.optimized is None and mode.damping_ratio > 0.0 and residual > 1e-6:
            warnings.append(
                f"the closed-form rules assume zeta = 0 (Sec. 2.3); with this plant's zeta = {mode.damping_ratio:.3g} "
                f"the design leaves {100 * residual:.3g} % of the move as residual vibration (method 'optimized' "
                "minimises it)"
            )
        if len(problem.plant.modes()) > 1:
            warnings.append(
                f"the STAP is designed for the first mode ({mode.natural_frequency_hz:.6g} Hz); the other modes' "
                "residuals are in metrics.modes"
            )
        return Finish(replace(design.summary, residual_vibration=residual), warnings=tuple(warnings))

    def sensitivity(
        self, problem: Problem, design: Design, ratios: NDArray[np.float64], zetas: NDArray[np.float64]
    ) -> SensitivityCurve | None:
        """Appendix B's closed form where it applies (zeta = 0, rest-to-velocity), else the exact free state."""

        detail: _StapDetail = design.detail
        if design.command is None:
            return None
        mode = problem.plant.modes()[0]
        closed = (zetas == 0.0) & (detail.move is None)
        grid = np.empty((zetas.size, ratios.size))
        if not np.all(closed):  # the free state only for the rows the closed form does not give
            free = ~closed
            grid[free] = sensitivity(design.command, mode.natural_frequency_rad_s, ratios, zetas[free]).residual
        if np.any(closed):
            grid[closed] = stap_sensitivity(detail.stap, mode.natural_frequency_hz, ratios)
        curve = sensitivity_curve(problem, design.command, ratios, zetas, rows=grid)
        return replace(curve, method=tuple("appendix_b" if c else "free_state" for c in closed))
