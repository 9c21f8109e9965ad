"""Plant schemas: the ``plant`` object of every request, and the analysis response."""

from __future__ import annotations

from typing import Annotated, Any, ClassVar, Literal

from pydantic import Field

from app.schemas.common import OutModel, StrictModel
from app.schemas.drive import DriveIn, checked_drive
from models.errors import InvalidParameter
from models.plants import (
    FREQUENCY_MAX_HZ,
    FREQUENCY_MIN_HZ,
    MAX_TRANSFER_FUNCTION_ORDER,
    PARAMETER_MAX,
    BeltPlatformPlant,
    Mode,
    Plant,
    make_plant,
)
from models.plants import (
    PLANT_KINDS as MODEL_PLANT_KINDS,
)
from models.servo import closed_loop
from models.servo_response import load_plant

# Physical lower bounds: far below any machine (a 1e-9 kg m^2 rotor is a watch's; a 1e-6 kg mass a grain of
# sand), and high enough that every derived quantity (k/J, k J, c0 k, m0 m1, 2 k R^2) stays a normal double.
INERTIA_MIN_KGM2 = 1e-9
MASS_MIN_KG = 1e-6
STIFFNESS_MIN = 1e-6  # N/m or N m/rad
DAMPING_MIN = 1e-9  # N s/m, where a damping must be > 0
RADIUS_MIN_M, RADIUS_MAX_M = 1e-4, 1e3
GEAR_RATIO_MIN, GEAR_RATIO_MAX = 1e-6, 1e6
COEFFICIENT_MAX = 1e100  # transfer-function coefficients: |c| <= 1e100 (s^20 of a 1e6 rad/s pole is 1e120 ...)

Inertia = Annotated[float, Field(ge=INERTIA_MIN_KGM2, le=PARAMETER_MAX)]
Mass = Annotated[float, Field(ge=MASS_MIN_KG, le=PARAMETER_MAX)]
Stiffness = Annotated[float, Field(ge=STIFFNESS_MIN, le=PARAMETER_MAX)]
NonNegative = Annotated[float, Field(ge=0, le=PARAMETER_MAX)]
Radius = Annotated[float, Field(ge=RADIUS_MIN_M, le=RADIUS_MAX_M)]
Coefficient = Annotated[float, Field(ge=-COEFFICIENT_MAX, le=COEFFICIENT_MAX)]


PHYSICS = (
    f"plant (two_inertia, belt_platform, rigid_flexible): the parameters must give an oscillatory mode whose "
    f"natural frequency lies in [{FREQUENCY_MIN_HZ:g}, {FREQUENCY_MAX_HZ:g}] Hz and damping ratio is below 1.",
)


class ModeIn(StrictModel):
    """One vibration mode: the load follows the motor through (2 zeta w s + w^2)/(s^2 + 2 zeta w s + w^2)."""

    kind: Literal["mode"]
    natural_frequency_hz: float = Field(
        ge=FREQUENCY_MIN_HZ, le=FREQUENCY_MAX_HZ, description="Undamped natural frequency f_n, Hz."
    )
    damping_ratio: float = Field(0.0, ge=0, lt=1, description="Damping ratio zeta, 0 <= zeta < 1.")


class TwoInertiaIn(StrictModel):
    """Motor and load inertias on a compliant shaft (Cusimano Fig. 1); motor torque is defined."""

    kind: Literal["two_inertia"]
    UNSCHEMED_RULES: ClassVar[tuple[str, ...]] = PHYSICS
    motor_inertia_kgm2: Inertia = Field(description="Motor inertia J_M, kg m^2 (1e-9 to 1e12).")
    load_inertia_kgm2: Inertia = Field(description="Load inertia J_L, kg m^2 (1e-9 to 1e12).")
    stiffness_nm_per_rad: Stiffness = Field(description="Shaft torsional stiffness k, N m/rad (1e-6 to 1e12).")
    damping_nms_per_rad: NonNegative = Field(0.0, description="Shaft damping c, N m s/rad.")


class BeltPlatformIn(StrictModel):
    """Rotary platform on a two-branch belt behind a reducer (Incerti Fig. 1, Table I).

    The command is the motor angle (rad); the load is the platform angle (rad).
    """

    kind: Literal["belt_platform"]
    UNSCHEMED_RULES: ClassVar[tuple[str, ...]] = PHYSICS
    platform_inertia_kgm2: Inertia = Field(description="Platform inertia J, kg m^2 (1e-9 to 1e12).")
    branch_stiffness_n_per_m: Stiffness = Field(description="Stiffness k of each belt branch, N/m (1e-6 to 1e12).")
    branch_damping_ns_per_m: NonNegative = Field(description="Damping c of each belt branch, N s/m.")
    motor_pulley_radius_m: Radius = Field(description="Radius r of pulley (1), on the reducer, m (1e-4 to 1e3).")
    platform_pulley_radius_m: Radius = Field(description="Radius R of pulley (2), on the platform, m (1e-4 to 1e3).")
    gear_ratio: float = Field(
        ge=GEAR_RATIO_MIN,
        le=GEAR_RATIO_MAX,
        description="Reducer ratio z = pulley (1) speed / motor speed (0.1 for 1:10), 1e-6 to 1e6.",
    )


class RigidFlexibleIn(StrictModel):
    """Drive and load masses on a spring (Chatlatanagulchai Fig. 2), modelled by eq. (3) as printed.

    The command is the drive's velocity v; the load output is x1 = P(s) V(s). Eq. (3) as printed
    equals s X1(s)/F(s) of the paper's equations of motion, not X1/V: the service keeps it
    because the paper's mode (0.577 rad/s, zeta 0.0577) and figures come from it.
    """

    kind: Literal["rigid_flexible"]
    UNSCHEMED_RULES: ClassVar[tuple[str, ...]] = PHYSICS
    drive_mass_kg: Mass = Field(description="Driving mass m0, kg (1e-6 to 1e12).")
    load_mass_kg: Mass = Field(description="Driven mass m1, kg (1e-6 to 1e12).")
    stiffness_n_per_m: Stiffness = Field(description="Spring stiffness k, N/m (1e-6 to 1e12).")
    damping_ns_per_m: NonNegative = Field(description="Spring damping c, N s/m.")
    drive_damping_ns_per_m: float = Field(
        ge=DAMPING_MIN,
        le=PARAMETER_MAX,
        description="Drive damping c0, N s/m, 1e-9 to 1e12 (> 0: c0 k is eq. 3's constant term).",
    )


class TransferFunctionIn(StrictModel):
    """Any stable, proper transfer function from the motor command to the load."""

    kind: Literal["transfer_function"]
    numerator: list[Coefficient] = Field(
        min_length=1,
        max_length=MAX_TRANSFER_FUNCTION_ORDER + 1,
        description="Numerator, highest power of s first (each |c| <= 1e100).",
    )
    denominator: list[Coefficient] = Field(
        min_length=2,
        max_length=MAX_TRANSFER_FUNCTION_ORDER + 1,
        description="Denominator, highest power of s first (each |c| <= 1e100).",
    )
    command_input: Literal["position", "velocity"] = Field(
        "position", description="Whether the transfer function takes the motor position or velocity."
    )

    UNSCHEMED_RULES: ClassVar[tuple[str, ...]] = (
        "plant (transfer_function): proper (numerator degree, after its leading zeros, at most the denominator's; "
        "below it for command_input velocity); poles in the left half-plane (undamped complex pairs allowed), not "
        "repeated, of magnitude at most 2 pi 1e6 rad/s; the coefficients within double precision's range once the "
        "denominator is made monic; its modes physical (natural frequency within [1e-3, 1e5] Hz).",
    )

    @classmethod
    def schema_rules(cls) -> list[dict[str, Any]]:
        # models.plants.TransferFunctionPlant: a denominator whose leading coefficient is not 0 and whose constant
        # term is not 0 either (a pole at s = 0: not in the left half-plane), and a numerator not all zeros
        nonzero = {"not": {"const": 0}}
        last_nonzero = [
            {"minItems": n, "maxItems": n, "prefixItems": [{}] * (n - 1) + [nonzero]}
            for n in range(2, MAX_TRANSFER_FUNCTION_ORDER + 2)
        ]
        return [
            *super().schema_rules(),
            {"properties": {"denominator": {"prefixItems": [nonzero], "anyOf": last_nonzero}}},
            {"properties": {"numerator": {"contains": nonzero}}},
        ]


Mechanics = ModeIn | TwoInertiaIn | BeltPlatformIn | RigidFlexibleIn | TransferFunctionIn
MechanicsIn = Annotated[Mechanics, Field(discriminator="kind")]


class ClosedLoopIn(StrictModel):
    """The machine through its drive: the closed loop from the position command (what the drive is sent) to the
    load (models.servo), as a transfer function whose modes are the closed loop's: the modes a design cancels."""

    kind: Literal["closed_loop"]
    UNSCHEMED_RULES: ClassVar[tuple[str, ...]] = (
        "plant (closed_loop): the closed loop must be stable and its transfer function a valid transfer_function "
        "plant (poles not repeated, modes within [1e-3, 1e5] Hz).",
    )
    mechanics: MechanicsIn = Field(description="The machine's mechanics: any other plant kind.")
    drive: DriveIn


PlantIn = Annotated[Mechanics | ClosedLoopIn, Field(discriminator="kind")]
# the model's kinds, in its order (mode, two_inertia, ... transfer_function), then the closed loop through a drive
PLANT_KINDS = (*MODEL_PLANT_KINDS, "closed_loop")


def to_plant(schema: Mechanics | ClosedLoopIn) -> Plant:
    """The core plant of a request's ``plant`` object; physics errors name ``plant.<field>``."""
    if isinstance(schema, ClosedLoopIn):
        return _closed_loop_plant(schema)
    try:
        return make_plant(**schema.model_dump())
    except InvalidParameter as exc:
        raise exc.under("plant") from None


def _closed_loop_plant(schema: ClosedLoopIn) -> Plant:
    """The closed loop's transfer function from the command to the load (models.servo_response.load_plant)."""
    mechanics = to_plant(schema.mechanics)
    try:
        drive = checked_drive(schema.drive, mechanics)
    except InvalidParameter as exc:
        raise exc.under("plant") from None
    if drive.sample_period_s is not None:
        raise InvalidParameter(
            "plant.drive.sample_period_s",
            drive.sample_period_s,
            "designing through a sampled drive is not modelled (its loop has no transfer function in s): design "
            "through its continuous loops (null), and check the design through the sampled drive with the "
            "request's drive",
        )
    try:
        return load_plant(closed_loop(mechanics, drive))
    except InvalidParameter as exc:  # (named drive...: models.servo, servo_response.load_plant)
        raise exc.under("plant") from None


# --- analysis response --------------------------------------------------------------------


class ModeOut(OutModel):
    natural_frequency_hz: float
    natural_frequency_rad_s: float
    damping_ratio: float
    damped_frequency_hz: float
    damped_frequency_rad_s: float
    natural_period_s: float
    damped_period_s: float
    decay_rate_1_s: float = Field(description="sigma = zeta w_n: the envelope decays as exp(-sigma t).")


class TransferFunctionOut(OutModel):
    numerator: list[float] = Field(description="Highest power of s first.")
    denominator: list[float]
    input: Literal["position", "velocity"] = Field(description="The motor quantity the function takes.")


class StateSpaceOut(OutModel):
    a: list[list[float]]
    b: list[list[float]]
    c: list[list[float]]
    d: list[list[float]]


class PlantAnalysis(OutModel):
    kind: str
    parameters: dict[str, float | list[float] | str]
    modes: list[ModeOut] = Field(description="Vibration modes (complex pole pairs), lowest first.")
    dc_gain: float = Field(description="G(0): load displacement per unit motor displacement (0 for velocity input).")
    transfer_function: TransferFunctionOut = Field(description="The kind's transfer function, from its command input.")
    load_transfer_function: TransferFunctionOut = Field(
        description="G(s) from the motor position to the load position."
    )
    state_space: StateSpaceOut = Field(description="A realisation of G(s): motor position in, load position out.")
    derived: dict[str, float] = Field(description="Kind-specific derived quantities (k_t, c_t, lambda, ...).")
    defines_energy: bool = Field(description="Whether the vibration energy (J) is defined for this kind.")
    defines_motor_torque: bool


def mode_out(mode: Mode) -> ModeOut:
    return ModeOut(**mode.as_dict())


def analyse(plant: Plant) -> PlantAnalysis:
    num, den = plant.command_transfer_function()
    lnum, lden = plant.load_transfer_function()
    ss = plant.state_space()
    derived: dict[str, float] = {}
    if isinstance(plant, BeltPlatformPlant):
        derived = {
            "equivalent_stiffness_nm_per_rad": plant.equivalent_stiffness_nm_per_rad,
            "equivalent_damping_nms_per_rad": plant.equivalent_damping_nms_per_rad,
            "transmission_ratio": plant.transmission_ratio,
        }
    inertias = plant.torque_inertias()
    if inertias is not None:
        derived = {"total_inertia_kgm2": sum(inertias), "inertia_ratio": inertias[1] / inertias[0]}
    params = {k: (list(v) if isinstance(v, tuple) else v) for k, v in plant.parameter_values().items()}
    return PlantAnalysis(
        kind=plant.kind,
        parameters=params,
        modes=[mode_out(m) for m in plant.modes()],
        dc_gain=plant.dc_gain,
        transfer_function=TransferFunctionOut(
            numerator=num.tolist(), denominator=den.tolist(), input=plant.command_input
        ),
        load_transfer_function=TransferFunctionOut(
            numerator=lnum.tolist(), denominator=lden.tolist(), input="position"
        ),
        state_space=StateSpaceOut(a=ss.a.tolist(), b=ss.b.tolist(), c=ss.c.tolist(), d=ss.d.tolist()),
        derived=derived,
        defines_energy=plant.energy_inertia is not None,
        defines_motor_torque=inertias is not None,
    )
