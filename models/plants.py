"""Plant kinds: the elastic machines that the motor command drives.

The convention of all four papers is that the drive executes the motor command exactly (an ideal,
"kinematic" motor) and the load follows through the elastic element. Each kind gives its transfer
function once, in ``_command_tf`` (see ``models.plant_base``, which also holds ``Plant``, ``Mode``
and the limits; they are re-exported here).

Kinds and their sources:

- ``mode``: one vibration mode, G(s) = (2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2)
  (Biagiotti eq. 7 rewritten for the load, Cusimano eq. 4, Incerti eq. 4).
- ``two_inertia``: motor and load inertias on a compliant shaft (Cusimano Fig. 1, eqs. 1-3).
- ``belt_platform``: rotary platform on a two-branch belt behind a reducer (Incerti Fig. 1,
  eqs. 1-4, Tables I and III).
- ``rigid_flexible``: two masses on a spring, velocity-commanded drive (Chatlatanagulchai Fig. 2,
  eq. 3 as printed; see ``RigidFlexiblePlant``).
- ``transfer_function``: any stable rational transfer function given by its coefficients.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from models.errors import InvalidParameter
from models.plant_base import (
    FREQUENCY_MAX_HZ,
    FREQUENCY_MIN_HZ,
    PARAMETER_MAX,
    CommandInput,
    Mode,
    Plant,
    StateSpace,
    check_derived_frequency,
    check_modes,
    check_positive,
)
from models.plant_symbolic import SymbolicPlant

__all__ = [
    "FREQUENCY_MAX_HZ",
    "FREQUENCY_MIN_HZ",
    "MAX_TRANSFER_FUNCTION_ORDER",
    "PARAMETER_MAX",
    "PLANT_KINDS",
    "BeltPlatformPlant",
    "CommandInput",
    "Mode",
    "ModePlant",
    "Plant",
    "RigidFlexiblePlant",
    "StateSpace",
    "SymbolicPlant",
    "TransferFunctionPlant",
    "TwoInertiaPlant",
    "example_plants",
    "make_plant",
]

MAX_TRANSFER_FUNCTION_ORDER = 20
# Poles closer than this (relative) are repeated or nearly so: np.roots scatters a k-fold root by
# about eps^(1/k), and partial fractions of near-repeated poles lose all accuracy.
_REPEATED_POLE_RELATIVE_GAP = 1e-3
_ROOT_TOLERANCE = 1e-9  # relative: roots of s^2 + w^2 come out with |Re| ~ 1e-16 |p|


@dataclass(frozen=True)
class ModePlant(Plant):
    """A single mode given by its natural frequency and damping ratio.

    The load follows the motor through G(s) = (2 zeta w s + w^2)/(s^2 + 2 zeta w s + w^2): the
    model of all four papers (Cusimano eq. 4, Incerti eq. 4 with lambda = 1, Biagiotti eq. 7,
    Chatlatanagulchai eq. 1).
    """

    kind: ClassVar[str] = "mode"
    natural_frequency_hz: float
    damping_ratio: float = 0.0

    def __post_init__(self) -> None:
        f = check_positive("natural_frequency_hz", self.natural_frequency_hz)
        if not FREQUENCY_MIN_HZ <= f <= FREQUENCY_MAX_HZ:
            raise InvalidParameter(
                "natural_frequency_hz", f, f"must lie in [{FREQUENCY_MIN_HZ:g}, {FREQUENCY_MAX_HZ:g}] Hz"
            )
        z = float(self.damping_ratio)
        if not (math.isfinite(z) and 0.0 <= z < 1.0):
            raise InvalidParameter("damping_ratio", z, "must satisfy 0 <= damping_ratio < 1")

    @staticmethod
    def _command_tf(p: Mapping[str, Any]) -> tuple[list[Any], list[Any]]:
        w = 2.0 * math.pi * p["natural_frequency_hz"]
        z = p["damping_ratio"]
        return [2.0 * z * w, w * w], [1.0, 2.0 * z * w, w * w]

    def modes(self) -> tuple[Mode, ...]:
        return (Mode(2.0 * math.pi * self.natural_frequency_hz, self.damping_ratio),)


@dataclass(frozen=True)
class TwoInertiaPlant(Plant):
    """Motor inertia J_M driving a load J_L through a shaft of stiffness k and damping c.

    Cusimano Fig. 1: Omega_n = sqrt(k/J_L) (eq. 1), zeta = c/(2 sqrt(k J_L)) (eq. 3); the load
    obeys J_L th_L'' = k (th_M - th_L) + c (th_M' - th_L'), so G(s) = (c s + k)/(J_L s^2 + c s + k)
    (eq. 4 in absolute coordinates). The motor torque of a motion is J_M th_M'' + J_L th_L''.
    """

    kind: ClassVar[str] = "two_inertia"
    motor_inertia_kgm2: float
    load_inertia_kgm2: float
    stiffness_nm_per_rad: float
    damping_nms_per_rad: float = 0.0

    def __post_init__(self) -> None:
        check_positive("motor_inertia_kgm2", self.motor_inertia_kgm2)
        check_positive("load_inertia_kgm2", self.load_inertia_kgm2)
        check_positive("stiffness_nm_per_rad", self.stiffness_nm_per_rad)
        check_positive("damping_nms_per_rad", self.damping_nms_per_rad, allow_zero=True)
        check_modes(self.modes(), "stiffness_nm_per_rad")

    @staticmethod
    def _command_tf(p: Mapping[str, Any]) -> tuple[list[Any], list[Any]]:
        k, c, j_l = p["stiffness_nm_per_rad"], p["damping_nms_per_rad"], p["load_inertia_kgm2"]
        return [c, k], [j_l, c, k]

    def modes(self) -> tuple[Mode, ...]:
        k, j_l = self.stiffness_nm_per_rad, self.load_inertia_kgm2
        omega = check_derived_frequency("stiffness_nm_per_rad", math.sqrt(k / j_l))
        return (Mode(omega, self.damping_nms_per_rad / (2.0 * j_l * omega)),)

    def torque_inertias(self) -> tuple[float, float]:
        return self.motor_inertia_kgm2, self.load_inertia_kgm2

    @property
    def energy_inertia(self) -> float:
        return self.load_inertia_kgm2

    @property
    def energy_stiffness(self) -> float:
        return self.stiffness_nm_per_rad


@dataclass(frozen=True)
class BeltPlatformPlant(Plant):
    """Rotary platform driven by a servomotor through a reducer and a two-branch belt.

    Incerti Fig. 1 and eqs. (1)-(4): k_t = 2 k R^2, c_t = 2 c R^2, lambda = z r / R,
    omega_n = sqrt(k_t / J), xi = c_t / (2 J omega_n). The platform angle follows the motor angle
    through G(s) = lambda (c_t s + k_t) / (J s^2 + c_t s + k_t). ``gear_ratio`` is z, the speed of
    pulley (1) over the motor speed (0.1 for the 1:10 reducer of Table III). The vibration
    energy is E = J/2 (alpha'^2 + omega_n^2 alpha^2) with alpha = theta - lambda phi_m
    (eqs. 24-26).
    """

    kind: ClassVar[str] = "belt_platform"
    platform_inertia_kgm2: float
    branch_stiffness_n_per_m: float
    branch_damping_ns_per_m: float
    motor_pulley_radius_m: float
    platform_pulley_radius_m: float
    gear_ratio: float

    def __post_init__(self) -> None:
        check_positive("platform_inertia_kgm2", self.platform_inertia_kgm2)
        check_positive("branch_stiffness_n_per_m", self.branch_stiffness_n_per_m)
        check_positive("branch_damping_ns_per_m", self.branch_damping_ns_per_m, allow_zero=True)
        check_positive("motor_pulley_radius_m", self.motor_pulley_radius_m)
        check_positive("platform_pulley_radius_m", self.platform_pulley_radius_m)
        check_positive("gear_ratio", self.gear_ratio)
        check_modes(self.modes(), "branch_stiffness_n_per_m")

    @staticmethod
    def _command_tf(p: Mapping[str, Any]) -> tuple[list[Any], list[Any]]:
        r_big = p["platform_pulley_radius_m"]
        k_t = 2.0 * p["branch_stiffness_n_per_m"] * r_big * r_big
        c_t = 2.0 * p["branch_damping_ns_per_m"] * r_big * r_big
        lam = p["gear_ratio"] * p["motor_pulley_radius_m"] / r_big
        return [lam * c_t, lam * k_t], [p["platform_inertia_kgm2"], c_t, k_t]

    @property
    def equivalent_stiffness_nm_per_rad(self) -> float:
        """k_t = 2 k R^2 (eq. 3)."""
        return 2.0 * self.branch_stiffness_n_per_m * self.platform_pulley_radius_m**2

    @property
    def equivalent_damping_nms_per_rad(self) -> float:
        """c_t = 2 c R^2 (eq. 3)."""
        return 2.0 * self.branch_damping_ns_per_m * self.platform_pulley_radius_m**2

    @property
    def transmission_ratio(self) -> float:
        """lambda = z r / R (eq. 2): platform angle per motor angle for a rigid belt."""
        return self.gear_ratio * self.motor_pulley_radius_m / self.platform_pulley_radius_m

    def modes(self) -> tuple[Mode, ...]:
        j, k_t, c_t = (
            self.platform_inertia_kgm2,
            self.equivalent_stiffness_nm_per_rad,
            self.equivalent_damping_nms_per_rad,
        )
        omega = check_derived_frequency("branch_stiffness_n_per_m", math.sqrt(k_t / j))
        return (Mode(omega, c_t / (2.0 * j * omega)),)

    @property
    def energy_inertia(self) -> float:
        return self.platform_inertia_kgm2

    @property
    def energy_stiffness(self) -> float:
        return self.equivalent_stiffness_nm_per_rad


@dataclass(frozen=True)
class RigidFlexiblePlant(Plant):
    """Drive mass m0 and load mass m1 on a spring k with damping c; drive damping c0.

    Chatlatanagulchai Fig. 2 and eq. (3) *as printed*:
    P(s) = (c s + k) / (m0 m1 s^3 + (m0 c + m1 c + m1 c0) s^2 + (m0 k + m1 k + c c0) s + c0 k),
    taken from the paper's velocity command v to the load output x1. As the reproduction notes
    say, that expression is s X1(s)/F(s) of the equations of motion, not X1/V for v = dx0/dt: it
    is kept because the paper's figures and its printed mode (omega_n = 0.577 rad/s,
    zeta = 0.0577) come from it. The command input of this kind is therefore the velocity.
    """

    kind: ClassVar[str] = "rigid_flexible"
    drive_mass_kg: float
    load_mass_kg: float
    stiffness_n_per_m: float
    damping_ns_per_m: float
    drive_damping_ns_per_m: float

    def __post_init__(self) -> None:
        check_positive("drive_mass_kg", self.drive_mass_kg)
        check_positive("load_mass_kg", self.load_mass_kg)
        check_positive("stiffness_n_per_m", self.stiffness_n_per_m)
        check_positive("damping_ns_per_m", self.damping_ns_per_m, allow_zero=True)
        # c0 k is the constant term of eq. (3): with c0 = 0 the transfer function has a pole at 0.
        check_positive("drive_damping_ns_per_m", self.drive_damping_ns_per_m)
        modes = self.modes()
        if not modes:
            raise InvalidParameter("stiffness_n_per_m", self.stiffness_n_per_m, "the plant has no oscillatory mode")
        check_modes(modes, "stiffness_n_per_m")

    @property
    def command_input(self) -> CommandInput:
        return "velocity"

    @staticmethod
    def _command_tf(p: Mapping[str, Any]) -> tuple[list[Any], list[Any]]:
        m0, m1 = p["drive_mass_kg"], p["load_mass_kg"]
        k, c, c0 = p["stiffness_n_per_m"], p["damping_ns_per_m"], p["drive_damping_ns_per_m"]
        return [c, k], [m0 * m1, m0 * c + m1 * c + m1 * c0, m0 * k + m1 * k + c * c0, c0 * k]


@dataclass(frozen=True)
class TransferFunctionPlant(Plant):
    """Any stable, proper transfer function from the motor command to the load.

    ``numerator`` and ``denominator`` are in descending powers of s. ``command_input`` says
    whether the input is the motor position (default) or velocity. Poles must lie in the left
    half-plane; undamped complex pairs on the imaginary axis are allowed, a pole at 0 or repeated
    poles are not. The complex pole pairs are the modes.
    """

    kind: ClassVar[str] = "transfer_function"
    numerator: tuple[float, ...]
    denominator: tuple[float, ...]
    command_input: CommandInput = "position"

    def __post_init__(self) -> None:
        num = np.asarray(self.numerator, dtype=float)
        den = np.asarray(self.denominator, dtype=float)
        if self.command_input not in ("position", "velocity"):
            raise InvalidParameter("command_input", self.command_input, "must be 'position' or 'velocity'")
        for name, arr in (("numerator", num), ("denominator", den)):
            if arr.ndim != 1 or arr.size == 0:
                raise InvalidParameter(name, arr.ravel().tolist(), "must be a non-empty list of coefficients")
            if arr.size > MAX_TRANSFER_FUNCTION_ORDER + 1:
                raise InvalidParameter(
                    name, f"{arr.size} coefficients", f"order must be <= {MAX_TRANSFER_FUNCTION_ORDER}"
                )
            if not np.all(np.isfinite(arr)):
                raise InvalidParameter(name, "non-finite coefficient", "every coefficient must be finite")
        if den[0] == 0.0:
            raise InvalidParameter("denominator", den.tolist(), "the leading coefficient must not be 0")
        with np.errstate(all="ignore"):
            monic = den / den[0]
        if not np.all(np.isfinite(monic)) or np.any((monic != 0) & (np.abs(monic) < 1e-300)):
            raise InvalidParameter(
                "denominator", den.tolist(), "the coefficients span too wide a range for double precision"
            )
        num = np.trim_zeros(num, "f")
        if num.size == 0:
            raise InvalidParameter("numerator", list(self.numerator), "must not be all zeros")
        if den.size < 2:
            raise InvalidParameter("denominator", den.tolist(), "must be at least first order")
        relative = 1 if self.command_input == "velocity" else 0
        if num.size - 1 + relative > den.size - 1:
            rule = (
                "numerator degree must be below the denominator degree (velocity input)"
                if relative
                else ("numerator degree must not exceed the denominator degree (the plant must be proper)")
            )
            raise InvalidParameter("numerator", list(self.numerator), rule)
        poles = np.roots(den)
        scale = float(np.max(np.abs(poles)))
        for p in poles:
            oscillatory = abs(p.imag) > _ROOT_TOLERANCE * abs(p)
            if p.real > _ROOT_TOLERANCE * abs(p) or (not oscillatory and p.real >= -_ROOT_TOLERANCE * abs(p)):
                raise InvalidParameter(
                    "denominator",
                    den.tolist(),
                    f"pole {complex(p):.6g} is not in the left half-plane: the load would not follow the motor",
                )
        gaps = np.abs(poles[:, None] - poles[None, :])
        gaps[np.diag_indices(poles.size)] = np.inf
        size = np.maximum(np.abs(poles[:, None]), np.abs(poles[None, :]))
        if poles.size > 1 and np.any(gaps <= _REPEATED_POLE_RELATIVE_GAP * size):
            raise InvalidParameter(
                "denominator", den.tolist(), "repeated (or less than 0.1 % apart) poles are not supported"
            )
        if scale > 2 * math.pi * FREQUENCY_MAX_HZ * 10:
            raise InvalidParameter(
                "denominator", den.tolist(), f"a pole of magnitude {scale:.3g} rad/s is out of range"
            )
        _check_partial_fractions(num, den, poles)
        check_modes(self.modes(), "denominator")
        object.__setattr__(self, "numerator", tuple(float(x) for x in num))
        object.__setattr__(self, "denominator", tuple(float(x) for x in den))

    @staticmethod
    def _command_tf(p: Mapping[str, Any]) -> tuple[list[Any], list[Any]]:
        return list(p["numerator"]), list(p["denominator"])

    def command_transfer_function(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return np.asarray(self.numerator, dtype=float), np.asarray(self.denominator, dtype=float)

    def symbolic_sizes(self) -> dict[str, int]:
        return {"numerator": len(self.numerator), "denominator": len(self.denominator)}


def _check_partial_fractions(
    num: NDArray[np.float64], den: NDArray[np.float64], poles: NDArray[np.inexact[Any]]
) -> None:
    """The simulation writes G(s) = D + sum r_j/(s - p_j); refuse a plant whose poles are so
    clustered that this form does not reproduce G (checked at s = 0 and at points of the right
    half-plane, where no pole lies)."""
    # Coefficients up to 1e100 (the schema's bound) can overflow here: a non-finite value is refused below.
    with np.errstate(all="ignore"):
        residues = np.polyval(num, poles) / np.polyval(np.polyder(den), poles)
    direct = num[0] / den[0] if num.size == den.size else 0.0
    top = float(np.max(np.abs(poles)))
    for s in (0.0, top * (0.5 + 0.5j), top * (0.2 + 1.3j), top * (1.0 + 0.1j)):
        with np.errstate(all="ignore"):
            exact = np.polyval(num, s) / np.polyval(den, s)
            rebuilt = direct + np.sum(residues / (s - poles))
            size = float(np.sum(np.abs(residues / (s - poles)))) + abs(direct)
        if (
            not np.isfinite(rebuilt)
            or not np.isfinite(exact)
            or abs(rebuilt - exact) > 1e-4 * max(abs(exact), 1e-12 * size)
        ):
            raise InvalidParameter(
                "denominator", den.tolist(), "the poles are too clustered for an accurate partial-fraction form"
            )


PLANT_KINDS: dict[str, type[Plant]] = {
    cls.kind: cls for cls in (ModePlant, TwoInertiaPlant, BeltPlatformPlant, RigidFlexiblePlant, TransferFunctionPlant)
}


def make_plant(kind: str, **parameters: Any) -> Plant:
    """Build a plant of a kind from its parameters; raises InvalidParameter on bad values."""
    try:
        cls = PLANT_KINDS[kind]
    except KeyError:
        raise InvalidParameter("kind", kind, f"must be one of {', '.join(PLANT_KINDS)}") from None
    if cls is TransferFunctionPlant:
        parameters = {**parameters}
        for key in ("numerator", "denominator"):
            if key in parameters:
                parameters[key] = tuple(parameters[key])
    return cls(**parameters)


def example_plants() -> dict[str, Plant]:
    """The papers' plants, used by the docs' examples and the tests."""
    return {
        "incerti_table_iii": BeltPlatformPlant(6.0, 9e4, 150.0, 0.060, 0.180, 0.1),
        "cusimano_8hz_equal_inertia": TwoInertiaPlant(0.005, 0.005, 0.005 * (2 * math.pi * 8.0) ** 2, 0.0),
        "chatlatanagulchai_eq3": RigidFlexiblePlant(2.0, 3.0, 1.0, 0.1, 30.0),
        # sigma = -15.6539 1/s, Omega = 122.7185 rad/s (Biagiotti Sec. VI)
        "biagiotti_identified": ModePlant(
            math.hypot(122.7185, 15.6539) / (2 * math.pi), 15.6539 / math.hypot(122.7185, 15.6539)
        ),
    }
