"""The ``drive`` object: the servo that executes the command (models.servo), by its gains or its bandwidths."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Annotated, Any, ClassVar

from pydantic import Field, model_validator

from app.schemas.common import OutModel, StrictModel, either, given, never
from models.errors import InvalidParameter
from models.plants import Plant
from models.servo import PI, Drive, Motor, current_pi, moved_inertia, velocity_pi

# Physical ranges, far beyond any drive, that keep every entry of the closed loop's matrix a normal double (the
# plant schema's own, app.schemas.plants, for the inertia).
BANDWIDTH_MIN_HZ, BANDWIDTH_MAX_HZ = 1e-3, 1e5
Bandwidth = Annotated[float, Field(ge=BANDWIDTH_MIN_HZ, le=BANDWIDTH_MAX_HZ)]
Gain = Annotated[float, Field(ge=1e-9, le=1e9)]
IntegralGain = Annotated[float, Field(ge=0, le=1e12)]
Electrical = Annotated[float, Field(ge=1e-6, le=1e6)]  # ohm, N m/A, V s/rad
Inductance = Annotated[float, Field(ge=1e-9, le=1e3)]
Limit = Annotated[float, Field(ge=1e-9, le=1e12)]
Inertia = Annotated[float, Field(ge=1e-9, le=1e12)]  # app.schemas.plants.Inertia's range
SamplePeriod = Annotated[float, Field(ge=1e-6, le=0.1)]


class PositionLoopIn(StrictModel):
    """The position loop: a P controller, w_ref = kp (r - th_M) (+ r' with velocity feed-forward)."""

    bandwidth_hz: Bandwidth | None = Field(
        None, description="Its bandwidth, Hz: kp_per_s = 2 pi bandwidth_hz (the loop's corner with ideal inner loops)."
    )
    kp_per_s: Gain | None = Field(None, description="Its gain, 1/s (rad/s per rad of error), 1e-9 to 1e9.")

    @model_validator(mode="after")
    def _one_way(self) -> PositionLoopIn:
        if (self.bandwidth_hz is None) == (self.kp_per_s is None):
            raise ValueError("give bandwidth_hz or kp_per_s (one of them)")
        return self

    @classmethod
    def schema_rules(cls) -> list[dict[str, Any]]:
        one = either(given("bandwidth_hz"), given("kp_per_s"))
        return [*super().schema_rules(), one.holds, never(given("bandwidth_hz"), given("kp_per_s"))]


class PiLoopIn(StrictModel):
    """A PI loop, by its bandwidth (a named rule gives the gains) or by kp and ki."""

    bandwidth_hz: Bandwidth | None = Field(None, description="Bandwidth, Hz (1e-3 to 1e5).")
    kp: Gain | None = Field(None, description="Proportional gain (1e-9 to 1e9).")
    ki: IntegralGain | None = Field(None, description="Integral gain (0 to 1e12).")

    @model_validator(mode="after")
    def _one_way(self) -> PiLoopIn:
        by_gains = self.kp is not None or self.ki is not None
        if (self.bandwidth_hz is None) != by_gains or (by_gains and (self.kp is None or self.ki is None)):
            raise ValueError("give bandwidth_hz, or kp and ki (not both ways)")
        return self

    @classmethod
    def schema_rules(cls) -> list[dict[str, Any]]:
        return [
            *super().schema_rules(),
            either(given("bandwidth_hz"), given("kp")).holds,
            never(given("bandwidth_hz"), given("kp")),
            never(given("bandwidth_hz"), given("ki")),
            never(given("kp"), ~given("ki")),
        ]


class VelocityLoopIn(PiLoopIn):
    """The velocity PI, in torque units: kp in N m s/rad, ki in N m/rad (N s/m and N/m on a linear axis). By
    bandwidth: the symmetric optimum (Kessler 1958, a = 2), kp = J w, ki = J w^2 / 2, J the inertia moved."""


class CurrentLoopIn(PiLoopIn):
    """The current PI: kp in V/A, ki in V/(A s). By bandwidth: internal model control of the winding (Harnefors
    & Nee 1998), kp = L w, ki = R w: a first-order current loop of that bandwidth."""


class FeedforwardIn(StrictModel):
    velocity: bool = Field(True, description="Add the command's velocity to the velocity reference.")
    acceleration: bool = Field(
        True, description="Add J r'' to the torque reference (J: J_M + J_L on a two_inertia plant, else the motor's)."
    )


class MotorIn(StrictModel):
    """The motor's electrical data and limits (SI; on a linear motor N, m and N/A in place of N m, rad, N m/A)."""

    resistance_ohm: Electrical = Field(description="Winding resistance R, ohm (1e-6 to 1e6).")
    inductance_h: Inductance = Field(description="Winding inductance L, H (1e-9 to 1e3).")
    torque_constant_nm_per_a: Electrical = Field(description="K_T, N m/A (1e-6 to 1e6).")
    back_emf_v_s_per_rad: Electrical | None = Field(
        None, description="K_E, V s/rad (default K_T: the same in SI units)."
    )
    max_torque_nm: Limit | None = Field(
        None,
        description="Torque limit: the drive clamps its current reference to max_torque_nm / K_T; a command that "
        "needs more is reported and simulated at the limit (closed_loop.simulation).",
    )
    max_voltage_v: Limit | None = Field(
        None,
        description="Supply voltage limit: the current loop's output is clamped to it; a command that needs more is "
        "reported and simulated at the limit (reported only without a current loop or with a sampled drive).",
    )
    inertia_kgm2: Inertia | None = Field(
        None, description="Motor inertia J_M, kg m^2, needed on plants other than two_inertia (which give it)."
    )


class DriveIn(StrictModel):
    """The servo drive that executes the command: position P, velocity PI, current PI (null: the torque follows
    its reference ideally), feed-forward, the motor (models.servo)."""

    UNSCHEMED_RULES: ClassVar[tuple[str, ...]] = (
        "drive: the closed loop of these gains on the plant must be stable (its poles are given where not).",
        "drive.motor.inertia_kgm2 is required unless the plant (or closed_loop's mechanics) is two_inertia.",
    )
    sample_period_s: SamplePeriod | None = Field(
        None,
        description="The position and velocity loops' sample period, s (1e-6 to 0.1): they run digitally, the "
        "command and the motor's position and velocity sampled every period, the torque reference applied one "
        "period later and held (zero-order hold, one sample of computation delay); the motor, its current loop "
        "and the mechanics stay continuous, discretised exactly. Needs a position loop. The closed_loop block is "
        "then at the samples k sample_period_s. null: continuous loops.",
    )
    position_loop: PositionLoopIn | None = Field(
        description="The position loop; null: none, the drive follows the command's velocity (a velocity-mode "
        "drive, Cusimano Fig. 20), and the positions are what that velocity integrates to."
    )
    velocity_loop: VelocityLoopIn
    current_loop: CurrentLoopIn | None = None
    feedforward: FeedforwardIn = FeedforwardIn()
    motor: MotorIn


def _pi(loop: PiLoopIn, rule: Callable[[float], PI]) -> PI:
    if loop.bandwidth_hz is not None:
        return rule(loop.bandwidth_hz)
    assert loop.kp is not None and loop.ki is not None
    return PI(loop.kp, loop.ki)


def to_drive(schema: DriveIn, mechanics: Plant) -> Drive:
    """The model's Drive for ``mechanics`` (the gains a bandwidth gives depend on its inertia)."""
    m = schema.motor
    motor = Motor(
        m.resistance_ohm,
        m.inductance_h,
        m.torque_constant_nm_per_a,
        m.back_emf_v_s_per_rad,
        m.max_torque_nm if m.max_torque_nm is not None else float("inf"),
        m.max_voltage_v if m.max_voltage_v is not None else float("inf"),
        m.inertia_kgm2,
    )
    inertia = moved_inertia(mechanics, motor)
    position = schema.position_loop
    kp_per_s = None
    if position is not None:
        kp_per_s = position.kp_per_s if position.bandwidth_hz is None else 2.0 * math.pi * position.bandwidth_hz
    current = None if schema.current_loop is None else _pi(schema.current_loop, lambda f: current_pi(f, motor))
    return Drive(
        kp_per_s,
        _pi(schema.velocity_loop, lambda f: velocity_pi(f, inertia)),
        current,
        motor,
        schema.feedforward.velocity,
        schema.feedforward.acceleration,
        schema.sample_period_s,
    )


def checked_drive(schema: DriveIn, mechanics: Plant) -> Drive:
    """``to_drive``, its errors named under ``drive``."""
    try:
        return to_drive(schema, mechanics)
    except InvalidParameter as exc:
        raise exc if exc.field.startswith("drive") else exc.under("drive") from None


class GainsOut(OutModel):
    """The gains the drive runs with (those given, or those its bandwidths give)."""

    position_kp_per_s: float | None = Field(description="null: no position loop (a velocity-mode drive).")
    velocity_kp: float
    velocity_ki: float
    current_kp: float | None
    current_ki: float | None
    sample_period_s: float | None = Field(description="The position and velocity loops'; null: continuous.")
