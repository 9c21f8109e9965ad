"""What the pseudo-polynomial family says of a design: its ``design`` block (the exponents chosen, the final energy
before and after, how they were selected, the duration search), and the ``initial`` design's profile, load and
metrics on the same sampling (optim.results blocks)."""

from __future__ import annotations

from dataclasses import dataclass

from models.simulation import Response
from optim.families import pseudo_polynomial as pp
from optim.family import Profile, SolverSummary
from optim.results import Block, MetricsReport

SELECTION_RULE = (
    "Zero final energy is two equations per mode in order + 1 exponents, so for order >= 2 the zero-energy "
    "designs form a curve (or a surface). The design returned is the zero-energy design closest to the "
    "initial exponents that IPOPT reaches from them (selection 'closest_zero_energy'). If none meets the "
    "limits, the energy is minimised from the initial exponents and six fixed spread starts and the "
    "lowest-energy design within the limits is returned (selection 'minimum_energy', energy_ratio > 0). If no "
    "minimum-energy solve converges, the lowest-energy design within the limits met on the way (the initial "
    "exponents or a solve's last iterate) is returned (selection 'fallback', fallback_reason says which). "
    "Every design is checked on the sampled command, as the response's limit check does, and re-solved with "
    "tightened limits where the solver's constraint grid let a peak through."
)


@dataclass(frozen=True)
class ExponentBounds(Block):
    min_exponent: float
    max_exponent: float
    min_separation: float


@dataclass(frozen=True)
class DurationTry(Block):
    """One duration of minimize_duration's search, and whether a design met the limits there."""

    duration_s: float
    feasible: bool


@dataclass(frozen=True)
class DurationBracket(Block):
    shortest_feasible_s: float
    longest_infeasible_below_s: float | None


@dataclass(frozen=True)
class PseudoPolynomialReport(Block):
    """The ``design`` block."""

    order: int
    duration_s: float
    displacement: float
    exponents: tuple[float, ...]
    coefficients: tuple[float, ...]
    initial_exponents: tuple[float, ...]
    initial_coefficients: tuple[float, ...]
    final_energy_before: float
    final_energy_after: float
    energy_ratio: float
    energy_units: str
    residual_amplitude: float
    initial_residual_amplitude: float
    selection: str
    selection_rule: str
    bounds: ExponentBounds
    fallback_reason: str | None
    solver: SolverSummary
    duration_search: tuple[DurationTry, ...] | None
    duration_search_method: str | None
    duration_bracket: DurationBracket | None


@dataclass(frozen=True)
class InitialDesign(Block):
    """The design of the initial exponents on the answer's sampling: what the optimisation changed."""

    profile: Profile
    load: Response
    metrics: MetricsReport


@dataclass(frozen=True)
class PseudoPolynomialExtras(Block):
    initial: InitialDesign


def design_report(design: pp.PseudoPolynomialDesign) -> PseudoPolynomialReport:
    law, initial = design.law, design.initial
    return PseudoPolynomialReport(
        order=law.order,
        duration_s=law.duration_s,
        displacement=law.displacement,
        exponents=law.exponents,
        coefficients=law.coefficients,
        initial_exponents=initial.exponents,
        initial_coefficients=initial.coefficients,
        final_energy_before=design.initial_energy,
        final_energy_after=design.final_energy,
        energy_ratio=design.energy_ratio,
        energy_units="J" if design.energy_is_physical else "per unit load inertia",
        residual_amplitude=design.residual_amplitude,
        initial_residual_amplitude=design.initial_residual_amplitude,
        selection=design.selection,
        selection_rule=SELECTION_RULE,
        bounds=ExponentBounds(
            min_exponent=pp.lower_bound(law.order),
            max_exponent=pp.MAX_EXPONENT,
            min_separation=pp.MIN_SEPARATION,
        ),
        fallback_reason=design.fallback_reason or None,
        solver=SolverSummary.of(design.solver, design.solves),
        duration_search=tuple(DurationTry(d, ok) for d, ok in design.duration_search) or None,
        duration_search_method=pp.SEARCH_METHOD if design.duration_search else None,
        duration_bracket=DurationBracket(
            shortest_feasible_s=law.duration_s,
            longest_infeasible_below_s=design.longest_infeasible_below_s,
        )
        if design.duration_search
        else None,
    )
