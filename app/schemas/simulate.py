"""Sampled profiles in and out, the load response, and the simulation metrics."""

from __future__ import annotations

from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import Field

from app.schemas.common import (
    TOLERANCE_MIN,
    Cond,
    OutModel,
    SampleTime,
    SampleValue,
    StrictModel,
    either,
    given,
    inside,
    is_value,
    never,
    present,
)
from app.schemas.drive import DriveIn, GainsOut
from app.schemas.plants import ModeOut, PlantIn
from models.commands import DERIVATIVE_NAMES, PiecewiseCommand
from models.errors import InvalidParameter

Quantity = Literal["position", "velocity", "acceleration", "jerk"]
_CONSISTENCY_TOLERANCE = 1e-6


class ProfileIn(StrictModel):
    """A sampled motor command: a time grid and one or more of its derivatives."""

    time_s: list[SampleTime] = Field(min_length=2, description="Strictly increasing sample times, s (|t| <= 1e6).")
    position: list[SampleValue] | None = Field(
        None, description="Motor position (rad or m), one per time (|x| <= 1e12)."
    )
    velocity: list[SampleValue] | None = Field(None, description="Motor velocity, one per time (|v| <= 1e12).")
    acceleration: list[SampleValue] | None = Field(None, description="Motor acceleration, one per time (<= 1e12).")
    jerk: list[SampleValue] | None = Field(None, description="Motor jerk, one per time (|j| <= 1e12).")

    UNSCHEMED_RULES: ClassVar[tuple[str, ...]] = (
        "profile.time_s strictly increasing, at most the service's sample cap (VIBFREE_MAX_SAMPLES); every array "
        "given as long as profile.time_s.",
    )

    @classmethod
    def schema_rules(cls) -> list[dict[str, Any]]:
        # at least one of the quantities (to_command)
        return [*super().schema_rules(), either(*(given(name, "array") for name in DERIVATIVE_NAMES)).holds]


class SettlingIn(StrictModel):
    """When the load counts as settled: from the earliest time after which both hold for ever."""

    position_tolerance: float = Field(
        1e-3,
        ge=TOLERANCE_MIN,
        le=1,
        description="|load - target| as a fraction of the load's move (velocity for rest-to-velocity).",
    )
    vibration_tolerance: float | None = Field(
        None,
        ge=TOLERANCE_MIN,
        le=1e9,
        description="Bound on the amplitude of the load's vibration envelope, in the load's units (velocity units "
        "for rest-to-velocity): the free oscillation about its rigid motion plus, during the move, the quasi-static "
        "deflection. Default: 1 % of the lowest mode's quasi-static deflection of the load, |G(0)| max_acceleration "
        "/ omega_n^2 (|G(0)| max_acceleration / omega_n in velocity) where an acceleration limit applies, else 1e-3 of "
        "the load's move (on /v1/simulate, which has no limits: 1e-3 of the load's move, or of its largest excursion "
        "if larger).",
    )


class SimulationOptions(StrictModel):
    held_quantity: Quantity | None = Field(
        None,
        description="Which array drives the simulation (default: the highest derivative given; with the cubic "
        "hold, the one below it). Lower derivatives are its exact integrals, starting from the first sample of "
        "each one given (else 0).",
    )
    hold: Literal["linear", "zero", "cubic"] = Field(
        "linear",
        description="Between samples the held quantity is linear (first-order hold), constant (zero-order hold) or "
        "the cubic Hermite curve through its samples and those of its derivative (e.g. velocity with "
        "acceleration: what a cam table with velocity feed-forward does). The simulation is exact for that "
        "interpolation.",
    )
    settling_tolerance: float = Field(
        1e-3,
        ge=TOLERANCE_MIN,
        le=1,
        description="Settling band as a fraction of the load's displacement (or final speed).",
        deprecated="settling_tolerance is deprecated: use settling.position_tolerance",
    )
    settling_window: float | None = Field(
        None,
        ge=TOLERANCE_MIN,
        le=1e9,
        description="Absolute settling band in load units (1e-12 to 1e9); overrides settling_tolerance.",
    )
    settling: SettlingIn | None = Field(
        None,
        description="The settling criteria (vibration_tolerance default here, without limits: 1e-3 of the load's "
        "move). settling.position_tolerance replaces settling_tolerance.",
    )

    @classmethod
    def schema_rules(cls) -> list[dict[str, Any]]:
        # settling_tolerance is the deprecated settling.position_tolerance: not beside settling (settling_criteria)
        return [*super().schema_rules(), never(present("settling_tolerance"), given("settling", "object"))]

    def settling_criteria(self) -> tuple[float, float | None]:
        """The position tolerance and the vibration bound (None: the default)."""
        legacy = float(self.__dict__["settling_tolerance"])  # without the deprecated field's access warning
        if self.settling is None:
            return legacy, None
        if "settling_tolerance" in self.model_fields_set:
            raise InvalidParameter("settling_tolerance", legacy, "give settling.position_tolerance only")
        return self.settling.position_tolerance, self.settling.vibration_tolerance


class SimulateRequest(SimulationOptions):
    plant: PlantIn
    profile: ProfileIn
    drive: DriveIn | None = Field(
        None,
        description="The servo that executes the command: the answer gains ``closed_loop``, what the motor and the "
        "load do through it (the ideal-motor prediction stays in ``load`` and ``metrics``).",
    )

    @classmethod
    def schema_rules(cls) -> list[dict[str, Any]]:
        """The held quantity is given, and a cubic hold also has its derivative (``to_command``)."""

        def lacks(name: str) -> Cond:
            return ~given(name, "array")

        cubic = is_value("hold", "cubic")
        rules = [*super().schema_rules(), never(cubic, is_value("held_quantity", "jerk"))]
        for index, name in enumerate(DERIVATIVE_NAMES):
            rules.append(never(is_value("held_quantity", name), inside("profile", lacks(name))))
            if index + 1 < len(DERIVATIVE_NAMES):  # a cubic hold of name needs its derivative
                next_lacking = inside("profile", lacks(DERIVATIVE_NAMES[index + 1]))
                rules.append(never(cubic, is_value("held_quantity", name), next_lacking))
            # cubic, held_quantity unset: the highest quantity given (name) and the one below it
            highest = [given(name, "array"), *(lacks(above) for above in DERIVATIVE_NAMES[index + 1 :])]
            below = [lacks(DERIVATIVE_NAMES[index - 1])] if index else []
            rules.append(never(cubic, ~given("held_quantity", "string"), inside("profile", *highest, *below)))
        return rules


class ProfileOut(OutModel):
    """The motor command, sampled: what to paste into a drive."""

    time_s: list[float]
    position: list[float]
    velocity: list[float]
    acceleration: list[float]
    jerk: list[float] = Field(description="Right-hand values where the jerk jumps.")


class LoadOut(OutModel):
    """The predicted load motion, at the times of the command that was simulated (``profile.time_s``; on
    /v1/profiles/input-shaped ``rate_limited.time_s``, what the drive makes of the profile)."""

    time_s: list[float] | None = Field(
        None,
        deprecated=True,
        description="Deprecated: the same array as profile.time_s (rate_limited.time_s for input-shaped), so it "
        "is left out of the answer; returned only when asked for by `fields=load.time_s`.",
    )
    position: list[float] = Field(description="Load position, in the load's units (platform rad for belt_platform).")
    velocity: list[float]
    acceleration: list[float]
    deflection: list[float] | None = Field(
        None, description="Load position minus G(0) times the motor position; null for velocity-input plants."
    )
    motor_torque_nm: list[float] | None = Field(None, description="J_M th_M'' + J_L th_L'' (two_inertia only).")


class ModeResidualOut(OutModel):
    natural_frequency_hz: float
    damping_ratio: float
    residual_amplitude: float
    residual_velocity_amplitude: float


class MetricsOut(OutModel):
    command_end_s: float = Field(description="Time of the command's last change: where the residual is measured.")
    motion_time_s: float = Field(description="The command's duration: from its start (t = 0) to its last change.")
    residual_amplitude: float = Field(
        description="Envelope of the load's free oscillation when the command ends, from the state (sum over modes)."
    )
    residual_velocity_amplitude: float = Field(description="The same for the load velocity.")
    modes: list[ModeResidualOut]
    final_energy_j: float | None = Field(
        description="Vibration energy J/2 alpha'^2 + k/2 alpha^2 left when the command ends (physical plants only)."
    )
    settling_time_s: float | None = Field(
        description="From the command's start, the earliest time after which the load stays within the position "
        "band and its vibration envelope below the vibration bound for ever (it can be before the command's end); "
        "null if it never does (an undamped mode left ringing, or a command that does not move: a band of zero)."
    )
    settled: bool
    settling_quantity: Literal["position", "velocity"]
    settling_window: float = Field(description="Half-width of the position band, in load units.")
    settling_vibration_window: float | None = Field(
        description="The bound on the load's vibration envelope that settling also needs (load units)."
    )
    percentage_vibration: float | None = Field(
        None,
        description="V at the plant's first mode as modelled, % (see the sensitivity block for its definition); "
        "null without a mode, and on /v1/simulate, which has no limits to build the reference from.",
    )
    peak_velocity: float | None = Field(description="Peak |command velocity|; null where it is impulsive.")
    peak_acceleration: float | None
    peak_jerk: float | None
    peak_motor_torque_nm: float | None = Field(description="Peak |motor torque| at the samples (two_inertia only).")


class MotorOut(OutModel):
    """The motor through its drive, at the command's times (a sampled drive's: at its samples)."""

    time_s: list[float] = Field(
        description="The times of every closed-loop array: the command's (profile.time_s); with a sampled drive "
        "its samples, k drive.sample_period_s from the command's start to the first sample at or after its end."
    )
    position: list[float]
    velocity: list[float]
    acceleration: list[float]
    torque_nm: list[float] = Field(description="K_T i (the torque reference where the current loop is ideal).")
    current_a: list[float]
    voltage_v: list[float] = Field(
        description="The current PI's output; without a current loop what the winding needs, R i + K_E w (its "
        "inductance neglected)."
    )


class ClosedLoopLoadOut(OutModel):
    time_s: list[float] = Field(description="As motor.time_s.")
    position: list[float]
    velocity: list[float]
    acceleration: list[float]


class SaturationOut(OutModel):
    quantity: Literal["torque_nm", "voltage_v"]
    limit: float
    peak: float = Field(
        description="Largest |value| the command needs through the loop were the motor unlimited (the linear "
        "prediction's, at the command's times): how far past the limit the command asks to go."
    )
    first_time_s: float


class DifferenceOut(OutModel):
    """The closed loop against the ideal motor (``load`` and ``metrics``)."""

    load_position_max_abs: float = Field(description="max |closed-loop load - ideal-motor load| at the samples.")
    residual_amplitude_ratio: float | None = Field(
        description="Closed-loop residual amplitude over the ideal motor's; null where the ideal one is 0."
    )
    settling_time_change_s: float | None = Field(
        description="Closed-loop settling time less the ideal motor's; null where either never settles."
    )


class ClosedLoopOut(OutModel):
    """What the machine does through its drive (models.servo): linear, exact at the command's times (a sampled
    drive's, models.servo_sampled: exact at its samples, and its settling and residual measured there)."""

    motor: MotorOut
    load: ClosedLoopLoadOut
    tracking_error: list[float] = Field(description="Command position less motor position.")
    metrics: MetricsOut = Field(
        description="The load's, from the closed loop's state at the command's end (at the drive's limits: from the "
        "first sample after which it provably stays within them); peak_motor_torque_nm is the peak "
        "of motor.torque_nm; percentage_vibration (on the profile endpoints and compare) is 100 x the residual over "
        "the unshaped rigid command's under the same limits, both through the drive (null on /v1/simulate, as "
        "``metrics``' own)."
    )
    saturated: bool = Field(
        description="The command asks the motor for more than max_torque_nm or max_voltage_v (see saturation): "
        "then the drive clamps its current reference and its voltage, and every array here is the drive at its "
        "limits (simulation 'limited'), unless simulation_note says why it is linear."
    )
    saturation: list[SaturationOut]
    simulation: Literal["linear", "limited"] = Field(
        description="'linear': the loop never reaches a limit, or (saturated, with simulation_note) the limited "
        "simulation could not answer, or the drive is sampled (its limits are reported, not simulated); "
        "'limited': the drive at its limits, the current reference and voltage clamped, the integrators "
        "kept from winding up by back-calculation, integrated to rtol 1e-10 (models.servo_limits). Its arrays "
        "then run past the command's end until the drive provably stays within its limits, and the metrics' "
        "free vibration is measured from there."
    )
    simulation_note: str | None = Field(description="Why a saturated prediction is linear; null otherwise.")
    gains: GainsOut
    modes: list[ModeOut] = Field(description="The closed loop's oscillatory poles, lowest first: the modes to cancel.")
    difference: DifferenceOut


class SimulateResponse(OutModel):
    profile: ProfileOut
    load: LoadOut
    metrics: MetricsOut
    warnings: list[str]
    closed_loop: ClosedLoopOut | None = Field(None, description="With ``drive``: the prediction through it.")


def check_sample_count(field: str, count: int, max_samples: int) -> None:
    if count > max_samples:
        raise InvalidParameter(
            field, f"{count} samples", f"at most {max_samples} samples are allowed (VIBFREE_MAX_SAMPLES)"
        )


def to_command(profile: ProfileIn, options: SimulationOptions, max_samples: int) -> tuple[PiecewiseCommand, list[str]]:
    """The piecewise-polynomial command a sampled profile describes, and consistency warnings."""
    check_sample_count("profile.time_s", len(profile.time_s), max_samples)
    given = [name for name in DERIVATIVE_NAMES if getattr(profile, name) is not None]
    if not given:
        raise InvalidParameter("profile", "no samples", "give at least one of position, velocity, acceleration, jerk")
    cubic = options.hold == "cubic"
    if cubic and options.held_quantity is None and len(given) < 2:
        raise InvalidParameter(
            "hold", "cubic", "a cubic hold needs a quantity and its derivative (e.g. velocity and acceleration)"
        )
    held = options.held_quantity or (given[-2] if cubic else given[-1])
    if held not in given:
        raise InvalidParameter("held_quantity", held, f"profile.{held} is not given")
    if cubic:
        slope_name = DERIVATIVE_NAMES[DERIVATIVE_NAMES.index(held) + 1] if held != "jerk" else None
        if slope_name is None or slope_name not in given:
            raise InvalidParameter(
                "hold", "cubic", f"a cubic hold of {held} needs profile.{slope_name or 'its derivative'}"
            )
    arrays = {name: np.asarray(getattr(profile, name), dtype=float) for name in given}
    for name, arr in arrays.items():
        if arr.size != len(profile.time_s):
            raise InvalidParameter(
                f"profile.{name}",
                f"{arr.size} samples",
                f"must have as many samples as profile.time_s ({len(profile.time_s)})",
            )
    order = DERIVATIVE_NAMES.index(held)
    initial = tuple(float(arrays[n][0]) if n in arrays else 0.0 for n in DERIVATIVE_NAMES[:order])
    command = PiecewiseCommand.from_samples(
        np.asarray(profile.time_s, dtype=float),
        arrays[held],
        order,
        hold=options.hold,
        slopes=arrays[slope_name] if cubic and slope_name is not None else None,
        initial=initial,
    )
    warnings = []
    for m, name in enumerate(DERIVATIVE_NAMES[:order]):
        if name in arrays:
            given_values = arrays[name]
            gap = np.abs(command.derivative(m) - given_values)
            scale = max(float(np.max(np.abs(given_values))), 1e-300)
            if float(np.max(gap)) > _CONSISTENCY_TOLERANCE * scale:
                k = int(np.argmax(gap))
                warnings.append(
                    f"profile.{name} differs from the integral of profile.{held} by up to {gap[k]:.3g} "
                    f"(at t = {command.time_s[k]:.6g} s); the simulation uses profile.{held}"
                )
    return command, warnings
