"""Input shapers under an acceleration limit: the catalogue and the input-shaped profile."""

from __future__ import annotations

from typing import ClassVar, Literal

from pydantic import Field

from app.schemas.common import OutModel
from app.schemas.family import FamilyResponse, ProfileRequest
from app.schemas.simulate import MetricsOut, ProfileOut
from models.errors import InvalidParameter
from optim.families.input_shaped import MAX_SHAPED_MODES, InputShapedOptions
from optim.family import FAMILIES
from optim.problem import MAX_MOVE, Problem
from optim.shapers import CATALOGUE_NAMES, DEFAULT_VIBRATION_TOLERANCE, MAX_DERIVATIVE_ORDER

FAMILY = FAMILIES["input_shaped"]


class InputShapedRequest(ProfileRequest):
    """A velocity step (``target_velocity``) or a rest-to-rest move (``displacement``), shaped for
    the plant's mode and kept within the drive's acceleration limit.

    The command is the motor velocity (steps and ramps); for position-input plants the motor
    position is its exact integral. A command that breaks the acceleration limit ``limits.max_acceleration``
    (on a two_inertia plant also M/(J_M + J_L) from ``limits.max_torque_nm``) is changed by the drive: for a
    velocity step its rate limiter ramps at the limit (Chatlatanagulchai Fig. 5); for a rest-to-rest move the
    drive is in position mode and its profile generator follows the shaped position reference time-optimally
    within the acceleration and velocity limits, so it arrives at the displacement. The load is simulated
    with what the drive does. A rest-to-rest move cruises at the speed, at most ``limits.max_velocity``, that
    makes it end soonest with its baseline: for a single ramp of Delta = V W / a (W the largest sum of
    amplitudes within a window of Delta; max A_i, the modified baseline, where the ramps do not overlap),
    sqrt(a |D| / W) or the end of a regime of W; the plain step cruises at ``limits.max_velocity``. The shaped
    command's peak velocity is the baseline's (positive impulses summing to 1), so it never exceeds it.
    """

    LEGACY_LIMITS: ClassVar[dict[str, str]] = {
        "acceleration_limit": "max_acceleration",
        "cruise_velocity": "max_velocity",
    }

    shaper: str = Field(
        "zvd",
        description=f"One of {', '.join(CATALOGUE_NAMES)}, or zv followed by up to {MAX_DERIVATIVE_ORDER} letters d "
        "(see GET /v1/shapers). Designed for the plant's own mode(s), damping included.",
    )
    vibration_tolerance: float = Field(
        DEFAULT_VIBRATION_TOLERANCE,
        ge=0.001,
        le=0.3,
        description="EI shapers only: the residual (fraction) allowed at the humps, 0.05 = 5 %.",
    )
    shaped_modes: Literal["first", "all"] = Field(
        "first",
        description="Shape the lowest mode, or every mode (one shaper per mode, convolved; at most "
        f"{MAX_SHAPED_MODES}).",
    )
    baseline: Literal["auto", "step", "modified", "multi_step"] = Field(
        "auto",
        description="auto: the fastest baseline (by the shaped command's end) whose shaped command meets the limits: "
        "the plain step without an acceleration limit, else the shortest single ramp (the modified baseline where "
        "its shaped ramps do not overlap, a longer ramp where they would) or, for shapers of up to 5 impulses, a "
        "multi-step baseline when it ends sooner; design.baseline says which and why. step: the plain velocity step "
        "(or pulse), which the drive's limiter distorts; modified: the paper's ramp-plus-step with "
        "Delta = a1 max|A_i| / a (Sec. 4), refused where its ramps would overlap; multi_step: steps at the first "
        "impulse times (Fig. 10), by the paper's relations where they hold (ZV) and otherwise the fastest valid "
        "steps. modified and multi_step need an acceleration limit.",
    )
    baseline_steps: int = Field(2, ge=1, le=32, description="multi_step only: the number of steps (<= impulse count).")
    cruise_velocity: float | None = Field(
        None, gt=0, le=MAX_MOVE, deprecated="cruise_velocity is deprecated: use limits.max_velocity (same meaning)"
    )
    acceleration_limit: float | None = Field(
        None, gt=0, le=1e12, deprecated="acceleration_limit is deprecated: use limits.max_acceleration (same meaning)"
    )

    def _legacy_move(
        self, updates: dict[str, float], notes: list[str], aliases: dict[str, str]
    ) -> tuple[float | None, float | None]:
        cruise = self.__dict__.get("cruise_velocity")
        if self.target_velocity is not None and cruise is not None:
            raise InvalidParameter("cruise_velocity", cruise, "applies to a rest-to-rest move (displacement) only")
        return self.displacement, self.target_velocity

    def options(self, problem: Problem) -> InputShapedOptions:
        return InputShapedOptions(
            self.shaper, self.vibration_tolerance, self.shaped_modes, self.baseline, self.baseline_steps
        )


class ImpulsesOut(OutModel):
    amplitudes: list[float] = Field(description="A_i: they sum to 1 (eq. 6).")
    times_s: list[float] = Field(description="t_i, s; t_1 = 0 (eq. 7).")


class InputShapedResponse(FamilyResponse):
    """``profile`` is the shaped command sent to the drive (v_s); ``rate_limited`` is what the drive
    makes of it (v_a), which ``load`` and ``metrics`` simulate; ``unmodified`` gives the metrics of
    the plain shaped step (or pulse) after the limiter, for comparison."""

    impulses: ImpulsesOut
    ramp_time_s: float | None = Field(description="Delta, the baseline's ramp rise time (null for the step baseline).")
    baseline: ProfileOut = Field(description="The baseline command v_b, before shaping.")
    rate_limited: ProfileOut = Field(description="v_a: the shaped command after the drive's acceleration limit.")
    unmodified: MetricsOut = Field(description="Metrics of the plain shaped step (or pulse) after the limiter.")


class ShaperInfo(OutModel):
    name: str
    impulse_count: int
    duration_periods: float = Field(description="t_n in damped periods of the design mode.")
    band_5_percent: list[float | None] | None = Field(
        description="[low, high] ratios of true to design natural frequency where the residual V stays <= 5 %, "
        "computed from V (Sec. 3.1); null if V exceeds 5 % at the design frequency."
    )
    band_width: float | None = Field(description="high - low: the 5 % insensitivity.")
    amplitudes: list[float]
    times_periods: list[float] = Field(description="t_i in damped periods of the design mode.")
    method: str
    reference: str


class UnavailableShaper(OutModel):
    name: str
    reason: str


class ShaperCatalogue(OutModel):
    damping_ratio: float = Field(description="Damping ratio the shapers are designed for (and evaluated at).")
    vibration_tolerance: float = Field(description="Tolerance of the EI shapers.")
    band_threshold: float = Field(description="Residual threshold of the bands (0.05 = 5 %).")
    shapers: list[ShaperInfo]
    unavailable: list[UnavailableShaper] = Field(
        description="EI shapers whose defining conditions have no solution at this damping and tolerance."
    )
