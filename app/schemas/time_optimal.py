"""Request and response of POST /v1/profiles/time-optimal."""

from __future__ import annotations

from dataclasses import replace
from typing import Annotated, Any, ClassVar

from pydantic import Field, field_validator, model_validator

from app.schemas.common import (
    INTEGRAL,
    Cond,
    DampingRatio,
    OutModel,
    StrictModel,
    either,
    given,
    inside,
    leaf,
    limit_given,
    never,
)
from app.schemas.family import FamilyResponse, ProfileRequest
from app.settings import Settings
from models.errors import InvalidParameter
from models.plants import FREQUENCY_MAX_HZ, FREQUENCY_MIN_HZ
from optim.families.time_optimal.options import MAX_TRADEOFF, Robustness, TimeOptimalOptions
from optim.families.time_optimal.types import DEFAULT_MAX_PERCENTAGE_VIBRATION, MAX_MODES, MIN_PERCENTAGE_VIBRATION
from optim.problem import REST, MotionState, Problem
from optim.registry import FAMILIES

FAMILY = FAMILIES["time_optimal"]
MIN_RATIO, MAX_RATIO = 0.05, 20.0


def _range(value: list[float] | None, name: str, low: float, high: float) -> None:
    if value is None:
        return
    if not (low <= value[0] < value[1] <= high):
        raise ValueError(f"{name} must be [lo, hi] with {low:g} <= lo < hi <= {high:g}")


class RobustnessIn(StrictModel):
    """Robustness of the command: a band where the percentage vibration V stays <= max_percentage_vibration, or
    zero residual with zero derivatives in frequency at the nominal modes. Give at most one of
    frequency_ratio_range, frequency_range_hz and derivative_order."""

    frequency_ratio_range: list[Annotated[float, Field(ge=MIN_RATIO, le=MAX_RATIO)]] | None = Field(
        None,
        min_length=2,
        max_length=2,
        description=f"[lo, hi]: the true natural frequency over the plant's, for every cancelled mode "
        f"({MIN_RATIO:g} <= lo < hi <= {MAX_RATIO:g}); e.g. [0.9, 1.1] for +-10 %.",
    )
    frequency_range_hz: list[Annotated[float, Field(ge=FREQUENCY_MIN_HZ, le=FREQUENCY_MAX_HZ)]] | None = Field(
        None,
        min_length=2,
        max_length=2,
        description="[lo, hi] Hz: an absolute band (the damping ratio of the cancelled mode nearest to it); modes "
        "outside it keep zero residual.",
    )
    max_percentage_vibration: float = Field(
        DEFAULT_MAX_PERCENTAGE_VIBRATION,
        ge=MIN_PERCENTAGE_VIBRATION,
        le=100,
        description="V_max, %: residual amplitude over the unshaped rigid command's residual envelope (see "
        f"SensitivityOut), bounded over the whole band; at least {MIN_PERCENTAGE_VIBRATION:g} % (below it the bound "
        "is under the residual's rounding error).",
    )
    damping_ratio_range: list[DampingRatio] | None = Field(
        None,
        min_length=2,
        max_length=2,
        description="[lo, hi]: the band also holds for these true damping ratios (its ends and middle are checked); "
        "default: the mode's own.",
    )
    zero_residual_at_modes: bool = Field(
        True,
        description="With a band: also exactly zero residual at the nominal modes (default), so that the load "
        "settles when the command ends on the nominal plant; false: the band only (up to a few % shorter, "
        "leaving up to max_percentage_vibration at the nominal frequency).",
    )
    derivative_order: Annotated[int, Field(ge=1, le=2), INTEGRAL] | None = Field(
        None,
        description="Zero residual and zero derivatives in frequency up to this order at the nominal modes "
        "(1: ZVD-like, 2: ZVDD-like), instead of a band.",
    )

    UNSCHEMED_RULES: ClassVar[tuple[str, ...]] = (
        "robustness.frequency_ratio_range and robustness.frequency_range_hz are [lo, hi] with lo < hi; "
        "robustness.damping_ratio_range [lo, hi] with lo <= hi.",
    )

    @classmethod
    def schema_rules(cls) -> list[dict[str, Any]]:
        return [
            *super().schema_rules(),
            {
                "oneOf": [
                    given("frequency_ratio_range", "array").holds,
                    given("frequency_range_hz", "array").holds,
                    given("derivative_order", "integer").holds,
                ]
            },
        ]

    @model_validator(mode="after")
    def _check(self) -> RobustnessIn:
        chosen = [self.frequency_ratio_range, self.frequency_range_hz, self.derivative_order]
        if sum(v is not None for v in chosen) != 1:
            raise ValueError("give exactly one of frequency_ratio_range, frequency_range_hz or derivative_order")
        _range(self.frequency_ratio_range, "frequency_ratio_range", MIN_RATIO, MAX_RATIO)
        _range(self.frequency_range_hz, "frequency_range_hz", 1e-3, 1e5)
        if self.damping_ratio_range is not None and not (
            0.0 <= self.damping_ratio_range[0] <= self.damping_ratio_range[1] < 1.0
        ):
            raise ValueError("damping_ratio_range must be [lo, hi] with 0 <= lo <= hi < 1")
        return self

    def to_core(self) -> Robustness:
        def pair(v: list[float] | None) -> tuple[float, float] | None:
            return None if v is None else (float(v[0]), float(v[1]))

        return Robustness(
            frequency_ratio_range=pair(self.frequency_ratio_range),
            frequency_range_hz=pair(self.frequency_range_hz),
            max_percentage_vibration=self.max_percentage_vibration,
            damping_ratio_range=pair(self.damping_ratio_range),
            derivative_order=self.derivative_order or 0,
            zero_residual_at_modes=self.zero_residual_at_modes,
        )


class MotionStateIn(StrictModel):
    """The motor's motion where a move starts or ends (Ruckig's current_/target_ velocity and acceleration); the
    load is taken as quasi-static in it (it has followed that motion long enough for its vibration to have died)."""

    velocity: float = Field(
        0.0, ge=-1e9, le=1e9, description="Motor velocity (m/s or rad/s), within limits.max_velocity."
    )
    acceleration: float = Field(
        0.0,
        ge=-1e9,
        le=1e9,
        description="Motor acceleration, within limits.max_acceleration; non-zero only with limits.max_jerk.",
    )

    def to_core(self) -> MotionState:
        return MotionState(float(self.velocity), float(self.acceleration))


def _accelerating(name: str) -> Cond:
    """``<name>.acceleration`` is given and not 0."""
    return inside(name, leaf("acceleration", {"not": {"const": 0}}, {"const": 0}))


class TimeOptimalIn(ProfileRequest):
    """The shortest command within the limits that leaves no residual vibration at the plant's modes, or whose
    percentage vibration stays below max_percentage_vibration over a band of frequencies (robustness).

    The acceleration (with limits.max_jerk, the jerk) is piecewise constant: bang, coast and switch arcs. Limits:
    max_acceleration (or max_jerk, or max_torque_nm on a two_inertia plant) is needed, max_velocity and the
    others are optional; all are hard."""

    robustness: RobustnessIn | None = Field(None, description="Default: exactly zero residual at the nominal modes.")
    modes: list[Annotated[int, Field(ge=0, lt=1000), INTEGRAL]] | None = Field(
        None,
        min_length=1,
        max_length=MAX_MODES,
        description=f"Indices of the plant's modes to cancel (0 = lowest, see /v1/plants/modes). Default: every mode, "
        f"at most the lowest {MAX_MODES} (a warning says so).",
    )
    tradeoff: list[Annotated[float, Field(ge=0, lt=0.9)]] | None = Field(
        None,
        min_length=1,
        max_length=MAX_TRADEOFF,
        description="Band half-widths h (each in [0, 0.9)): the answer's tradeoff lists the minimum duration for the "
        "band [1 - h, 1 + h] of frequency ratios (h = 0: zero residual), with the same max_percentage_vibration "
        "and damping_ratio_range: what robustness costs.",
    )
    initial_state: MotionStateIn | None = Field(
        None,
        description="Where the move starts in motion (default rest): the previous move's end, so that moves chain. "
        "Only with a displacement.",
    )
    final_state: MotionStateIn | None = Field(
        None, description="Where the move ends in motion (default rest), the load's vibration zero there."
    )
    max_duration_s: float | None = Field(
        None,
        ge=1e-6,
        le=1e4,
        description="The longest command searched (default: 4 x the rigid minimum time + 20 periods of the slowest "
        "cancelled mode). Infeasible within it is proven, or reported as not found.",
    )

    @classmethod
    def schema_rules(cls) -> list[dict[str, Any]]:
        # without a bound on the acceleration the minimum-time command is impulsive: the family's not_applicable
        bound = either(limit_given("max_acceleration"), limit_given("max_jerk"), limit_given("max_torque_nm"))
        states = [
            # optim.problem.Problem._check_states: a move in motion has a displacement
            never(given("initial_state", "object"), given("target_velocity")),
            never(given("final_state", "object"), given("target_velocity")),
            # optim.problem.Problem._check_states: an acceleration at either end needs a jerk limit
            never(_accelerating("initial_state"), ~limit_given("max_jerk")),
            never(_accelerating("final_state"), ~limit_given("max_jerk")),
        ]
        return [*super().schema_rules(), bound.holds, *states]

    UNSCHEMED_RULES: ClassVar[tuple[str, ...]] = (
        "initial_state and final_state: |velocity| within limits.max_velocity, |acceleration| within "
        "limits.max_acceleration (and M / (J_M + J_L) with a torque limit); with limits.max_jerk, an end's "
        "acceleration brought to the other's no faster than the jerk allows must not carry the velocity past "
        "limits.max_velocity (a 422 infeasible).",
    )

    def to_problem(self, settings: Settings) -> Problem:
        problem = super().to_problem(settings)
        start, end = self.initial_state, self.final_state
        if start is None and end is None:
            return problem
        if not problem.rest_to_rest:  # even at rest: a ramp has its own end (the schema's rule)
            raise InvalidParameter(
                "initial_state" if start is not None else "final_state",
                "given",
                "a move that starts or ends in motion needs a displacement, not target_velocity",
            )
        return replace(
            problem,
            initial_state=start.to_core() if start is not None else REST,
            final_state=end.to_core() if end is not None else REST,
        )

    @field_validator("modes")
    @classmethod
    def _modes(cls, value: list[int] | None) -> list[int] | None:
        if value is not None and any(not (0 <= m < 1000) for m in value):
            raise ValueError("modes must be indices >= 0 (0 = the lowest mode)")
        return value

    @field_validator("tradeoff")
    @classmethod
    def _tradeoff(cls, value: list[float] | None) -> list[float] | None:
        if value is not None and any(not (0.0 <= h < 0.9) for h in value):
            raise ValueError("every tradeoff half-width must lie in [0, 0.9)")
        return value

    def options(self, problem: Problem) -> TimeOptimalOptions:
        return TimeOptimalOptions(
            robustness=None if self.robustness is None else self.robustness.to_core(),
            modes=None if self.modes is None else tuple(self.modes),
            tradeoff=None if self.tradeoff is None else tuple(float(h) for h in self.tradeoff),
            max_duration_s=self.max_duration_s,
        )


class TradeoffRow(OutModel):
    half_width: float = Field(description="h: the band [1 - h, 1 + h] of frequency ratios (0: zero residual).")
    frequency_ratio_range: list[float]
    duration_s: float | None = Field(description="The minimum duration for that band, s (null if none was found).")
    lower_bound_s: float | None = Field(description="The proven lower bound for that band, s.")
    cost_over_nominal: float | None = Field(description="duration / the h = 0 duration - 1 (when h = 0 was asked).")
    status: str = Field(description="ok, or the problem type of the failure (infeasible, solver-failed, ...).")
    reason: str | None = Field(description="Why a row has no duration.")
    from_half_width: float | None = Field(
        None,
        description="The band whose design gives this duration: a design for a wider band meets every narrower one, "
        "so a row shows the shortest of them (equal to half_width unless a wider band's design is shorter).",
    )


class TimeOptimalOut(FamilyResponse):
    tradeoff: list[TradeoffRow] | None = Field(None, description="One row per requested half-width.")


__all__ = ["FAMILY", "RobustnessIn", "TimeOptimalIn", "TimeOptimalOut", "TradeoffRow"]
