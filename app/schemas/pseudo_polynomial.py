"""Request and response of POST /v1/profiles/pseudo-polynomial."""

from __future__ import annotations

from typing import Any

from pydantic import Field

from app.schemas.common import OutModel, StrictModel
from app.schemas.family import LimitsIn, SensitivityIn, SensitivityOut
from app.schemas.plants import PlantIn
from app.schemas.simulate import LoadOut, MetricsOut, ProfileOut
from optim.pseudo_polynomial import MAX_EXPONENT, MAX_ORDER, MIN_SEPARATION

SELECTION_RULE = (
    "Zero final energy is two equations per mode in order + 1 exponents, so for order >= 2 the zero-energy "
    "designs form a curve (or a surface). The design returned is the zero-energy design closest to the "
    "initial exponents that IPOPT reaches from them (selection 'closest_zero_energy'). If none meets the "
    "limits, the energy is minimised from the initial exponents and six fixed spread starts and the "
    "lowest-energy design within the limits is returned (selection 'minimum_energy', energy_ratio > 0)."
)


class PseudoPolynomialIn(StrictModel):
    """A rest-to-rest move phi(t) = Phi [1 - sum C_i (1 - t/T)^gamma_i] (Incerti eq. 17) whose exponents
    are chosen by IPOPT to leave no vibration energy when the move ends (eqs. 24-31).

    Exponents are kept in [max(3, order + 0.05), 80] (above the order so the end conditions hold, at least 3
    so the jerk stays bounded) and at least 0.05 apart (eq. 22 stays well conditioned)."""

    plant: PlantIn
    displacement: float = Field(description="Phi: motor displacement, rad or m (15 rev = 30 pi rad in Table III).")
    duration_s: float = Field(gt=0, le=1e5, description="Motion time T, s.")
    order: int = Field(
        2, ge=1, le=MAX_ORDER, description="n: derivatives up to n are null at both ends (n + 1 exponents)."
    )
    initial_exponents: list[float] | None = Field(
        None, description="Starting exponents; default n+1, ..., 2n+1, the classical polynomial ((3, 4, 5) for n = 2)."
    )
    limits: LimitsIn = Field(default_factory=LimitsIn)
    sample_period_s: float = Field(1e-3, ge=1e-6, le=10, description="Sample period of the returned profile, s.")
    horizon_s: float | None = Field(
        None, gt=0, le=1e6, description="End of the returned samples, s (default: the move plus 5 periods of the mode)."
    )
    minimize_duration: bool = Field(
        False,
        description="Search the shortest duration (from duration_s down) whose design meets the residual tolerance within the limits.",
    )
    residual_tolerance: float | None = Field(
        None,
        gt=0,
        description="Residual load amplitude accepted by minimize_duration (default 1e-6 of the load's displacement).",
    )
    settling_tolerance: float = Field(1e-3, gt=0, le=1, description="Settling band as a fraction of the displacement.")
    sensitivity: SensitivityIn | None = None


class SolverOut(OutModel):
    status: str = Field(description="IPOPT's return status of the solve that produced the design.")
    iterations: int = Field(description="IPOPT iterations over all solves.")
    solve_time_s: float = Field(description="Wall time of the design, s.")
    solves: int


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
    selection: str = Field(description="closest_zero_energy or minimum_energy (see selection_rule).")
    selection_rule: str
    bounds: BoundsOut
    solver: SolverOut
    duration_search: list[dict[str, Any]] | None = Field(None, description="Durations tried by minimize_duration.")


class DesignRun(OutModel):
    profile: ProfileOut
    load: LoadOut
    metrics: MetricsOut


class PseudoPolynomialOut(OutModel):
    profile: ProfileOut
    design: PseudoPolynomialDesignOut
    load: LoadOut
    metrics: MetricsOut
    initial: DesignRun = Field(description="The initial design's profile, load response and metrics.")
    sensitivity: SensitivityOut | None = None
    warnings: list[str]
