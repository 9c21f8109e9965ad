"""The request and response vocabulary every profile endpoint and compare share.

A family endpoint parses its body into a ``Problem`` (plant, move, limits, sampling, settling,
sensitivity) and the family's options, runs the one pipeline (``optim.synthesis``) and answers with
the same blocks: ``profile``, ``design``, ``load``, ``metrics``, ``sensitivity``, ``solver``,
``limit_violations`` and ``warnings``. Old field names stay accepted as deprecated aliases: each
use adds a line to ``warnings``.
"""

from __future__ import annotations

from typing import Annotated, Any, ClassVar

import numpy as np
from pydantic import Field, PrivateAttr, model_validator
from pydantic.config import JsonDict

from app.schemas.common import (
    TOLERANCE_MIN,
    DampingRatio,
    Int,
    OutModel,
    StrictModel,
    given,
    limit_given,
    never,
    plant_kind_is,
    present,
)
from app.schemas.drive import DriveIn
from app.schemas.plants import PlantIn, to_plant
from app.schemas.simulate import ClosedLoopOut, LoadOut, MetricsOut, ProfileOut, SettlingIn
from app.settings import Settings
from models.errors import InvalidParameter
from optim.problem import MAX_MOVE, MIN_MOVE, Limits, Problem, SensitivityGrid, SettlingCriteria

MAX_SENSITIVITY_POINTS = 4001
# The smallest limit: a micrometre (or microradian) per second, per s^2, per s^3, a micronewton metre.
LIMIT_MIN = 1e-6
HORIZON_MIN_S = 1e-6
# |move| >= MIN_MOVE (optim.problem): a move field is no number strictly between -MIN_MOVE and MIN_MOVE
NOT_A_TINY_MOVE: JsonDict = {"not": {"type": "number", "exclusiveMinimum": -MIN_MOVE, "exclusiveMaximum": MIN_MOVE}}
# The move of a rest-to-rest family: a displacement, no target_velocity (the family's not_applicable)
REST_TO_REST_ONLY = [given("displacement").holds, given("target_velocity").fails]


class LimitsIn(StrictModel):
    """Bounds on the motor command along the whole motion (Ruckig's max_ names); all optional."""

    max_velocity: float | None = Field(
        None, ge=LIMIT_MIN, le=1e12, description="Largest |motor velocity| (rad/s or m/s), 1e-6 to 1e12."
    )
    max_acceleration: float | None = Field(
        None, ge=LIMIT_MIN, le=1e12, description="Largest |motor acceleration|, 1e-6 to 1e12."
    )
    max_jerk: float | None = Field(None, ge=LIMIT_MIN, le=1e15, description="Largest |motor jerk|, 1e-6 to 1e15.")
    max_torque_nm: float | None = Field(
        None, ge=LIMIT_MIN, le=1e12, description="Largest |motor torque| (two_inertia only), 1e-6 to 1e12 N m."
    )


class SensitivityIn(StrictModel):
    """Where to evaluate the residual vibration versus the true/estimated frequency ratio."""

    frequency_ratios: list[Annotated[float, Field(ge=0.01, le=100)]] | None = Field(
        None,
        min_length=1,
        max_length=MAX_SENSITIVITY_POINTS,
        description="Explicit ratios f_n/f_n,e (each in [0.01, 100]).",
    )
    min_ratio: float = Field(0.5, ge=0.01, le=100, description="Start of a uniform range of ratios (>= 0.01).")
    max_ratio: float = Field(1.5, ge=0.01, le=100, description="End of the range.")
    count: Int = Field(201, ge=2, le=MAX_SENSITIVITY_POINTS, description="Points in the range.")
    damping_ratios: list[DampingRatio] | None = Field(
        None,
        min_length=1,
        max_length=50,
        description="True damping ratios to evaluate (a grid with the ratios); default: the plant's own.",
    )

    UNSCHEMED_RULES: ClassVar[tuple[str, ...]] = (
        "sensitivity.max_ratio must be greater than sensitivity.min_ratio.",
        f"sensitivity: at most {20 * MAX_SENSITIVITY_POINTS} (damping ratio, frequency ratio) points: the damping "
        "ratios times the frequency ratios (frequency_ratios, or count).",
    )

    @model_validator(mode="after")
    def _check(self) -> SensitivityIn:
        if self.max_ratio <= self.min_ratio:
            raise ValueError("max_ratio must be greater than min_ratio")
        if self.frequency_ratios is not None and any(not (0.01 <= r <= 100) for r in self.frequency_ratios):
            raise ValueError("every frequency ratio must lie in [0.01, 100]")
        if self.damping_ratios is not None and any(not (0 <= z < 1) for z in self.damping_ratios):
            raise ValueError("every damping ratio must satisfy 0 <= zeta < 1")
        if self.damping_ratios is not None and len(self.damping_ratios) * self.points > 20 * MAX_SENSITIVITY_POINTS:
            raise ValueError(f"at most {20 * MAX_SENSITIVITY_POINTS} (damping, frequency) points")
        return self

    @property
    def points(self) -> int:
        return len(self.frequency_ratios) if self.frequency_ratios is not None else self.count

    def ratios(self) -> np.ndarray:
        if self.frequency_ratios is not None:
            return np.asarray(self.frequency_ratios, dtype=float)
        return np.linspace(self.min_ratio, self.max_ratio, self.count)


class SensitivityOut(OutModel):
    """Robustness to a wrong natural frequency, in the percentage vibration of the field: V(omega) = 100 x the
    residual amplitude the command leaves on the mode at the true frequency omega = ratio x omega_n (the plant's
    first mode; its damping ratio, or each of damping_ratio), divided by the residual envelope of the unshaped
    rigid command under the same limits at that same mode: sum over its acceleration steps of
    |delta a_k| exp(-sigma (T - t_k)) / (omega omega_d) (4 a_max / omega^2 for an undamped bang-bang move), or,
    without an acceleration limit, the step itself (then V is the classical ratio to the unshaped residual: a
    ZV, ZVD or EI shaper on a step has its textbook curve). Rest-to-velocity moves compare velocities."""

    frequency_ratio: list[float] = Field(description="f_n / f_n,e: true over estimated natural frequency.")
    percentage_vibration: list[float] = Field(description="V, % (5 = 5 %), at the first damping ratio.")
    reference_amplitude: list[float] = Field(
        description="The reference's residual envelope at each ratio (the denominator of V), load units."
    )
    reference: str = Field(description="The reference command V is measured against.")
    residual_amplitude: list[float] = Field(description="The design's residual amplitude at each ratio, load units.")
    residual_vibration: list[float] = Field(
        description="The same residual as a fraction of the move (0.05 = 5 % of the displacement or final speed)."
    )
    quantity: str = Field(description="position (rest-to-rest) or velocity (rest-to-velocity).")
    damping_ratio: list[float] = Field(description="The true damping ratios evaluated.")
    percentage_vibration_grid: list[list[float]] | None = Field(
        None, description="One V curve per damping ratio, when several were asked."
    )
    residual_vibration_grid: list[list[float]] | None = Field(
        None, description="One residual-fraction curve per damping ratio, when several were asked."
    )
    band_5_percent: list[float | None] | None = Field(
        None,
        description="[low, high]: the contiguous ratios around 1 where V <= 5 % (first damping ratio); an end is "
        "null where the band runs past the evaluated ratios; null when V > 5 % at ratio 1.",
    )


# Fields the family cores still name in their own (older) words, and the request's name for them.
CORE_FIELD_NAMES = {
    "max_acceleration": "limits.max_acceleration",
    "max_torque_nm": "limits.max_torque_nm",
    "acceleration_limit": "limits.max_acceleration",
    "cruise_velocity": "limits.max_velocity",
}


def _deprecated(old: str, new: str) -> str:
    return f"{old} is deprecated: use {new} (same meaning)"


class ProfileRequest(StrictModel):
    """The uniform vocabulary: plant, move, limits, sampling, settling, sensitivity; then the family's own
    options. Subclasses list their legacy fields in ``LEGACY_LIMITS`` (old name -> limits field)."""

    LEGACY_LIMITS: ClassVar[dict[str, str]] = {}

    plant: PlantIn
    displacement: float | None = Field(
        None,
        ge=-MAX_MOVE,
        le=MAX_MOVE,
        description=f"Rest-to-rest: the signed motor displacement (rad or m), {MIN_MOVE:g} <= |displacement| <= "
        f"{MAX_MOVE:g}.",
        json_schema_extra=NOT_A_TINY_MOVE,
    )
    target_velocity: float | None = Field(
        None,
        ge=-MAX_MOVE,
        le=MAX_MOVE,
        description=f"Rest-to-velocity: the signed final motor velocity (rad/s or m/s), {MIN_MOVE:g} <= "
        f"|target_velocity| <= {MAX_MOVE:g}. Give this or displacement.",
        json_schema_extra=NOT_A_TINY_MOVE,
    )
    limits: LimitsIn = Field(
        default_factory=LimitsIn, description="max_velocity is also the cruise speed of a rest-to-rest move."
    )
    sample_period_s: float | None = Field(
        None,
        ge=1e-6,
        le=10,
        description="Period of the returned series, s (corners kept). Default: about 2000 samples over the horizon, "
        "rounded to 1, 2 or 5 times a power of ten.",
    )
    horizon_s: float | None = Field(
        None,
        ge=HORIZON_MIN_S,
        le=1e6,
        description="End of the returned series, s (>= the command's end). Default: the command's end plus 5 natural "
        "periods of the slowest mode.",
    )
    settling: SettlingIn = Field(default_factory=SettlingIn)
    drive: DriveIn | None = Field(
        None,
        description="The servo that executes the command: the answer gains ``closed_loop``, what the motor and the "
        "load do through it (``load`` and ``metrics`` stay the ideal motor's). Not with a closed_loop plant, whose "
        "prediction is already through its drive.",
    )
    sensitivity: SensitivityIn | None = Field(
        None, description="Percentage vibration versus f_n/f_n,e (see SensitivityOut), when asked."
    )
    allow_limit_violation: bool = Field(
        False,
        description="Limits are hard: a design whose samples break a limit (beyond 1e-9 relative) is a 422 "
        "/problems/infeasible. With true, it is returned instead, with limits_met false and the violations listed.",
    )
    settling_tolerance: float | None = Field(
        None, ge=TOLERANCE_MIN, le=1, deprecated=_deprecated("settling_tolerance", "settling.position_tolerance")
    )

    _deprecations: list[str] = PrivateAttr(default_factory=list)
    _aliases: dict[str, str] = PrivateAttr(default_factory=dict)  # new field -> the legacy field the caller used

    MOVE_FIELD: ClassVar[str] = "displacement"  # the field a missing move is reported under
    UNSCHEMED_RULES: ClassVar[tuple[str, ...]] = (
        "A deprecated field that names a limit (see each field) must equal the limits field it stands for when both "
        "are given.",
        "sample_period_s: the returned series (horizon_s / sample_period_s samples) must not exceed the service's "
        "sample cap (VIBFREE_MAX_SAMPLES); the answer names the smallest period that fits. horizon_s: at least the "
        "command's end.",
        "limits.max_torque_nm: M / (J_M + J_L) at least 1e-9.",
        "drive: not with a closed_loop plant (its prediction is already through its drive).",
    )

    @classmethod
    def schema_rules(cls) -> list[dict[str, Any]]:
        # Each rule here is in every family's schema: schemathesis gives up on an operation whose rules multiply
        # to more than about 100 alternatives (tests/app/test_schema_rules.py builds a strategy for each).
        return [
            *super().schema_rules(),
            *cls.move_rules(),
            # settling_tolerance is the deprecated settling.position_tolerance: not beside settling
            never(given("settling_tolerance"), present("settling")),
            # only a two_inertia plant defines the motor torque (optim.problem.Problem)
            never(limit_given("max_torque_nm"), ~plant_kind_is("two_inertia")),
        ]

    @classmethod
    def move_rules(cls) -> list[dict[str, Any]]:
        """Exactly one of displacement (rest-to-rest) and target_velocity (rest-to-velocity): ``_resolved``."""
        return [{"oneOf": [given("displacement").holds, given("target_velocity").holds]}]

    def _resolved(self) -> tuple[LimitsIn, SettlingIn, float | None, float | None]:
        """Legacy fields folded into the uniform ones (recording each use), and the move checked; a
        break is an InvalidParameter naming the field."""
        raw = self.__dict__  # reads deprecated fields without their access warning
        notes: list[str] = []
        aliases: dict[str, str] = {}
        settling = self.settling
        if raw.get("settling_tolerance") is not None:
            if "settling" in self.model_fields_set:
                raise InvalidParameter(
                    "settling_tolerance", raw["settling_tolerance"], "give settling.position_tolerance only"
                )
            settling = SettlingIn(position_tolerance=raw["settling_tolerance"])
            notes.append(_deprecated("settling_tolerance", "settling.position_tolerance"))
            aliases["settling.position_tolerance"] = "settling_tolerance"
        updates: dict[str, float] = {}
        for old, new in self.LEGACY_LIMITS.items():
            value = raw.get(old)
            if value is None:
                continue
            current = getattr(self.limits, new)
            if current is not None and current != value:
                raise InvalidParameter(
                    f"limits.{new}", current, f"disagrees with the deprecated {old} = {value:g}: give limits.{new} only"
                )
            updates[new] = value
            notes.append(_deprecated(old, f"limits.{new}"))
            aliases[f"limits.{new}"] = old
        self._aliases = aliases  # so that an error about a legacy move field is named as sent
        displacement, target = self._legacy_move(updates, notes, aliases)
        if (displacement is None) == (target is None):
            raise InvalidParameter(
                self.MOVE_FIELD if target is None else "target_velocity",
                target,
                "give exactly one of displacement (rest-to-rest) or target_velocity (rest-to-velocity)",
            )
        self._deprecations, self._aliases = notes, aliases
        return self.limits.model_copy(update=updates), settling, displacement, target

    def _legacy_move(
        self, updates: dict[str, float], notes: list[str], aliases: dict[str, str]
    ) -> tuple[float | None, float | None]:
        """(displacement, target_velocity); a family whose old body gave the cruise speed beside the
        displacement folds it into ``updates`` here."""
        return self.displacement, self.target_velocity

    def options(self, problem: Problem) -> Any:
        """The family's options from this request's own fields."""
        raise NotImplementedError

    @property
    def deprecations(self) -> list[str]:
        """One warning per deprecated field used (known once ``to_problem`` has run)."""
        return list(self._deprecations)

    def caller_field(self, field: str | None) -> str | None:
        """The name the caller used for a field: the uniform name of a core field, or the legacy alias
        where the caller used one."""
        if field is None:
            return None
        uniform = CORE_FIELD_NAMES.get(field, field)
        return self._aliases.get(uniform, uniform)

    def to_problem(self, settings: Settings) -> Problem:
        lim, settling, displacement, target = self._resolved()
        grid = None
        if self.sensitivity is not None:
            s = self.sensitivity
            grid = SensitivityGrid(
                tuple(float(r) for r in s.ratios()),
                tuple(s.damping_ratios) if s.damping_ratios else None,
                explicit=s.frequency_ratios is not None,
            )
        return Problem(
            plant=to_plant(self.plant),
            displacement=displacement,
            target_velocity=target,
            limits=Limits(lim.max_velocity, lim.max_acceleration, lim.max_jerk, lim.max_torque_nm),
            sample_period_s=self.sample_period_s,
            horizon_s=self.horizon_s,
            settling=SettlingCriteria(settling.position_tolerance, settling.vibration_tolerance),
            allow_limit_violation=self.allow_limit_violation,
            sensitivity=grid,
            max_samples=settings.max_samples,
            solver=settings.solve_caps,
        )

    def common_body(self) -> dict[str, Any]:
        """The uniform part of this request in the new vocabulary (for compare's rows[].request)."""
        limits, settling, displacement, target = self._resolved()
        body: dict[str, Any] = {"plant": self.plant.model_dump()}
        if displacement is not None:
            body["displacement"] = displacement
        else:
            body["target_velocity"] = target
        if limits.model_dump(exclude_none=True):
            body["limits"] = limits.model_dump(exclude_none=True)
        for name in ("sample_period_s", "horizon_s"):
            if getattr(self, name) is not None:
                body[name] = getattr(self, name)
        body["settling"] = settling.model_dump(exclude_none=True)
        if self.allow_limit_violation:
            body["allow_limit_violation"] = True
        if self.sensitivity is not None:
            body["sensitivity"] = self.sensitivity.model_dump(exclude_none=True)
        return body


class SolverOut(OutModel):
    status: str = Field(description="The solver's status of the solve that produced the design.")
    iterations: int = Field(description="Iterations over all solves.")
    solve_time_s: float = Field(description="Wall time of the solves, s.")
    solves: int = Field(description="Solves run for this design (a duration search runs several).")


class FamilyResponse(OutModel):
    profile: ProfileOut
    design: dict[str, Any]
    load: LoadOut
    metrics: MetricsOut
    sensitivity: SensitivityOut | None = None
    solver: SolverOut | None = Field(None, description="Where a solver ran: its status, iterations and time.")
    limits_met: bool = Field(True, description="False only when allow_limit_violation let a violating design through.")
    limit_violations: list[str] = Field(
        default_factory=list,
        description="Every requested limit the command breaks (only with allow_limit_violation; also in warnings).",
    )
    warnings: list[str] = Field(default_factory=list)
    closed_loop: ClosedLoopOut | None = Field(None, description="With ``drive``: the design through it.")


__all__ = [
    "FamilyResponse",
    "LimitsIn",
    "ProfileRequest",
    "SensitivityIn",
    "SensitivityOut",
    "SettlingIn",
    "SolverOut",
]
