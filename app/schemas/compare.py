"""The request and answer of POST /v1/compare: one plant, one move, one set of limits; a row per design."""

from __future__ import annotations

from typing import Any, ClassVar, Literal

from pydantic import Field

from app.family_names import FamilyName
from app.schemas.common import OutModel
from app.schemas.family import ProfileRequest, SensitivityIn, SensitivityOut
from app.schemas.simulate import ClosedLoopLoadOut, LoadOut, ProfileOut, SaturationOut
from app.schemas.stap import StapSensitivityOut
from optim.families.pseudo_polynomial.family import PseudoPolynomialOptions
from optim.problem import Problem

DEFAULT_SENSITIVITY = SensitivityIn(min_ratio=0.5, max_ratio=1.5, count=201)


class CompareIn(ProfileRequest):
    """One plant, one move (displacement for rest-to-rest, or target_velocity) and one set of limits, with the
    sampling, settling band and sensitivity grid every family is run with (sensitivity default: 0.5..1.5, 201
    ratios, for the 5 % band)."""

    duration_s: float | None = Field(
        None,
        ge=1e-6,
        le=1e5,
        description="Duration of the pseudo-polynomial move (default: the shortest within the limits).",
    )
    families: list[FamilyName] | None = Field(None, min_length=1, description="Run only these families (default: all).")
    include_curves: bool = Field(False, description="Add each design's profile, load response and sensitivity curve.")

    UNSCHEMED_RULES: ClassVar[tuple[str, ...]] = ("plant: at least one vibration mode to design against.",)

    def options(self, problem: Problem) -> dict[str, Any]:
        if self.duration_s is None:
            return {}
        return {"pseudo_polynomial": PseudoPolynomialOptions(duration_s=self.duration_s)}


class Curves(OutModel):
    profile: ProfileOut
    load: LoadOut
    # a STAP row's sensitivity also says which method computed each curve
    sensitivity: SensitivityOut | StapSensitivityOut | None
    closed_loop_load: ClosedLoopLoadOut | None = Field(None, description="With ``drive``: the load through it.")


class ClosedLoopRow(OutModel):
    """A row's command through the request's ``drive`` (the ``closed_loop`` block of /v1/profiles/*, summed up)."""

    settling_time_s: float | None = Field(description="The load's settling through the drive; null if never.")
    residual_amplitude: float = Field(description="Its free-oscillation envelope (velocity for rest-to-velocity).")
    residual_vibration: float = Field(description="The same, fraction of the load's move.")
    saturated: bool = Field(description="The command drives the motor past a torque or voltage limit.")
    saturation: list[SaturationOut]
    simulation: Literal["linear", "limited"] = Field(description="As the closed_loop block's (ClosedLoopOut).")


class Row(OutModel):
    family: FamilyName
    label: str = Field(description="The design: the family, and the variant where it offers several (input_shaped/zv).")
    endpoint: str = Field(description="The family endpoint; POST `request` there to get this design.")
    request: dict[str, Any] = Field(description="The request that reproduces this row at `endpoint`.")
    motion_time_s: float = Field(description="Until the command's last change.")
    settling_time_s: float | None = Field(
        description="From the start, the earliest time after which the load stays within settling.position_tolerance "
        "and its vibration envelope below settling.vibration_tolerance for ever; null if never."
    )
    settling_window: float = Field(description="The position band settling needs, load units.")
    settling_vibration_window: float | None = Field(
        description="The bound on the load's vibration envelope settling needs, load units."
    )
    percentage_vibration: float | None = Field(
        description="V at the nominal mode, %: the residual over the unshaped rigid command's (see /v1/profiles/*)."
    )
    residual_vibration: float = Field(
        description="Residual left by every mode of the plant (their envelopes summed), fraction of the load's move."
    )
    residual_amplitude: float = Field(
        description="Load free-oscillation envelope (position; velocity for rest-to-velocity)."
    )
    band_5_percent: list[float | None] | None = Field(
        description="f_n/f_n,e range around 1 where the percentage vibration V stays <= 5 % (evaluated on 0.5..1.5; "
        "an end is null where the band runs past that range)."
    )
    peak_velocity: float | None
    peak_acceleration: float | None
    peak_jerk: float | None
    peak_motor_torque_nm: float | None
    limits_met: bool
    limit_violations: list[str]
    warnings: list[str]
    curves: Curves | None = None
    closed_loop: ClosedLoopRow | None = Field(None, description="With ``drive``: this design through the drive.")


class Unavailable(OutModel):
    family: FamilyName
    reason: str
    problem_type: str | None = Field(None, description="The problem type the family's endpoint answers with.")


class CompareOut(OutModel):
    move: Literal["rest_to_rest", "rest_to_velocity"]
    rows: list[Row] = Field(
        description="Sorted by settling time (never-settling designs last; with ``drive``, the closed loop's), then "
        "motion time. A family offering "
        "several variants (shapers) has a row per variant; of alternatives (closed form or optimized, filter kinds) "
        "only the one that settles first."
    )
    unavailable: list[Unavailable]
