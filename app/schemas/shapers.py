"""Input shapers under an acceleration limit: the catalogue and the input-shaped profile."""

from __future__ import annotations

from typing import Any, ClassVar, Literal

from pydantic import ConfigDict, Field

from app.schemas.common import Int, OutModel, given, limit_given, never
from app.schemas.family import FamilyResponse, ProfileRequest
from app.schemas.simulate import MetricsOut, ProfileOut
from models.errors import InvalidParameter
from optim.families.input_shaped.firmware import KLIPPER_VERSION, MARLIN_VERSION, RRF_VERSION
from optim.families.input_shaped.options import MAX_SHAPED_MODES, MAX_SHAPED_RAMPS, InputShapedOptions
from optim.families.input_shaped.shapers import (
    CATALOGUE_NAMES,
    DEFAULT_VIBRATION_TOLERANCE,
    EI_HUMPS,
    MAX_DERIVATIVE_ORDER,
)
from optim.problem import MAX_MOVE, MIN_LIMIT, Problem
from optim.registry import FAMILIES

FAMILY = FAMILIES["input_shaped"]


def _any_case(word: str) -> str:
    return "".join(f"[{c}{c.upper()}]" if c.isalpha() else c for c in word)


# The names optim.families.input_shaped.shapers accepts (after strip and lower): zv and up to MAX_DERIVATIVE_ORDER
# letters d, mzv, the EIs.
SHAPER_PATTERN = (
    rf"^\s*(?:{_any_case('zv')}{_any_case('d')}{{0,{MAX_DERIVATIVE_ORDER}}}|"
    + "|".join(_any_case(name) for name in ("mzv", *EI_HUMPS))
    + r")\s*$"
)


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
        "(see GET /v1/shapers), in any case. Designed for the plant's own mode(s), damping included.",
        json_schema_extra={"pattern": SHAPER_PATTERN},
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
    baseline_steps: Int = Field(2, ge=1, le=32, description="multi_step only: the number of steps (<= impulse count).")
    cruise_velocity: float | None = Field(
        None,
        ge=MIN_LIMIT,
        le=MAX_MOVE,
        deprecated="cruise_velocity is deprecated: use limits.max_velocity (same meaning)",
    )
    acceleration_limit: float | None = Field(
        None,
        ge=MIN_LIMIT,
        le=1e12,
        deprecated="acceleration_limit is deprecated: use limits.max_acceleration (same meaning)",
    )

    UNSCHEMED_RULES: ClassVar[tuple[str, ...]] = (
        "baseline modified and multi_step need an acceleration limit (limits.max_acceleration, or "
        "limits.max_torque_nm on a two_inertia plant).",
        "baseline_steps: at most the shaper's impulse count; the impulses (of every shaped mode) times the steps: "
        f"at most {MAX_SHAPED_RAMPS} ramps.",
        f"shaped_modes all: at most {MAX_SHAPED_MODES} modes.",
    )

    @classmethod
    def schema_rules(cls) -> list[dict[str, Any]]:
        # cruise_velocity (deprecated limits.max_velocity) is the cruise of a rest-to-rest move: ``_legacy_move``
        return [
            *super().schema_rules(),
            never(given("target_velocity"), given("cruise_velocity")),
            never(limit_given("max_jerk")),  # shaped steps make the jerk impulsive: the family's not_applicable
            # a rest-to-rest move cruises at limits.max_velocity where no acceleration limit bounds it (its cruise)
            never(
                given("displacement"),
                *(
                    ~cond
                    for cond in (
                        limit_given("max_velocity"),
                        given("cruise_velocity"),
                        limit_given("max_acceleration"),
                        given("acceleration_limit"),
                        limit_given("max_torque_nm"),
                    )
                ),
            ),
        ]

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


_EXACT = (
    "True where the firmware's impulses are the designed ones (amplitudes to 1e-7, times to 1e-7 of the duration; "
    "numbers are written to 10 significant digits)."
)
_RESIDUAL = (
    "Percentage vibration, %, that the firmware's shaper leaves at the design frequency (the plant's first mode, "
    "its damping): this design's baseline shaped by the firmware's impulses, over the unshaped rigid command, the "
    "definition of metrics.percentage_vibration and sensitivity.percentage_vibration (where that is not "
    "representable, shaper_residual_percent)."
)
_SHAPER_RESIDUAL = "100 V of the firmware's impulses alone (Sec. 3.1), %: the percentage vibration on a plain step."
_OTHERS = "Multi-mode designs: 100 V of the firmware's impulses at each further designed mode, %."


class _FirmwareTargetOut(OutModel):
    """What every firmware's block says of its shaper against the design."""

    exact: bool = Field(description=_EXACT)
    residual_percent: float = Field(description=_RESIDUAL)
    shaper_residual_percent: float = Field(description=_SHAPER_RESIDUAL)
    other_modes_shaper_residual_percent: list[float] = Field(description=_OTHERS)


class KlipperOut(_FirmwareTargetOut):
    """Klipper's ``[input_shaper]`` section for the X axis."""

    firmware: Literal["Klipper"]
    version: str = Field(description=f"The Klipper whose shaper definitions this uses: {KLIPPER_VERSION}.")
    documentation: list[str] = Field(description="The configuration reference and the shaper definitions used.")
    axis: Literal["x"] = Field(description="The lines set the X axis; for Y write them with _y.")
    shaper_type: str = Field(
        description="Klipper's built-in type: the design's own where Klipper has it (zv, mzv, zvd, ei, 2hump_ei, "
        "3hump_ei), else the one whose V curve over 0.25..1.75 f_n is nearest."
    )
    shaper_freq_hz: float = Field(description="shaper_freq_x: the design mode's undamped natural frequency, Hz.")
    damping_ratio: float = Field(
        description="damping_ratio_x: the design mode's (always written: Klipper's default is 0.1), capped at the "
        "type's maximum (ei 0.4, 2hump_ei 0.3, 3hump_ei 0.2)."
    )
    section: str = Field(description="The text to paste into printer.cfg.")
    note: str | None = Field(description="Why the type or its impulses differ from the design; null where not.")


class RepRapFirmwareOut(_FirmwareTargetOut):
    """RepRapFirmware's ``M593``; one shaper for all axes."""

    firmware: Literal["RepRapFirmware"]
    version: str = Field(description=f"{RRF_VERSION}: the meaning of H and T changed in 3.6.0.")
    documentation: list[str] = Field(description="The G-code dictionary's M593 and the firmware source read.")
    shaper_type: str = Field(
        description="A named type (zvd, zvdd, zvddd, mzv, ei2, ei3) where RRF's impulses are the design's, else "
        '"custom" with the design\'s own impulses (at most 5), else the nearest named type.'
    )
    frequency_hz: float = Field(description="F: the design mode's undamped natural frequency, Hz.")
    damping_ratio: float = Field(description="S: the design mode's damping ratio (M593 takes 0 to 0.99).")
    command: str = Field(
        description='For RRF 3.6: P"custom" with H the individual amplitudes of every impulse but the last (RRF sets '
        "the last to 1 minus their sum) and T the cumulative delays of every impulse but the first, s."
    )
    command_3_5: str = Field(
        description='For RRF 3.4 and 3.5: P"custom" with H the cumulative amplitudes and T the durations between '
        "impulses, s; a named type is the same command."
    )
    note: str | None = Field(description="Why the type or its impulses differ from the design; null where not.")


class MarlinOut(_FirmwareTargetOut):
    """Marlin's ``M493`` (Fixed-Time Motion) for the X axis."""

    firmware: Literal["Marlin"]
    version: str = Field(description=f"{MARLIN_VERSION}.")
    documentation: list[str] = Field(description="The M493 page and the shaper definitions read.")
    axis: Literal["x"] = Field(description="The X flag: A, I and Q apply to X (write Y for the Y axis).")
    shaper_mode: int = Field(description="C: 1 ZV, 2 ZVD, 3 ZVDD, 4 ZVDDD, 5 EI, 6 2HEI, 7 3HEI, 8 MZV.")
    frequency_hz: float = Field(description="A: the design mode's undamped natural frequency, Hz.")
    damping_ratio: float = Field(description="I: the design mode's damping ratio, within M493's [0.01, 1].")
    vibration_tolerance: float | None = Field(description="Q: the EI types' tolerance (the design's); null otherwise.")
    command: str = Field(description="The G-code line (S1 turns Fixed-Time Motion on), FTM V2 (M493 V answers FTM V2).")
    command_v1: str = Field(
        description="The same for a build before FTM V2 (Oct 2025; M493 V unknown): X<mode> selects X's shaper, "
        "A, I and Q are X's (M493.cpp at 485fbf20, 2025-01-28)."
    )
    note: str | None = Field(description="What differs from the design: the 1 ms delay grid, the damping bound.")


class FirmwareOut(OutModel):
    """The designed shaper as firmware settings (input-shaped designs only; other families have no firmware
    block)."""

    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={
            "examples": [
                {
                    "axis": "x",
                    "design_frequency_hz": 40.0,
                    "design_damping_ratio": 0.0,
                    "klipper": {
                        "firmware": "Klipper",
                        "version": KLIPPER_VERSION,
                        "documentation": ["https://www.klipper3d.org/Config_Reference.html#input_shaper"],
                        "axis": "x",
                        "shaper_type": "zvd",
                        "shaper_freq_hz": 40.0,
                        "damping_ratio": 0.0,
                        "section": "[input_shaper]\nshaper_type_x: zvd\nshaper_freq_x: 40\ndamping_ratio_x: 0\n",
                        "exact": True,
                        "residual_percent": 1.5e-14,
                        "shaper_residual_percent": 0.0,
                        "other_modes_shaper_residual_percent": [],
                        "note": None,
                    },
                    "reprapfirmware": {
                        "firmware": "RepRapFirmware",
                        "version": RRF_VERSION,
                        "documentation": [
                            "https://docs.duet3d.com/User_manual/Reference/Gcodes#m593-configure-input-shaping"
                        ],
                        "shaper_type": "zvd",
                        "frequency_hz": 40.0,
                        "damping_ratio": 0.0,
                        "command": 'M593 P"zvd" F40 S0',
                        "command_3_5": 'M593 P"zvd" F40 S0',
                        "exact": True,
                        "residual_percent": 1.5e-14,
                        "shaper_residual_percent": 0.0,
                        "other_modes_shaper_residual_percent": [],
                        "note": None,
                    },
                    "reprapfirmware_reason": None,
                    "marlin": {
                        "firmware": "Marlin",
                        "version": MARLIN_VERSION,
                        "documentation": ["https://marlinfw.org/docs/gcode/M493.html"],
                        "axis": "x",
                        "shaper_mode": 2,
                        "frequency_hz": 40.0,
                        "damping_ratio": 0.01,
                        "vibration_tolerance": None,
                        "command": "M493 S1 X C2 A40 I0.01",
                        "command_v1": "M493 S1 X2 A40 I0.01",
                        "exact": False,
                        "residual_percent": 0.0136,
                        "shaper_residual_percent": 0.419,
                        "other_modes_shaper_residual_percent": [],
                        "note": "Marlin delays the impulses by whole 1 ms samples (FTM_FS = 1000 Hz): 0, 13, 26 ms. "
                        "M493 I takes 0.01 to 1; the design's damping ratio is 0.",
                    },
                    "marlin_reason": None,
                }
            ]
        },
    )

    axis: Literal["x"] = Field(description="The axis the Klipper and Marlin lines set (RRF's M593 sets every axis).")
    design_frequency_hz: float = Field(description="The design (first shaped) mode's undamped natural frequency, Hz.")
    design_damping_ratio: float = Field(description="Its damping ratio.")
    klipper: KlipperOut
    reprapfirmware: RepRapFirmwareOut | None = Field(
        description="null where M593 cannot take the design frequency (4 to 1000 Hz); see reprapfirmware_reason."
    )
    reprapfirmware_reason: str | None = Field(description="Why reprapfirmware is null.")
    marlin: MarlinOut | None = Field(
        description="null where Fixed-Time Motion has no such shaper (a multi-mode design, ZV-D beyond ZVDDD) or "
        "the frequency is outside FTM_MIN_SHAPE_FREQ (20 Hz by default) to FTM_FS / 2 (500 Hz); see marlin_reason."
    )
    marlin_reason: str | None = Field(description="Why marlin is null.")


class InputShapedDesignOut(OutModel):
    """The design block of an input-shaped answer: the shaper, the baseline, the drive and ``firmware``."""

    model_config = ConfigDict(extra="allow")

    firmware: FirmwareOut = Field(
        description="The designed shaper as Klipper, RepRapFirmware and Marlin settings, with the residual each "
        "firmware's shaper leaves at the design frequency."
    )


class InputShapedResponse(FamilyResponse):
    """``profile`` is the shaped command sent to the drive (v_s); ``rate_limited`` is what the drive
    makes of it (v_a), which ``load`` and ``metrics`` simulate; ``unmodified`` gives the metrics of
    the plain shaped step (or pulse) after the limiter, for comparison."""

    design: InputShapedDesignOut  # type: ignore[assignment]
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
