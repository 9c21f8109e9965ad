"""The pseudo-polynomial family (Incerti): exponents chosen by IPOPT for zero final energy.

phi(t) = Phi [1 - sum C_i (1 - t/T)^gamma_i] (eq. 17); the exponents make the plant's vibration
energy vanish when the move ends (eqs. 24-31), within the limits (see optim.families.pseudo_polynomial).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from models.errors import InvalidParameter
from models.pseudo_polynomial import PseudoPolynomial
from models.simulation import simulate
from optim.families import pseudo_polynomial as pp
from optim.families.pseudo_polynomial.report import InitialDesign, PseudoPolynomialExtras, design_report
from optim.family import BaseFamily, Design, Grid, Profile, Run, SolverSummary, counted
from optim.problem import Problem
from optim.results import Finish, MetricsReport
from optim.solver import SolveCaps
from optim.synthesis import grid_until, horizon_of, metrics_of, nominal_percentage_vibration


@dataclass(frozen=True)
class PseudoPolynomialOptions:
    duration_s: float
    order: int = 2
    initial_exponents: tuple[float, ...] | None = None
    minimize_duration: bool = False
    residual_tolerance: float | None = None


def sampled_peaks(problem: Problem) -> pp.PeaksOf:
    """The peaks the pipeline checks (``optim.synthesis.limit_violations``): those of the law sampled as
    ``PseudoPolynomialFamily.sample`` does on the pipeline's grid for that duration, the motor torque
    from its exact simulation."""

    def peaks(law: PseudoPolynomial) -> pp.Peaks:
        grid = grid_until(problem, law.duration_s)
        command = law.command(grid.period_s, grid.horizon_s)
        torque = None
        if problem.limits.max_torque_nm is not None:
            torque_nm = simulate(problem.plant, command).motor_torque_nm
            torque = None if torque_nm is None else float(np.max(np.abs(torque_nm)))
        return pp.Peaks(command.peak_abs(1), command.peak_abs(2), command.peak_abs(3), torque)

    return peaks


class PseudoPolynomialFamily(BaseFamily):
    name: ClassVar[str] = "pseudo_polynomial"

    def not_applicable(self, problem: Problem) -> str | None:
        if not problem.rest_to_rest:
            return "pseudo-polynomial commands are rest-to-rest moves; give a displacement"
        if not problem.plant.modes():
            return "the plant has no vibration mode for a pseudo-polynomial command to cancel"
        return None

    def default_options(self, problem: Problem) -> PseudoPolynomialOptions:
        """Without limits, 5 periods of the slowest mode; with limits, the shortest duration: whole periods
        scanned from the kinematic floor (order-2 zero-energy designs live near them) up to those above twice
        the floor, here the duration_s of the options (optim.families.pseudo_polynomial.duration_search)."""
        period = problem.slowest_period_s
        if not problem.limits.any:
            return PseudoPolynomialOptions(duration_s=5 * period)
        start = max(2 * problem.kinematic_floor_s(), 5 * period)
        return PseudoPolynomialOptions(duration_s=period * math.ceil(start / period - 1e-9), minimize_duration=True)

    def uses_solver(self, options: Any) -> bool:
        return True

    def warm_up(self, solver: SolveCaps) -> None:
        pp.warm_up(solver)

    def design(self, problem: Problem, options: PseudoPolynomialOptions) -> Design:

        if problem.displacement is None:
            raise InvalidParameter("displacement", None, "pseudo-polynomial commands are rest-to-rest moves")
        lim = problem.limits
        core = pp.PseudoPolynomialRequest(
            plant=problem.plant,
            displacement=problem.displacement,
            duration_s=options.duration_s,
            order=options.order,
            initial_exponents=options.initial_exponents,
            limits=lim,
            minimize_duration=options.minimize_duration,
            residual_tolerance=options.residual_tolerance,
            caps=problem.solver,
        )
        # Refuse a sampling above the cap before any solve (the design is no longer than duration_s).
        grid_until(problem, options.duration_s)
        with counted():  # a failure's report: every solve of the search, not the last one's
            result = pp.design(core, sampled_peaks(problem))
        warnings = []
        within = " within the limits" if lim.any else ""
        if options.minimize_duration and not result.duration_search:  # the search found none (its note)
            warnings.append(f"minimize_duration: {result.fallback_reason}")
        if result.selection == "minimum_energy":
            warnings.append(
                f"no zero-energy design was found{within}; this one leaves {100 * result.energy_ratio:.3g} % of "
                "the initial design's vibration energy"
            )
        elif result.selection == "fallback":
            warnings.append(
                f"fallback: {result.fallback_reason}; it leaves {100 * result.energy_ratio:.3g} % of the initial "
                "design's vibration energy"
            )
        return Design(
            command=None,
            summary=design_report(result),
            warnings=tuple(warnings),
            solver=SolverSummary.of(result.solver, result.solves),
            end_s=result.law.duration_s,
            detail=result,
        )

    def sample(self, problem: Problem, design: Design, period_s: float, horizon_s: float) -> Any:
        law = design.detail.law
        try:
            return law.command(period_s, horizon_s)
        except InvalidParameter as exc:  # a sample beyond 1e12: the move itself is out of range
            raise InvalidParameter(
                "duration_s", law.duration_s, f"the move is too fast to sample ({exc.rule})"
            ) from None

    def profile(self, design: Design, sampled: Any, grid: Grid) -> Profile:
        """The law's exact values at the sample times, for the drive."""
        return design.detail.law.samples(sampled.time_s)  # type: ignore[no-any-return]

    def profile_at(self, design: Design, sampled: Any, time_s: NDArray[np.float64]) -> Profile:
        return design.detail.law.samples(time_s)  # type: ignore[no-any-return]

    def finish(self, problem: Problem, design: Design, run: Run) -> Finish:
        """The initial design's profile, load response and metrics on the same sampling."""

        initial = design.detail.initial
        command = initial.command(run.grid.period_s, horizon_of(problem, initial.duration_s))
        response = simulate(problem.plant, command)
        metrics = MetricsReport(metrics_of(problem, response), nominal_percentage_vibration(problem, command))
        return Finish(extras=PseudoPolynomialExtras(InitialDesign(initial.samples(command.time_s), response, metrics)))
