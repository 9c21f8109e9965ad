"""Request and response of POST /v1/programs: several axes, a cycle of moves, plants that change with position."""

from __future__ import annotations

from typing import Annotated, Any, ClassVar, Literal

from pydantic import Field

from app.family_names import FamilyName, FamilySlug, name_of
from app.schemas.common import OutModel, StrictModel
from app.schemas.family import LimitsIn, SolverOut
from app.schemas.plants import PlantIn, to_plant
from app.schemas.simulate import MetricsOut, SettlingIn
from app.settings import Settings
from models.errors import InvalidParameter
from optim.problem import MAX_MOVE, Limits, SettlingCriteria
from optim.programs import PlantTable, Program, ProgramAxis, ProgramMove, TablePoint, positions
from optim.programs.types import MAX_AXES, MAX_DWELL_S, MAX_MOVES, MAX_TABLE_POINTS, TABLE_KINDS, check_axes

AXIS_NAME = r"^[A-Za-z_][A-Za-z0-9_]{0,31}$"
Position = Annotated[float, Field(ge=-MAX_MOVE, le=MAX_MOVE)]


class TablePointIn(StrictModel):
    at: float = Field(ge=-MAX_MOVE, le=MAX_MOVE, description="The coordinate's value (its axis's position).")
    plant: PlantIn = Field(description=f"The axis's plant there: {' or '.join(TABLE_KINDS)}, every point one kind.")


class PlantTableIn(StrictModel):
    """The axis's plant as a function of an axis's position (another's, or its own) or of a parameter set per move
    (a payload's mass): between two points every parameter is interpolated linearly; every value the coordinate
    takes must lie within the table."""

    coordinate: str = Field(
        pattern=AXIS_NAME, description="The axis whose position the plant depends on, or a parameter's name."
    )
    points: list[TablePointIn] = Field(
        min_length=2, max_length=MAX_TABLE_POINTS, description="Strictly increasing in `at`."
    )


class ProgramAxisIn(StrictModel):
    name: str = Field(pattern=AXIS_NAME, description="The axis's name, as the targets and the answer use it.")
    plant: PlantIn | None = Field(None, description="The axis's plant (motor command to load); or plant_table.")
    limits: LimitsIn = Field(
        default_factory=LimitsIn, description="Hard limits on the axis's motor command (its own units)."
    )
    plant_table: PlantTableIn | None = Field(
        None, description="The plant over a coordinate (a position-dependent mode); replaces plant."
    )


class ProgramMoveIn(StrictModel):
    target: dict[str, Position] = Field(description="Where every axis goes: one position per axis, by name.")
    coordination: Literal["straight_line", "synchronized", "independent"] = Field(
        "synchronized",
        description="straight_line: one path parameter, each axis's limits projected on the direction, every "
        "moving axis's modes cancelled on it; synchronized: each axis its own design, all starting and arriving "
        "together; independent: each axis its own design from the move's start.",
    )
    dwell_s: float = Field(0.0, ge=0.0, le=MAX_DWELL_S, description="Time spent at the stop after the move, s.")
    parameters: dict[Annotated[str, Field(pattern=AXIS_NAME)], Position] | None = Field(
        None,
        max_length=8,
        description="New values of a plant_table's coordinates that are no axis (a payload's mass), from this move "
        "on: what was picked or placed at the stop before it.",
    )
    still_at_stop: bool = Field(
        True,
        description="The load of every axis must be still at the stop (its modes cancelled); false: the rigid "
        "time-optimal move (Ruckig), the load rings on into the next moves.",
    )


class ProgramIn(StrictModel):
    """A cycle of moves of several axes, each designed by a family from rest at one stop to rest at the next."""

    axes: list[ProgramAxisIn] = Field(min_length=1, max_length=MAX_AXES)
    start: dict[str, Position] = Field(description="Where every axis starts: one position per axis.")
    moves: list[ProgramMoveIn] = Field(min_length=1, max_length=MAX_MOVES)
    parameters: dict[Annotated[str, Field(pattern=AXIS_NAME)], Position] = Field(
        default_factory=dict,
        max_length=8,
        description="A plant_table's coordinates that are no axis (a payload's mass, a rope length set per move), "
        "as they are at the start; a move's parameters change them from that move on.",
    )
    family: FamilySlug | FamilyName = Field("time-optimal", description="The family that designs every move.")
    settling: SettlingIn = Field(default_factory=SettlingIn)
    sample_period_s: float | None = Field(
        None, ge=1e-5, le=10, description="Period of the returned series (default: about 2000 samples a cycle)."
    )
    compare: bool = Field(True, description="Also run the recipes of `comparison` (Ruckig shaped; firmware).")

    UNSCHEMED_RULES: ClassVar[tuple[str, ...]] = (
        "axes[].name unique; start and every moves[].target name every axis once; a plant_table's coordinate "
        "names an axis, its points strictly increasing in at, all mode or all two_inertia plants, and every "
        "position its coordinate takes within its range; each axis has plant or plant_table.",
        "The moves' durations times the fastest frequency of any plant_table: at most 20000 periods (the true "
        "plant's simulation, bounded in work).",
    )

    @property
    def family_key(self) -> str:
        return name_of(self.family)

    def to_program(self, settings: Settings) -> Program:
        axes = tuple(self._axis(i, a) for i, a in enumerate(self.axes))
        names = tuple(a.name for a in axes)
        given = [*self.parameters, *(n for m in self.moves for n in (m.parameters or {}))]
        check_axes(axes, tuple(dict.fromkeys(given)))
        moves = tuple(
            ProgramMove(
                positions(m.target, names, f"moves[{k}].target"),
                m.coordination,
                float(m.dwell_s),
                m.still_at_stop,
                tuple((n, float(v)) for n, v in (m.parameters or {}).items()),
            )
            for k, m in enumerate(self.moves)
        )
        return Program(
            axes=axes,
            start=positions(self.start, names, "start"),
            moves=moves,
            family=self.family_key,
            settling=SettlingCriteria(self.settling.position_tolerance, self.settling.vibration_tolerance),
            solver=settings.solve_caps,
            max_samples=settings.max_samples,
            sample_period_s=self.sample_period_s,
            parameters=tuple((n, float(v)) for n, v in self.parameters.items()),
        )

    @staticmethod
    def _axis(i: int, axis: ProgramAxisIn) -> ProgramAxis:
        lim = axis.limits
        limits = Limits(lim.max_velocity, lim.max_acceleration, lim.max_jerk, lim.max_torque_nm)
        table = None
        if axis.plant_table is not None:
            points = []
            for j, point in enumerate(axis.plant_table.points):
                plant = _plant(point.plant, f"axes[{i}].plant_table.points[{j}].plant")
                points.append(TablePoint(float(point.at), plant))
            table = PlantTable(axis.plant_table.coordinate, tuple(points))
        if axis.plant is None and table is None:
            raise InvalidParameter(f"axes[{i}].plant", None, "give plant or plant_table")
        plant = _plant(axis.plant, f"axes[{i}].plant") if axis.plant is not None else table.points[0].plant  # type: ignore[union-attr]
        return ProgramAxis(axis.name, plant, limits, table)


def _plant(schema: Any, where: str) -> Any:
    try:
        return to_plant(schema)
    except InvalidParameter as exc:
        raise InvalidParameter(f"{where}.{exc.field}", exc.value, exc.rule) from None


class PathOut(OutModel):
    length: float = Field(description="|target - stop| over the moving axes (the path parameter's move).")
    direction: dict[str, float] = Field(description="u_i: each moving axis's share of the path.")
    max_velocity: float | None = Field(description="The path's limits: the least of limit_i / |u_i|.")
    max_acceleration: float | None
    max_jerk: float | None
    modes_hz: list[float] = Field(description="The modes the path's design cancels (every moving axis's).")


class VaryingOut(OutModel):
    iterations: int = Field(description="Newton steps on the effective modes.")
    designs: int = Field(description="Designs of the move it took (each from the previous one's structure).")
    residual: float | None = Field(
        description="The largest residual left on the true plant, of the axis's move (null: no design near the "
        "first could be made)."
    )
    converged: bool


class MoveAxisOut(OutModel):
    design: dict[str, Any] | None = Field(description="The family's design block (the path's on a straight line).")
    metrics: MetricsOut | None = Field(
        description="The axis's command simulated on the plant it was designed for (for an effective mode: the plant "
        "at the stop, time-invariant), from rest at the stop; stop_residual_* are the true plant's."
    )
    solver: SolverOut | None = None
    stop_residual_amplitude: float = Field(
        description="The load's free vibration at the stop in the cycle (load units): carried vibration included, "
        "on the true, position-dependent plant for a plant_table."
    )
    stop_residual_fraction: float | None = Field(description="The same over the axis's move (null: it stays).")
    settling_time_s: float | None = Field(
        description="From the move's start until this axis's load has settled (the metrics' criteria): for a "
        "plant_table, on the true plant over the cycle (the load during the move, its free vibration from the stop "
        "on the plant there), else the metrics' own; null where the axis stays or its load never settles."
    )
    band_hz: list[float] | None = Field(description="The band of the mode's frequency over the move (a table).")
    effective_mode: dict[str, float] | None = Field(
        description="A varying plant: the mode (natural_frequency_hz, damping_ratio) the design is made for, which "
        "leaves the true plant still (its damping ratio may be negative: a falling frequency feeds the vibration)."
    )
    stretched_from_s: float | None = Field(description="synchronized: the axis's own duration, before stretching.")


class MoveOut(OutModel):
    index: int
    start_s: float = Field(description="When the move starts in the cycle.")
    duration_s: float
    dwell_s: float
    settling_time_s: float | None = Field(
        description="From the move's start until every axis's load has settled: the latest of the axes' "
        "settling_time_s (for a plant_table, on the true plant); null where the load need not be still."
    )
    coordination: str
    still_at_stop: bool
    path: PathOut | None = None
    varying: VaryingOut | None = None
    axes: dict[str, MoveAxisOut]


class AxisSeriesOut(OutModel):
    profile: dict[str, list[float]] = Field(description="time_s, position, velocity, acceleration, jerk.")
    load: dict[str, list[float]] = Field(description="time_s, position, velocity, acceleration.")
    stop_residual_method: str = Field(
        description="exact (time-invariant closed form) or varying (the true plant integrated, DOP853 at 1e-12)."
    )


class RecipeRowOut(OutModel):
    method: str
    cycle_time_s: float | None = Field(description="null: the recipe has no answer here (reason).")
    cycle_time_ratio: float | None = Field(description="The recipe's cycle time over the program's.")
    max_stop_residual_fraction: float | None = Field(description="The largest residual it leaves at a still stop.")
    description: str
    reason: str | None = Field(None, description="Why the recipe has no answer (Ruckig refused the limits).")


class ProgramOut(OutModel):
    cycle_time_s: float = Field(description="The moves and their dwells end to end, s.")
    moves: list[MoveOut]
    axes: dict[str, AxisSeriesOut]
    comparison: list[RecipeRowOut] = Field(description="The same program by each recipe, run through the same checks.")
    warnings: list[str]


__all__ = ["ProgramIn", "ProgramOut"]
