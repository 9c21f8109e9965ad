"""Request and response of POST /v1/profiles/stap (Cusimano 2022)."""

from __future__ import annotations

import math
from typing import Annotated, Any, ClassVar, Literal

from pydantic import Field, field_validator

from app.schemas.common import (
    DampingRatio,
    Int,
    OutModel,
    StrictModel,
    both,
    either,
    given,
    is_value,
    limit_given,
)
from app.schemas.family import FamilyResponse, ProfileRequest, SensitivityOut, SolverOut
from models.errors import InvalidParameter
from optim.families.stap import (
    DEFAULT_FREQUENCY_UNCERTAINTY,
    DEFAULT_RESIDUAL_TOLERANCE,
    MAX_BAND_DAMPING_RATIOS,
    MAX_FREQUENCY_POINTS,
    OBJECTIVES,
)
from optim.families.stap.family import AUTO_RULE, StapOptimization, StapOptions
from optim.problem import MIN_LIMIT, Problem
from optim.registry import FAMILIES

MAX_JERK_PERIODS = 10_000
FAMILY = FAMILIES["stap"]


class OptimizationIn(StrictModel):
    """Options of method 'optimized' (a CasADi/IPOPT problem over t_a and t_j)."""

    objective: Literal["residual", "worst_case", "residual_and_time"] = Field(
        "residual",
        description="residual: minimise the residual at the plant's own modes, t_a fixed (acceleration_time_s or the "
        "closed-form t_a); worst_case: minimise the largest residual over the frequency band and damping ratios, t_a "
        "fixed; residual_and_time: the shortest t_a whose residual stays <= residual_tolerance over the band.",
    )
    damping_ratios: list[DampingRatio] | None = Field(
        None,
        min_length=1,
        max_length=MAX_BAND_DAMPING_RATIOS,
        description="Damping ratios of the band (worst_case, residual_and_time); default: the plant's own.",
    )
    frequency_points: Int = Field(
        21, ge=3, le=MAX_FREQUENCY_POINTS, description="Frequency ratios of the band grid, uniform over [1 - u, 1 + u]."
    )

    @field_validator("damping_ratios")
    @classmethod
    def _zetas(cls, value: list[float] | None) -> list[float] | None:
        if value is not None and any(not (0.0 <= z < 1.0) for z in value):
            raise ValueError("every damping ratio must satisfy 0 <= zeta < 1")
        return value


class StapIn(ProfileRequest):
    """A symmetric trapezoidal acceleration profile (Cusimano 2022): rest to ``target_velocity``, or a
    rest-to-rest move of ``displacement`` made of an accelerating STAP, a cruise at ``limits.max_velocity``
    (default: the fastest move, with no cruise; lowered if the displacement is too short) and a decelerating STAP.

    The acceleration limit is ``limits.max_acceleration``; on a two_inertia plant ``limits.max_torque_nm`` gives
    a_Max = M/(J_M + J_L) (eq. 19), lowered by the torque oscillation of eqs. (57)-(59) over the frequency band,
    and lowered further where the real torque J_M a_M + J_L a_L (damping, a short t_c, the other ramp of a move)
    would still exceed M: the product departs from the paper there, and checks the exact peak of every design.
    The plant's first vibration mode is the estimate f_n,e the STAP is designed for. The closed-form rules assume
    zeta = 0 (Sec. 2.3); method 'optimized' accounts for damping and frequency uncertainty."""

    LEGACY_LIMITS: ClassVar[dict[str, str]] = {"max_acceleration": "max_acceleration", "max_torque_nm": "max_torque_nm"}

    jerk_periods: Annotated[int, Field(ge=0, le=MAX_JERK_PERIODS)] | Literal["auto"] = Field(
        "auto",
        description="k_j: t_j = (k_j + delta dec(f_n,e t_a))/f_n,e (eqs. 44, 49); 'auto' applies the flowchart "
        "(see design.rule).",
    )
    delta: Int = Field(
        0, ge=0, le=1, description="delta of eq. (44): 1 takes the side band (needs acceleration_time_s)."
    )
    acceleration_time_s: float | None = Field(
        None,
        ge=1e-6,
        le=1e6,
        description="A caller-fixed t_a (>= t_a,min and >= 1/f_n,e, eq. 72); its zero-vibration jerk times are listed.",
    )
    method: Literal["closed_form", "optimized"] = Field(
        "closed_form",
        description="closed_form: the paper's rules; optimized: CasADi/IPOPT over (t_a, t_j), started from the closed "
        "form and returning it (design.optimization.selection = closed_form_kept, with a warning) when no solve "
        "meets the limits and beats it: a failed, timed-out or locally infeasible solve is never the answer.",
    )
    frequency_uncertainty: float = Field(
        DEFAULT_FREQUENCY_UNCERTAINTY,
        ge=0,
        le=0.9,
        description="u: the true f_n may lie in [1 - u, 1 + u] f_n,e. Used by auto, the torque rule and the "
        "worst_case/residual_and_time objectives.",
    )
    residual_tolerance: float = Field(
        DEFAULT_RESIDUAL_TOLERANCE,
        ge=1e-12,
        le=1,
        description="Residual vibration accepted over the band, a fraction of the move ('a few hundredths', Sec. 3).",
    )
    optimization: OptimizationIn | None = Field(None, description="Options of method 'optimized'.")
    max_acceleration: float | None = Field(
        None,
        ge=MIN_LIMIT,
        le=1e12,
        deprecated="max_acceleration is deprecated: use limits.max_acceleration (same meaning)",
    )
    max_torque_nm: float | None = Field(
        None, ge=MIN_LIMIT, le=1e12, deprecated="max_torque_nm is deprecated: use limits.max_torque_nm (same meaning)"
    )

    @field_validator("jerk_periods", mode="before")
    @classmethod
    def _jerk_periods(cls, value: Any) -> Any:
        if value == "auto":
            return value
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not math.isfinite(value)
            or value != int(value)
        ):
            raise ValueError("must be a whole number k_j >= 0 or 'auto'")
        if not 0 <= value <= MAX_JERK_PERIODS:
            raise ValueError(f"must lie in 0..{MAX_JERK_PERIODS} or be 'auto'")
        return int(value)

    MOVE_FIELD: ClassVar[str] = "target_velocity"
    # Rules kept out of the schema: schemathesis' generator (jsonschema_rs' canonical form) gives up on an
    # operation whose rules between fields multiply to more than about 100 alternatives ("UnsupportedSchema"; the
    # acceleration rule alone has 5), so the schema keeps those the fuzz met most and describes the others.
    UNSCHEMED_RULES: ClassVar[tuple[str, ...]] = (
        "target_velocity beside a displacement (deprecated: the cruise speed) must have the displacement's sign, "
        "and equal limits.max_velocity when that is given.",
        "max_torque_nm (deprecated: limits.max_torque_nm) needs a two_inertia plant.",
        "optimization applies to method optimized only.",
    )

    @classmethod
    def move_rules(cls) -> list[dict[str, Any]]:
        """displacement, target_velocity, or both (deprecated: target_velocity is then the cruise speed)."""
        return [either(given("displacement"), given("target_velocity")).holds]

    @classmethod
    def schema_rules(cls) -> list[dict[str, Any]]:
        # (k_j, delta) = (0, 0) is no zero of eq. (44); a side band (delta = 1) needs a whole k_j
        # (optim.families.stap.check_request) and t_a (eq. 49, optim.families.stap.ramp): one rule of two alternatives
        fundamental = both(is_value("delta", 0, default=True), ~is_value("jerk_periods", 0))
        side_band = both(
            is_value("delta", 1), ~is_value("jerk_periods", "auto", default=True), given("acceleration_time_s")
        )
        return [
            *super().schema_rules(),
            either(fundamental, side_band).holds,
            # a STAP is designed from the acceleration limit (the family's design: not applicable without one)
            either(
                limit_given("max_acceleration"),
                limit_given("max_torque_nm"),
                given("acceleration_time_s"),
                given("max_acceleration"),
                given("max_torque_nm"),
            ).holds,
        ]

    def _legacy_move(
        self, updates: dict[str, float], notes: list[str], aliases: dict[str, str]
    ) -> tuple[float | None, float | None]:
        """The old body gave the cruise speed as target_velocity beside the displacement."""
        if self.displacement is None or self.target_velocity is None:
            return self.displacement, self.target_velocity
        if self.displacement * self.target_velocity < 0:
            raise InvalidParameter(
                "target_velocity", self.target_velocity, "the cruise speed must have the displacement's sign"
            )
        current = self.limits.max_velocity
        if current is not None and current != abs(self.target_velocity):
            raise InvalidParameter(
                "target_velocity",
                self.target_velocity,
                "is the cruise speed here and disagrees with limits.max_velocity",
            )
        updates["max_velocity"] = abs(self.target_velocity)
        notes.append(
            "target_velocity beside a displacement is deprecated: give the cruise speed as limits.max_velocity"
        )
        aliases["limits.max_velocity"] = "target_velocity"
        return self.displacement, None

    def options(self, problem: Problem) -> StapOptions:
        if self.optimization is not None and self.method != "optimized":
            raise InvalidParameter("optimization", "given", "applies to method 'optimized' only")
        opt = self.optimization
        return StapOptions(
            jerk_periods=self.jerk_periods,
            delta=self.delta,
            acceleration_time_s=self.acceleration_time_s,
            method=self.method,
            frequency_uncertainty=self.frequency_uncertainty,
            residual_tolerance=self.residual_tolerance,
            optimization=None
            if opt is None
            else StapOptimization(
                opt.objective, tuple(opt.damping_ratios) if opt.damping_ratios else None, opt.frequency_points
            ),
        )


class TorqueLimitOut(OutModel):
    max_torque_nm: float
    nodal_acceleration_limit: float = Field(description="M/(J_M + J_L) (eq. 19).")
    nodal_min_acceleration_time_s: float = Field(description="v / nodal limit (eq. 21 with eq. 19).")
    inertia_ratio: float = Field(description="J_L / J_M.")
    coefficient: float = Field(description="(J_L/J_M)/(1 + J_L/J_M) (Fig. 19).")
    load_acceleration_oscillation: float = Field(description="Worst |a_l,c|/a_max over the band (eq. 57).")
    torque_overshoot: float = Field(description="Worst |M_m,c|/M_m,max over the band (eq. 59).")
    worst_frequency_ratio: float = Field(description="f_n/f_n,e where it occurs.")
    factor: float = Field(description="1/(1 + torque_overshoot): the lowered limit over the nodal one.")
    acceleration_limit: float = Field(description="The lowered acceleration limit.")
    peak_torque_nm: float | None = Field(
        None,
        description="Exact peak of the real motor torque J_M a_M + J_L a_L of the returned closed-form command, over "
        "all time (eqs. 19 and 57-59 bound only the rigid part and one undamped ramp; this is simulated).",
    )
    lowered_acceleration_limit: float | None = Field(
        None,
        description="Where the eq. (57)-(59) design's real torque peak broke max_torque_nm: the acceleration cap, "
        "found by a 1-D search on the exact peak, under which the returned design was made; null when not needed.",
    )


class StapCandidateOut(OutModel):
    k_j: int
    delta: int
    jerk_time_s: float
    kind: Literal["fundamental", "multiple", "side_band"]
    peak_acceleration: float
    acceleration_limit: float | None
    reaches_limit: bool
    note: str


class AutoStepOut(OutModel):
    what: str
    acceleration_time_s: float
    jerk_time_s: float
    band_worst_residual: float = Field(description="Largest undamped SC (Appendix B) over the band.")
    meets: bool


class StartOut(OutModel):
    acceleration_time_s: float
    jerk_time_s: float
    nominal_residual: float
    grid_worst_residual: float | None


class OptimizationOut(OutModel):
    objective: str
    selection: Literal["optimized", "closed_form_kept"] = Field(
        description="closed_form_kept when no solve met the limits and improved on the closed-form start (it is "
        "then returned, with a warning)."
    )
    nominal_residual: float = Field(
        description="Sum over the plant's modes of residual / the load's move (the optimiser's model)."
    )
    grid_worst_residual: float | None = Field(
        description="Largest residual / move over the optimiser's band grid (unit-gain modes)."
    )
    closed_form: StartOut = Field(description="The closed-form design the optimiser started from.")
    acceleration_time_bounds_s: list[float]
    jerk_time_floor_s: float
    torque_constrained: bool
    solver: SolverOut


class StapDesignOut(OutModel):
    method: Literal["closed_form", "optimized"]
    move: Literal["rest_to_velocity", "rest_to_rest"]
    rule: str = Field(description="The rule (equation) that produced t_a and t_j.")
    auto_rule: str = AUTO_RULE
    estimated_frequency_hz: float = Field(description="f_n,e: the plant's first mode.")
    target_velocity: float = Field(
        description="v_max reached by the ramp (the cruise velocity of a rest-to-rest move)."
    )
    acceleration_time_s: float = Field(description="t_a.")
    jerk_time_s: float = Field(description="t_j.")
    constant_acceleration_time_s: float = Field(description="t_c = t_a - 2 t_j.")
    min_acceleration_time_s: float | None = Field(
        description="t_a,min = v/a_Max (eq. 21) for the a_Max used; null without a limit."
    )
    peak_acceleration: float = Field(description="|a_max| = |v|/(t_a - t_j) (eq. 11; eq. 31 for a triangle).")
    peak_jerk: float | None = Field(description="|v|/(t_j (t_a - t_j)) (eq. 16); null for a rectangle.")
    shape: Literal["trapezoid", "triangle", "rectangle"]
    k_j: int | None = Field(description="k_j of eq. (44) (null for an optimised design).")
    delta: int | None = Field(description="delta of eq. (44) (null for an optimised design).")
    jerk_periods: float = Field(description="f_n,e t_j = k_j + delta dec(f_n,e t_a) (eqs. 51-52).")
    acceleration_time_periods: float = Field(description="r_n,a = f_n,e t_a (eq. 40).")
    dimensionless_jerk_time: float = Field(description="t_j / t_a (eq. 12).")
    acceleration_limit: float | None = Field(description="a_Max used (null without a limit).")
    limit_reached: bool = Field(description="Whether the peak acceleration equals a_Max.")
    torque_limit: TorqueLimitOut | None = None
    load_acceleration_oscillation: float = Field(
        description="|a_l,c|/a_max during t_c at f_n = f_n,e (eq. 57 with k_j = f_n,e t_j): 0 for whole k_j."
    )
    frequency_uncertainty: float
    residual_tolerance: float
    band_worst_residual: float = Field(description="Largest undamped SC (Appendix B) over [1 - u, 1 + u].")
    candidates: list[StapCandidateOut] | None = Field(
        None, description="With acceleration_time_s: the zero-vibration jerk times that fit (eqs. 44, 49), marked."
    )
    candidates_truncated: bool | None = None
    k_j_max: int | None = Field(None, description="(k_j, delta) of the last zero that fits, by enumeration.")
    delta_f: int | None = None
    paper_k_j_max: int | None = Field(None, description="Eq. (45) as printed.")
    paper_delta_f: int | None = Field(None, description="Eq. (46) as printed.")
    auto_steps: list[AutoStepOut] | None = Field(None, description="What auto tried, in order.")
    displacement: float | None = None
    cruise_velocity: float | None = None
    cruise_time_s: float | None = None
    duration_s: float = Field(description="t_a for rest-to-velocity; 2 t_a + t_cruise for rest-to-rest.")
    total_time_s: float = Field(description="Deprecated: the same as duration_s.")
    requested_velocity: float | None = None
    velocity_lowered: bool | None = None
    residual_vibration: float = Field(
        description="The load's residual vibration amplitude after the command (velocity for rest-to-velocity, "
        "position for rest-to-rest; metrics.residual_velocity_amplitude or metrics.residual_amplitude, the returned "
        "samples simulated on the plant) as a fraction of the load's move: |G(0) target_velocity| or "
        "|G(0) displacement| (the motor's move times the plant's static gain, e.g. lambda for belt_platform)."
    )
    optimization: OptimizationOut | None = None


class StapSensitivityOut(SensitivityOut):
    method: list[Literal["appendix_b", "free_state"]] = Field(
        description="Per damping ratio: the closed form of Appendix B (zeta = 0, rest-to-velocity) or the exact free "
        "state of the command (models.sensitivity)."
    )


class StapOut(FamilyResponse):
    design: StapDesignOut  # type: ignore[assignment]
    sensitivity: StapSensitivityOut | None = None


__all__ = ["AUTO_RULE", "OBJECTIVES", "OptimizationIn", "StapDesignOut", "StapIn", "StapOut"]
