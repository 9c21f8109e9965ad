"""Request and response of POST /v1/profiles/pseudo-polynomial."""

from __future__ import annotations

from typing import Annotated, Any, ClassVar

from pydantic import Field

from app.schemas.common import Int, OutModel
from app.schemas.family import REST_TO_REST_ONLY, FamilyResponse, ProfileRequest, SolverOut
from app.schemas.simulate import LoadOut, MetricsOut, ProfileOut
from optim.families.pseudo_polynomial import MAX_EXPONENT, MAX_ORDER, MIN_SEPARATION
from optim.families.pseudo_polynomial.family import PseudoPolynomialOptions
from optim.problem import Problem
from optim.registry import FAMILIES

FAMILY = FAMILIES["pseudo_polynomial"]


class PseudoPolynomialIn(ProfileRequest):
    """A rest-to-rest move phi(t) = Phi [1 - sum C_i (1 - t/T)^gamma_i] (Incerti eq. 17) whose exponents
    are chosen by IPOPT to leave no vibration energy when the move ends (eqs. 24-31).

    Exponents are kept in [max(3, order + 0.05), 80] (above the order so the end conditions hold, at least 3
    so the jerk stays bounded) and at least 0.05 apart (eq. 22 stays well conditioned)."""

    duration_s: float | None = Field(
        None,
        ge=1e-6,
        le=1e5,
        description="Motion time T, s. Default: 5 periods of the slowest mode without limits; with limits, the "
        "shortest duration found by minimize_duration, scanning whole periods from the kinematic floor up to "
        "whole periods above twice the floor (at least 5).",
    )
    order: Int = Field(
        2, ge=1, le=MAX_ORDER, description="n: derivatives up to n are null at both ends (n + 1 exponents)."
    )
    initial_exponents: list[Annotated[float, Field(gt=1, le=MAX_EXPONENT)]] | None = Field(
        None,
        description="Starting exponents (each in (1, 80], above the order n); default n+1, ..., 2n+1, the classical "
        "polynomial ((3, 4, 5) for n = 2).",
    )
    minimize_duration: bool = Field(
        False,
        description="Search the shortest duration whose design meets the residual tolerance within the limits: "
        "whole periods of the slowest mode from the kinematic floor up to duration_s (and 8 beyond), refined below "
        "the first feasible one (design.duration_search_method, design.duration_bracket).",
    )
    residual_tolerance: float | None = Field(
        None,
        ge=1e-15,
        le=1e9,
        description="Residual load amplitude accepted by minimize_duration (default 1e-6 of the load's move), "
        "1e-15 to 1e9 load units.",
    )

    UNSCHEMED_RULES: ClassVar[tuple[str, ...]] = (
        "initial_exponents: order + 1 of them, each >= max(3, order + 0.05) and at least 0.05 apart.",
        "minimize_duration needs at least one limit; limits.max_torque_nm needs a two_inertia plant.",
    )

    @classmethod
    def move_rules(cls) -> list[dict[str, Any]]:
        return REST_TO_REST_ONLY

    def options(self, problem: Problem) -> PseudoPolynomialOptions:
        exponents = tuple(self.initial_exponents) if self.initial_exponents else None
        if self.duration_s is None:
            default = FAMILY.default_options(problem)
            duration, minimize = default.duration_s, default.minimize_duration or self.minimize_duration
        else:
            duration, minimize = self.duration_s, self.minimize_duration
        return PseudoPolynomialOptions(duration, self.order, exponents, minimize, self.residual_tolerance)


class BoundsOut(OutModel):
    min_exponent: float
    max_exponent: float = MAX_EXPONENT
    min_separation: float = MIN_SEPARATION


class PseudoPolynomialDesignOut(OutModel):
    order: int
    duration_s: float
    displacement: float
    exponents: list[float]
    coefficients: list[float]
    initial_exponents: list[float]
    initial_coefficients: list[float]
    final_energy_before: float = Field(description="Vibration energy left by the initial design when the move ends.")
    final_energy_after: float = Field(description="The same for the returned design.")
    energy_ratio: float = Field(description="final_energy_after / final_energy_before.")
    energy_units: str = Field(description="J for belt_platform and two_inertia; per unit load inertia otherwise.")
    residual_amplitude: float = Field(description="Load free-oscillation envelope at T, from the optimiser's model.")
    initial_residual_amplitude: float
    selection: str = Field(description="closest_zero_energy, minimum_energy or fallback (see selection_rule).")
    fallback_reason: str | None = Field(None, description="For selection 'fallback': why, and which design it is.")
    selection_rule: str
    bounds: BoundsOut
    solver: SolverOut = Field(description="Deprecated here: the same as the top-level solver.")
    duration_search: list[dict[str, Any]] | None = Field(None, description="Durations tried by minimize_duration.")
    duration_search_method: str | None = Field(None, description="How minimize_duration searched.")
    duration_bracket: dict[str, float | None] | None = Field(
        None,
        description="minimize_duration's answer: the shortest feasible duration found and the longest infeasible "
        "one tried below it (null if none), s.",
    )


class DesignRun(OutModel):
    profile: ProfileOut
    load: LoadOut
    metrics: MetricsOut


class PseudoPolynomialOut(FamilyResponse):
    design: PseudoPolynomialDesignOut  # type: ignore[assignment]
    initial: DesignRun = Field(description="The initial design's profile, load response and metrics.")
