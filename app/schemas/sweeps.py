"""POST /v1/sweeps: the request (a family, a base request, axes) and one schema per NDJSON line of the answer."""

from __future__ import annotations

from typing import Annotated, Any, ClassVar, Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from app.family_names import FamilySlug, name_of
from app.schemas.common import INTEGRAL, Int, OutModel, StrictModel, is_value, leaf, never
from app.schemas.plants import PLANT_KINDS

MAX_AXES = 4
MAX_AXIS_VALUES = 1000  # per axis (the default point cap); bounds the body too
PATH_PATTERN = r"^[A-Za-z_][A-Za-z0-9_]*(\[[0-9]+\])?(\.[A-Za-z_][A-Za-z0-9_]*(\[[0-9]+\])?)*$"
DEFAULT_THRESHOLD_PERCENT = 5.0
MAX_REFINED_POINTS = 1000
RANGE = ("start", "stop", "num")


class AxisIn(StrictModel):
    """One axis of the sweep: a numeric field of the base request, by its path, and its values: a list, or a range
    of ``num`` values from ``start`` to ``stop`` inclusive (numpy's linspace, or geomspace with scale log)."""

    path: str = Field(
        min_length=1,
        max_length=200,
        pattern=PATH_PATTERN,
        description="Dotted path of a numeric field of the base request: plant.natural_frequency_hz, "
        "plant.load_inertia_kgm2, limits.max_acceleration, displacement, plant.modes[0].natural_frequency_hz ...",
    )
    values: list[float] | None = Field(
        None, min_length=1, max_length=MAX_AXIS_VALUES, description="The values, strictly increasing."
    )
    start: float | None = Field(None, description="First value of a range (with stop and num).")
    stop: float | None = Field(None, description="Last value of a range, included (> start).")
    num: Annotated[int, Field(ge=1, le=MAX_AXIS_VALUES), INTEGRAL] | None = Field(
        None, description="Values in the range, both ends included."
    )
    scale: Literal["linear", "log"] = Field(
        "linear",
        description="Spacing of a range (log: geometric, for frequencies and inertias; positive ends) and the "
        "midpoint refinement bisects at (arithmetic, or geometric).",
    )

    UNSCHEMED_RULES: ClassVar[tuple[str, ...]] = (
        "axes[].values strictly increasing; axes[].stop greater than axes[].start (unless num is 1).",
        "axes: each axis its own path, a numeric field of the base request.",
    )

    @classmethod
    def schema_rules(cls) -> list[dict[str, Any]]:
        """values, or start, stop and num (``_one_kind``); a log axis has positive values, or start > 0."""
        absent = {"type": "null"}  # in properties: absent or null
        listed = {"required": ["values"], "properties": {"values": {"type": "array"}, **dict.fromkeys(RANGE, absent)}}
        bounds = {"start": {"type": "number"}, "stop": {"type": "number"}, "num": {"type": "integer"}, "values": absent}
        ranged = {"required": list(RANGE), "properties": bounds}
        log = is_value("scale", "log")
        first_not_positive = leaf(
            "values", {"type": "array", "prefixItems": [{"maximum": 0}]}, {"prefixItems": [{"exclusiveMinimum": 0}]}
        )
        start_not_positive = leaf("start", {"type": "number", "maximum": 0}, {"exclusiveMinimum": 0})
        return [
            *super().schema_rules(),
            {"oneOf": [listed, ranged]},
            never(log, first_not_positive),
            never(log, start_not_positive),
        ]

    @model_validator(mode="after")
    def _one_kind(self) -> AxisIn:
        ranged = (self.start, self.stop, self.num)
        if self.values is not None:
            if any(v is not None for v in ranged):
                raise ValueError("give values, or start, stop and num: not both")
            if any(b <= a for a, b in zip(self.values, self.values[1:], strict=False)):
                raise ValueError("values must be strictly increasing (neighbours are consecutive values)")
            if self.scale == "log" and self.values[0] <= 0:
                raise ValueError("a log axis needs positive values")
            return self
        if any(v is None for v in ranged):
            raise ValueError("give values, or start, stop and num")
        assert self.start is not None and self.stop is not None
        if self.num != 1 and self.stop <= self.start:
            raise ValueError("stop must be greater than start")
        if self.scale == "log" and self.start <= 0:
            raise ValueError("a log range needs start > 0")
        return self

    def grid(self) -> list[float]:
        """The axis' values."""
        if self.values is not None:
            return list(self.values)
        assert self.start is not None and self.stop is not None and self.num is not None
        space = np.geomspace if self.scale == "log" else np.linspace
        out = [float(v) for v in space(self.start, self.stop, self.num)]
        out[0] = self.start
        if self.num > 1:
            out[-1] = self.stop  # exactly the ends asked (geomspace rounds them)
        return out

    @property
    def size(self) -> int:
        return len(self.values) if self.values is not None else int(self.num or 0)


class SweepIn(StrictModel):
    """A family, its base request and the axes: one design per point of the axes' Cartesian product."""

    family: FamilySlug = Field(description="The family, by its endpoint's name (/v1/profiles/{family}).")
    request: dict[str, Any] = Field(
        description="The base request, the family endpoint's body; each point is it with the axes' fields set. "
        "Without sensitivity, each point gets compare's grid (0.5..1.5, 201 ratios) so that band_5_percent is known."
    )
    axes: list[AxisIn] = Field(min_length=1, max_length=MAX_AXES, description="One to four axes, distinct paths.")
    threshold_percent: float = Field(
        DEFAULT_THRESHOLD_PERCENT,
        gt=0,
        le=100,
        description="The table check passes a pair of neighbours when each point's design leaves at most this "
        "percentage vibration V on the other's plant (default 5 %: the band_5_percent yardstick).",
    )
    refine: bool = Field(
        False,
        description="Bisect each pair that fails the check (the midpoint along its axis, other coordinates "
        "unchanged), and check both halves, round after round, up to max_refined_points new points.",
    )
    max_refined_points: Int = Field(
        32,
        ge=0,
        le=MAX_REFINED_POINTS,
        description=f"Most points refinement may add (at most {MAX_REFINED_POINTS}; also within the service's "
        "sweep point cap).",
    )

    UNSCHEMED_RULES: ClassVar[tuple[str, ...]] = (
        "request: the fields and types of a /v1/profiles/{family} body (the rules between its fields are each "
        "point's: a point they refuse is a row with ok false and its problem); at most the service's point cap "
        "(VIBFREE_SWEEP_MAX_POINTS) points.",
    )

    @classmethod
    def schema_rules(cls) -> list[dict[str, Any]]:
        # the base request is validated by the family's schema first (app.services.sweeps.SweepPlan): it needs a
        # plant, an object tagged by its kind
        plant = {"type": "object", "required": ["kind"], "properties": {"kind": {"enum": list(PLANT_KINDS)}}}
        return [
            *super().schema_rules(),
            {"properties": {"request": {"required": ["plant"], "properties": {"plant": plant}}}},
        ]

    @field_validator("axes")
    @classmethod
    def _distinct(cls, axes: list[AxisIn]) -> list[AxisIn]:
        paths = [a.path for a in axes]
        if len(set(paths)) != len(paths):
            raise ValueError("each axis needs its own path")
        return axes

    @property
    def family_key(self) -> str:
        return name_of(self.family)

    @property
    def points(self) -> int:
        return int(np.prod([a.size for a in self.axes], dtype=object))


# --- the NDJSON lines ------------------------------------------------------------------------------


class SolverLine(OutModel):
    status: str
    iterations: int = Field(description="Iterations over all the point's solves.")
    solves: int = Field(description="Solves run for the point (a duration search runs several).")


class RowLine(OutModel):
    """One point, as it finishes (lines come in completion order: sort by index). Its numbers are the family
    endpoint's for the point's request (metrics, sensitivity.band_5_percent, solver)."""

    line: Literal["row"]
    index: int = Field(
        description="The point: the axes' Cartesian product first (the first axis varying slowest), "
        "then the points refinement added, in the order they were made."
    )
    values: dict[str, float] = Field(description="The point's value on each axis, by path.")
    between: list[int] | None = Field(description="For a point refinement added: the pair it bisects.")
    ok: bool = Field(description="False: the point has no design, problem says why.")
    duration_s: float | None = Field(None, description="metrics.motion_time_s: until the command's last change.")
    settling_time_s: float | None = Field(None, description="metrics.settling_time_s (null: never settles).")
    percentage_vibration: float | None = Field(
        None, description="metrics.percentage_vibration: V at the point's own nominal mode, %."
    )
    residual_amplitude: float | None = Field(None, description="metrics.residual_amplitude, load units.")
    residual_velocity_amplitude: float | None = Field(None, description="metrics.residual_velocity_amplitude.")
    band_5_percent: list[float | None] | None = Field(None, description="sensitivity.band_5_percent.")
    limits_met: bool | None = None
    solver: SolverLine | None = Field(None, description="Where a solver ran (solve_time_s is in elapsed_s).")
    warnings: list[str] | None = None
    elapsed_s: float | None = Field(None, description="Wall time of the point's design in its worker, s.")
    problem: dict[str, Any] | None = Field(
        description="For a point without a design: the problem+json the endpoint answers its request with "
        "(type, title, status, detail, field, errors; fields named as in the point's request)."
    )


class CheckLine(OutModel):
    """One pair of neighbouring points, once both have finished: may the table be interpolated between them?"""

    line: Literal["check"]
    axis: str = Field(description="The axis along which the two points are neighbours.")
    pair: list[int] = Field(description="[a, b]: the two points' indices, a lower on the axis.")
    values: list[float] = Field(description="Their values on that axis.")
    a_at_b_percentage_vibration: float | None = Field(
        description="V of a's command on b's plant, % (the product's percentage vibration at b's first mode)."
    )
    b_at_a_percentage_vibration: float | None = Field(description="V of b's command on a's plant, %.")
    worst_percentage_vibration: float | None
    passes: bool | None = Field(description="worst <= threshold_percent; null if a point failed or has no mode.")


class SummaryLine(OutModel):
    """The last line."""

    line: Literal["summary"]
    points: int = Field(description="Points run, refinement included.")
    failed: int = Field(description="Points without a design.")
    refined: int = Field(description="Points refinement added.")
    pairs: int = Field(description="Pairs checked.")
    pairs_failing: int = Field(description="Pairs of the final table that fail the check.")
    pairs_unchecked: int = Field(description="Pairs of the final table with a failed point.")
    interpolable: bool = Field(description="Every point has a design and every pair of the final table passes.")
    threshold_percent: float
    elapsed_s: float


SweepLine = Annotated[RowLine | CheckLine | SummaryLine, Field(discriminator="line")]
