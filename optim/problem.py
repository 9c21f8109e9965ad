"""The synthesis problem every family designs for: one plant, one move, one set of limits.

The vocabulary is the service's (docs/api.md, One vocabulary): a rest-to-rest ``displacement`` xor a rest-to-velocity
``target_velocity``, both signed, in the plant's motor coordinate; ``limits`` with Ruckig's
``max_`` names (``max_velocity`` is also the cruise speed of a rest-to-rest move); the sampling and
horizon of the returned series; the settling band; the sensitivity grid. Families read only this
and their own options.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

from models.commands import PiecewiseCommand
from models.errors import Infeasible, InvalidParameter
from models.plants import Plant
from models.rigid_motion import RigidMove, rigid_move
from optim.solver import SolveCaps

MAX_MOVE = 1e9
MIN_MOVE = 1e-9  # a nanometre (nanoradian) move, or speed: below it no figure of the answer means anything
MIN_LIMIT = 1e-9  # the least limit (SI units) kept: smaller ones underflow the formulas they enter
TAIL_PERIODS = 5.0  # the returned series run this many natural periods of the slowest mode past the command
DEFAULT_SAMPLES = 2000  # about this many samples over the horizon when no sample period is given
MIN_SAMPLE_PERIOD_S = 1e-6


@dataclass(frozen=True)
class Limits:
    """Bounds on the motor command along the whole motion; None: unbounded."""

    max_velocity: float | None = None
    max_acceleration: float | None = None
    max_jerk: float | None = None
    max_torque_nm: float | None = None

    def items(self) -> tuple[tuple[str, float | None], ...]:
        return (
            ("max_velocity", self.max_velocity),
            ("max_acceleration", self.max_acceleration),
            ("max_jerk", self.max_jerk),
            ("max_torque_nm", self.max_torque_nm),
        )

    @property
    def any(self) -> bool:
        return any(value is not None for _, value in self.items())


VIBRATION_FRACTION_OF_DEFLECTION = 0.01  # default vibration tolerance: 1 % of the quasi-static deflection
VIBRATION_FRACTION_OF_MOVE = 1e-3  # ... or, without an acceleration limit, 1e-3 of the load's move


@dataclass(frozen=True)
class SettlingCriteria:
    """The settling criteria: |load - target| <= position_tolerance x the load's move, and the load's
    free-vibration envelope <= vibration_tolerance (load units; None: the default of ``Problem``)."""

    position_tolerance: float = 1e-3
    vibration_tolerance: float | None = None


@dataclass(frozen=True)
class SensitivityGrid:
    """Where to evaluate the residual versus f_n / f_n,e (and, optionally, other true damping ratios)."""

    frequency_ratios: tuple[float, ...]
    damping_ratios: tuple[float, ...] | None = None
    explicit: bool = False  # the ratios were listed by the caller (for the name of the field at fault)


@dataclass(frozen=True)
class MotionState:
    """The motor's velocity and acceleration where a move starts or ends (Ruckig's current_/target_ state); the
    load is quasi-static in that motion (it has followed it long enough for its free vibration to have died)."""

    velocity: float = 0.0
    acceleration: float = 0.0

    @property
    def moving(self) -> bool:
        return self.velocity != 0.0 or self.acceleration != 0.0


REST = MotionState()


@dataclass(frozen=True)
class Problem:
    plant: Plant
    displacement: float | None = None
    target_velocity: float | None = None
    limits: Limits = field(default_factory=Limits)
    sample_period_s: float | None = None
    horizon_s: float | None = None
    settling: SettlingCriteria = field(default_factory=SettlingCriteria)
    sensitivity: SensitivityGrid | None = None
    max_samples: int = 200_000
    solver: SolveCaps = field(default_factory=SolveCaps)
    allow_limit_violation: bool = False
    initial_state: MotionState = REST
    final_state: MotionState = REST

    def __post_init__(self) -> None:
        if (self.displacement is None) == (self.target_velocity is None):
            raise InvalidParameter(
                "displacement",
                self.displacement,
                "give exactly one of displacement (rest-to-rest) or target_velocity (rest-to-velocity)",
            )
        name, move = self.move_field, self.move
        if not math.isfinite(move) or not MIN_MOVE <= abs(move) <= MAX_MOVE:
            raise InvalidParameter(name, move, f"|{name}| must be within [{MIN_MOVE:g}, {MAX_MOVE:g}]")
        for limit, value in self.limits.items():
            if value is not None and value < MIN_LIMIT:
                raise InvalidParameter(f"limits.{limit}", value, f"must be >= {MIN_LIMIT:g} (SI units)")
        accel = self.acceleration_limit
        if accel is not None and accel < MIN_LIMIT:  # a torque over the inertias: M / (J_M + J_L)
            raise InvalidParameter(
                "limits.max_torque_nm",
                self.limits.max_torque_nm,
                f"gives an acceleration below {MIN_LIMIT:g} (M / (J_M + J_L) = {accel:.3g})",
            )
        if self.limits.max_torque_nm is not None and self.plant.torque_inertias() is None:
            raise InvalidParameter(
                "limits.max_torque_nm",
                self.limits.max_torque_nm,
                f"a {self.plant.kind} plant defines no motor torque (two_inertia does)",
            )
        self._check_states()
        top = self.limits.max_velocity
        if self.target_velocity is not None and top is not None and abs(self.target_velocity) > top:
            raise Infeasible(
                f"the target velocity {abs(self.target_velocity):.6g} exceeds limits.max_velocity = {top:.6g}",
                "target_velocity",
            )

    def _check_states(self) -> None:
        """A move in motion has a displacement; its states lie within the velocity and acceleration limits; a
        non-zero acceleration needs a jerk limit."""
        for name, state in (("initial_state", self.initial_state), ("final_state", self.final_state)):
            if not state.moving:
                continue
            if self.target_velocity is not None:
                raise InvalidParameter(
                    name, state.velocity, "a move in motion needs a displacement, not target_velocity"
                )
            for part, value, limit in (
                ("velocity", state.velocity, self.limits.max_velocity),
                ("acceleration", state.acceleration, self.acceleration_limit),
            ):
                if not math.isfinite(value) or abs(value) > MAX_MOVE:
                    raise InvalidParameter(f"{name}.{part}", value, f"must be finite and within +-{MAX_MOVE:g}")
                if limit is not None and abs(value) > limit:
                    raise InvalidParameter(f"{name}.{part}", value, f"must be within the limit {limit:g} (|{part}|)")
            if state.acceleration != 0.0 and self.limits.max_jerk is None:
                raise InvalidParameter(
                    f"{name}.acceleration",
                    state.acceleration,
                    "a move between non-zero accelerations needs limits.max_jerk (without one the acceleration is "
                    "held piecewise constant and may jump: give 0)",
                )
        self._check_overshoot()

    def _check_overshoot(self) -> None:
        """Infeasible (proven) where the jerk limit cannot bring an end's acceleration to the other's before the
        velocity passes max_velocity: from (v0, a0 > 0) every command has a >= a0 - J t, so v >= v0 + a0 t - J t^2 / 2
        until t = a0 / J, and the move lasts at least |a0 - a_end| / J: v passes v0 + a0 t - J t^2 / 2 at
        t = min(|a0 - a_end|, a0) / J; the end state is the start of the time-reversed move (velocity vf,
        acceleration -af)."""
        jerk, top = self.limits.max_jerk, self.limits.max_velocity
        if jerk is None or top is None:
            return
        start, end = self.initial_state, self.final_state
        for name, v0, a0, a_end in (
            ("initial_state", start.velocity, start.acceleration, end.acceleration),
            ("final_state", end.velocity, -end.acceleration, -start.acceleration),
        ):
            if a0 < 0.0:
                v0, a0, a_end = -v0, -a0, -a_end
            if a0 == 0.0:
                continue
            t = min(abs(a0 - a_end), a0) / jerk  # no sooner can it reach a_end, nor turn the velocity down
            peak = v0 + a0 * t - jerk * t * t / 2.0
            if peak > top * (1.0 + 1e-12):
                raise Infeasible(
                    f"{name}: the velocity passes {peak:.6g} (limits.max_velocity = {top:.6g}) in the time "
                    "limits.max_jerk needs to change the acceleration between the two ends",
                    name,
                )

    @property
    def rest_to_rest(self) -> bool:
        """A displacement is asked (a position move, from and to rest unless ``in_motion``)."""
        return self.displacement is not None

    @property
    def in_motion(self) -> bool:
        """The move starts or ends with the motor moving (initial_state, final_state)."""
        return self.initial_state.moving or self.final_state.moving

    def rigid_move(
        self, max_velocity: float | None, max_acceleration: float | None, max_jerk: float | None
    ) -> RigidMove:
        """Ruckig's rigid optimum of this move (its states included) within the limits given (ValueError if
        Ruckig finds none)."""
        start, end = self.initial_state, self.final_state
        return rigid_move(
            abs(self.move) if not self.in_motion else self.move,
            self.rest_to_rest,
            max_velocity,
            max_acceleration,
            max_jerk,
            current_velocity=start.velocity,
            current_acceleration=start.acceleration,
            target_velocity=end.velocity,
            target_acceleration=end.acceleration,
        )

    @property
    def move_field(self) -> str:
        return "displacement" if self.rest_to_rest else "target_velocity"

    @property
    def move(self) -> float:
        """The signed move: displacement (rest-to-rest) or final velocity (rest-to-velocity)."""
        value = self.displacement if self.displacement is not None else self.target_velocity
        return float(value) if value is not None else 0.0

    @property
    def load_move(self) -> float:
        """How far the load goes (or how fast it ends up moving): the scale of every relative residual."""
        return self.plant.load_move(self.move)

    @property
    def vibration_window(self) -> float | None:
        """The settling bound on the load's vibration envelope (load units; velocity units for a
        rest-to-velocity move): ``settling.vibration_tolerance``, else 1 % of the quasi-static deflection
        of the lowest mode under the acceleration limit, a / w_n^2 (a / w_n in velocity), else 1e-3 of
        the load's move. None for a plant without a vibration mode."""
        if self.settling.vibration_tolerance is not None:
            return self.settling.vibration_tolerance
        modes = self.plant.modes()
        if not modes:
            return None
        accel = self.acceleration_limit
        if accel is None:
            return VIBRATION_FRACTION_OF_MOVE * self.load_move
        omega = min(m.natural_frequency_rad_s for m in modes)
        deflection = accel / omega**2 if self.rest_to_rest else accel / omega
        return VIBRATION_FRACTION_OF_DEFLECTION * self.plant.load_move(1.0) * deflection

    @property
    def slowest_period_s(self) -> float:
        modes = self.plant.modes()
        return max(m.natural_period_s for m in modes) if modes else 0.0

    @property
    def acceleration_limit(self) -> float | None:
        """max_acceleration, lowered on a two-inertia plant by a torque limit to M / (J_M + J_L) (Cusimano eq. 19)."""
        candidates = [self.limits.max_acceleration] if self.limits.max_acceleration is not None else []
        inertias = self.plant.torque_inertias()
        if self.limits.max_torque_nm is not None and inertias is not None:
            candidates.append(self.limits.max_torque_nm / sum(inertias))
        return min(candidates) if candidates else None

    @functools.cached_property
    def rigid_reference(self) -> PiecewiseCommand:
        """The unshaped rigid command under the same limits: the time-optimal move at the acceleration limit
        (bang-bang, or a trapezoidal velocity at ``max_velocity``; jerk limits ignored), or without an
        acceleration limit the step itself (of position, or of velocity for rest-to-velocity). The reference of
        every percentage vibration (optim.synthesis.percentage_vibration)."""
        move, accel, top = abs(self.move), self.acceleration_limit, self.limits.max_velocity
        if accel is None:
            derivatives = [[0.0, move]] if self.rest_to_rest else [[0.0, 0.0], [0.0, move]]
            return PiecewiseCommand.from_derivatives([0.0, 1.0], derivatives)
        if not self.rest_to_rest:
            return PiecewiseCommand.from_held_steps([0.0, move / accel], [accel, 0.0], 2)
        ramp_s = math.sqrt(move / accel)
        if top is not None and accel * ramp_s > top:
            ramp_s = top / accel
            cruise_s = move / top - ramp_s
            return PiecewiseCommand.from_held_steps(
                [0.0, ramp_s, ramp_s + cruise_s, 2 * ramp_s + cruise_s], [accel, 0.0, -accel, 0.0], 2
            )
        return PiecewiseCommand.from_held_steps([0.0, ramp_s, 2 * ramp_s], [accel, -accel, 0.0], 2)

    @functools.cached_property
    def rigid_minimum_s(self) -> float | None:
        """The rigid machine's minimum time within every limit, the jerk's included (Ruckig's time-optimal
        move; a torque limit as the acceleration M / (J_M + J_L)); None without an acceleration or jerk bound."""
        if self.acceleration_limit is None and self.limits.max_jerk is None:
            return None
        lim = self.limits
        try:
            move = self.rigid_move(lim.max_velocity, self.acceleration_limit, lim.max_jerk)
        except ValueError:  # limits too far apart for Ruckig even scaled (models.rigid_motion): not known
            return None
        return move.duration_s

    def kinematic_floor_s(self) -> float:
        """A closed-form floor on the duration of any rest-to-rest move (or acceleration phase) within the limits,
        each limit alone (D / V, 2 sqrt(D / A), (32 D / J)^(1/3)); rigid_floor_s is the exact one. 0 for a move
        in motion (these forms assume rest at both ends)."""
        if self.in_motion:
            return 0.0
        lim = self.limits
        accel = self.acceleration_limit
        d = abs(self.move)
        if self.rest_to_rest:
            floors = [d / lim.max_velocity] if lim.max_velocity else []
            floors += [2 * math.sqrt(d / accel)] if accel else []
            floors += [(32 * d / lim.max_jerk) ** (1 / 3)] if lim.max_jerk else []
        else:
            floors = [d / accel] if accel else []
            floors += [2 * math.sqrt(d / lim.max_jerk)] if lim.max_jerk else []
        return max(floors, default=0.0)

    @functools.cached_property
    def rigid_floor_s(self) -> float:
        """The least duration any command can have within the limits: the motor's rigid optimum within its own
        velocity, acceleration and jerk limits (Ruckig: the motor is at rest, or at the target speed, at both ends
        whatever the plant), and with a torque limit the centre of mass's move under M / (J_M + J_L) whatever the
        motor does (in kinematic_floor_s)."""
        lim = self.limits
        floor = self.kinematic_floor_s()
        if self.in_motion and self.acceleration_limit != lim.max_acceleration:
            floor = max(floor, self._centre_of_mass_floor_s())
        if lim.max_acceleration is None and lim.max_jerk is None:
            return floor
        try:
            move = self.rigid_move(lim.max_velocity, lim.max_acceleration, lim.max_jerk)
        except ValueError:  # Ruckig refuses limits too far apart: the closed-form floor still holds
            return floor
        return max(floor, move.duration_s)

    def _centre_of_mass_floor_s(self) -> float:
        """A move in motion under a torque limit: the centre of mass, whose acceleration is the torque over
        J_M + J_L, moves D from v0 to vf (the load quasi-static at both ends moves with the motor), no faster than
        Ruckig's rigid optimum at M / (J_M + J_L) with no other limit; 0 where the ends accelerate (the centre's
        acceleration may then jump) or Ruckig finds none."""
        start, end, accel = self.initial_state, self.final_state, self.acceleration_limit
        if start.acceleration or end.acceleration or accel is None:
            return 0.0
        try:
            return rigid_move(
                self.move, True, None, accel, None, current_velocity=start.velocity, target_velocity=end.velocity
            ).duration_s
        except ValueError:
            return 0.0


def nice_period(span_s: float, samples: int = DEFAULT_SAMPLES) -> float:
    """A round sample period (1, 2 or 5 times a power of ten) giving about ``samples`` over ``span_s``
    (never more), and never below 1 microsecond."""
    raw = max(span_s / samples, MIN_SAMPLE_PERIOD_S)
    exponent = math.floor(math.log10(raw))
    for mantissa in (1.0, 2.0, 5.0, 10.0):
        if mantissa * 10.0**exponent >= raw * (1 - 1e-12):
            return mantissa * 10.0**exponent
    return 10.0 ** (exponent + 1)
