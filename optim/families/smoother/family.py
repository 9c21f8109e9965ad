"""The smoothers family (Biagiotti et al. 2020): a position step filtered by a chain of FIR smoothers.

Filters without a duration are tuned to the plant's first mode (the damped harmonic smoother with
T = 3 pi/Omega and sigma = -zeta omega_n cancels it, eqs. 10-11); rectangular filters are added in
front for the kinematic limits (eqs. 2-3, 6); the eq. (17) discrete filters on request.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar, Literal

from models.commands import PiecewiseCommand
from models.errors import InvalidParameter
from models.metrics import metrics
from models.simulation import simulate
from models.smoother_filters import FilterKind
from models.smoothers import MAX_RATE_TIMES_PERIOD, Chain, refinement, step_response
from optim.families.smoother.report import (
    ModeReport,
    PredictedPeaks,
    SmootherReport,
    discrete_report,
    filter_reports,
)
from optim.families.smoother.smoothers import (
    FilterSpec,
    SmootherLimits,
    chain_residual,
    commensurate_sample_period_s,
    design_chain,
    design_discrete,
    vibration_free_durations_s,
)
from optim.family import BaseFamily, Candidate, Design, Run
from optim.problem import Problem
from optim.results import Finish

# The kinds a duration tuned to the mode makes vibration-free on a damped mode (models.smoother_filters.DAMPED).
TUNED_KINDS: tuple[FilterKind, ...] = ("damped_harmonic", "exponential")


@dataclass(frozen=True)
class SmootherOptions:
    filters: tuple[FilterSpec, ...] = (FilterSpec("damped_harmonic"),)
    discrete_sample_period_s: float | None = None


def hold_residual(chain: Chain, command: PiecewiseCommand, problem: Problem) -> float:
    """Residual (fraction of the move) of the plant driven by the sampled profile alone, rebuilt the way a
    cam table with feed-forward interpolates it: the cubic Hermite curve through a quantity and its
    derivative, both continuous (position with velocity for a C^1 profile, velocity with acceleration for
    C^2, acceleration with jerk above), or a linear hold on the position for a C^0 profile."""
    smooth = chain.continuous_derivatives
    order = 0 if smooth == 0 else min(smooth - 1, 2)
    hold: Literal["linear", "cubic"] = "linear" if smooth == 0 else "cubic"
    initial = tuple(float(command.derivative(m)[0]) for m in range(order))
    slopes = command.derivative(order + 1) if hold == "cubic" else None
    held = PiecewiseCommand.from_samples(
        command.time_s, command.derivative(order), order, hold=hold, slopes=slopes, initial=initial
    )
    return metrics(simulate(problem.plant, held)).residual_amplitude / problem.load_move


class SmootherFamily(BaseFamily):
    name: ClassVar[str] = "smoother"

    def not_applicable(self, problem: Problem) -> str | None:
        if not problem.rest_to_rest:
            return "the smoother family shapes rest-to-rest moves (a filtered position step); give a displacement"
        return None

    def default_options(self, problem: Problem) -> SmootherOptions:
        return SmootherOptions()  # one damped harmonic smoother tuned to the plant: 3 pi/Omega, sigma = -zeta omega_n

    def candidates(self, problem: Problem) -> tuple[Candidate, ...]:
        """One chain per tuned filter kind (models.smoother_filters: the damped ones, S_sigma of duration
        3 pi/Omega and M_sigma of 2 pi/Omega, sigma = -zeta omega_n), in one group: compare keeps the one
        that settles first."""
        return tuple(
            Candidate(f"{self.name}/{kind}", SmootherOptions(filters=(FilterSpec(kind),)), self.name)
            for kind in TUNED_KINDS
        )

    def design(self, problem: Problem, options: SmootherOptions) -> Design:
        h = problem.move
        lim = problem.limits
        design = design_chain(
            problem.plant,
            h,
            list(options.filters),
            SmootherLimits(lim.max_velocity, lim.max_acceleration, lim.max_jerk),
        )
        chain, mode = design.chain, design.mode
        residual = chain_residual(chain, problem.plant, h, mode)
        warnings = list(design.warnings)
        if mode is not None and not residual.vibration_free:
            free = vibration_free_durations_s("damped_harmonic", mode)
            warnings.append(
                f"the chain does not cancel the plant's first mode ({mode.natural_frequency_hz:.6g} Hz, zeta "
                f"{mode.damping_ratio:.4g}): {100 * residual.fraction_of_move:.3g} % of the move is left; a "
                f"damped_harmonic filter of {', '.join(f'{t:.6g}' for t in free)} s (or omit duration_s) cancels it"
            )
        discrete = None
        if options.discrete_sample_period_s is not None:
            discrete = design_discrete(
                chain, problem.plant, h, mode, options.discrete_sample_period_s, problem.max_samples
            )
            prv = discrete.percent_residual_vibration
            if prv is not None and prv > 1e-4 and discrete.exact_sample_period_s is not None:
                warnings.append(
                    f"at Ts = {discrete.sample_period_s:.6g} s the discrete filters round T/Ts, which leaves "
                    f"{prv:.3g} % of the unfiltered vibration; Ts = {discrete.exact_sample_period_s:.9g} s makes "
                    "N Ts = T exactly"
                )
        summary = SmootherReport(
            filters=filter_reports(design),
            total_duration_s=chain.total_duration_s,
            duration_s=chain.total_duration_s,
            continuous_derivatives=chain.continuous_derivatives,
            mode=None if mode is None else ModeReport.of(mode),
            vibration_free=residual.vibration_free,
            percent_residual_vibration=residual.percent_residual_vibration,
            residual_amplitude_closed_form=residual.amplitude,
            residual_fraction_of_move=residual.fraction_of_move,
            predicted_peaks=PredictedPeaks(*design.predicted_peaks),
            discrete=None if discrete is None else discrete_report(discrete),
        )
        return Design(None, summary, tuple(warnings), end_s=chain.total_duration_s, detail=design)

    def _period(self, chain: Chain, period_s: float) -> tuple[int, float]:
        k = refinement(chain, period_s)
        return k, period_s / k

    def sample(self, problem: Problem, design: Design, period_s: float, horizon_s: float) -> PiecewiseCommand:
        """The chain's exact step response at every period (divided by k where the filters are too fast for
        it) and breakpoint, at rest at h until the horizon."""
        chain: Chain = design.detail.chain
        k, period = self._period(chain, period_s)
        count = int(horizon_s / period) + 1
        if count > problem.max_samples:
            why = (
                ""
                if k == 1
                else (
                    f"the filters (|lambda| = {chain.fastest_rate_1_s:.6g} 1/s) need samples at most {period:.3g} s "
                    "apart "
                    "to be described exactly, and "
                )
            )
            raise InvalidParameter(
                "sample_period_s",
                period_s,
                f"{why}{count} samples over {horizon_s:.6g} s exceed the cap of {problem.max_samples}",
            )
        command = step_response(chain, problem.move, period).command()
        if horizon_s > command.time_s[-1]:
            command = command.resampled(period, end_s=horizon_s)  # the motor rests at h; the load rings, or not
        return command

    def finish(self, problem: Problem, design: Design, run: Run) -> Finish:
        chain: Chain = design.detail.chain
        assert isinstance(design.summary, SmootherReport)
        k, period = self._period(chain, run.grid.period_s)
        warnings: list[str] = []
        if k > 1:
            warnings.append(
                f"sample_period_s {run.grid.period_s:.6g} s is divided by {k} (1 sample in {k} lies on the requested "
                f"grid): between samples the profile is exact only for |lambda| Ts <= {MAX_RATE_TIMES_PERIOD:g} "
                f"(|lambda| = {chain.fastest_rate_1_s:.6g} 1/s here)"
            )
        mode = design.detail.mode
        completed = replace(
            design.summary,
            sample_period_s=period,
            commensurate_sample_period_s=commensurate_sample_period_s(chain, mode, run.grid.period_s),
            hold_residual_fraction_of_move=hold_residual(chain, run.command, problem),
            residual_vibration=run.metrics.residual_amplitude / problem.load_move,
        )
        return Finish(completed, warnings=tuple(warnings))
