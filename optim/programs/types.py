"""A machine program in the core's own terms: axes (each a plant, limits and optionally a plant table over a
coordinate), where the axes start, and the moves between stops (optim.programs).

Axes keep their order everywhere: a target, a start and a position are tuples in the axes' order; the names are
the caller's (``Program.build`` maps a ``{axis: value}`` request onto that order and names what does not fit).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

from models.errors import InvalidParameter
from models.plants import Plant
from optim.problem import MAX_MOVE, Limits, SettlingCriteria
from optim.solver import SolveCaps

Coordination = Literal["straight_line", "synchronized", "independent"]
COORDINATIONS: tuple[Coordination, ...] = ("straight_line", "synchronized", "independent")
MAX_AXES = 8
MAX_MOVES = 200
MAX_TABLE_POINTS = 64
MAX_DWELL_S = 1e4
# The kinds a plant table holds: one spring and damper whose parameters may follow the coordinate, so that the
# time-varying plant has one meaning (optim.programs.tables, models.varying_mode)
TABLE_KINDS = ("mode", "two_inertia")


@dataclass(frozen=True)
class TablePoint:
    """The axis's plant where the table's coordinate is ``at``."""

    at: float
    plant: Plant


@dataclass(frozen=True)
class PlantTable:
    """An axis's plant as a function of another axis's position (or its own): ``points`` strictly increasing in
    ``at``, each a plant of the same kind; between two points every parameter is interpolated linearly
    (optim.programs.tables)."""

    coordinate: str
    points: tuple[TablePoint, ...]

    @property
    def low(self) -> float:
        return self.points[0].at

    @property
    def high(self) -> float:
        return self.points[-1].at


@dataclass(frozen=True)
class ProgramAxis:
    """One axis: its plant (or its plant table), its limits (Ruckig's max_ names, the axis's motor units)."""

    name: str
    plant: Plant
    limits: Limits
    table: PlantTable | None = None


@dataclass(frozen=True)
class ProgramMove:
    """A move to ``target`` (one position per axis), then ``dwell_s`` at the stop. ``still_at_stop``: the load of
    every axis must be still there (its modes cancelled); otherwise the move is the rigid time-optimal one."""

    target: tuple[float, ...]
    coordination: Coordination = "synchronized"
    dwell_s: float = 0.0
    still_at_stop: bool = True
    parameters: tuple[tuple[str, float], ...] = ()  # values from this move on (a payload picked at the stop before)


@dataclass(frozen=True)
class Program:
    axes: tuple[ProgramAxis, ...]
    start: tuple[float, ...]
    moves: tuple[ProgramMove, ...]
    family: str = "time_optimal"
    settling: SettlingCriteria = field(default_factory=SettlingCriteria)
    solver: SolveCaps = field(default_factory=SolveCaps)
    max_samples: int = 200_000
    sample_period_s: float | None = None  # of the returned series (default: about 2000 samples over the cycle)
    parameters: tuple[tuple[str, float], ...] = ()  # a table's non-axis coordinates at the start (a payload's mass)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(a.name for a in self.axes)

    def stop(self, k: int) -> tuple[float, ...]:
        """Where move ``k`` starts: the start, or the previous move's target."""
        return self.start if k == 0 else self.moves[k - 1].target

    def axis_index(self, name: str) -> int:
        return self.names.index(name)

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """Every parameter the start or a move gives (a table's coordinate that is no axis)."""
        given = [n for n, _ in self.parameters] + [n for m in self.moves for n, _ in m.parameters]
        return tuple(dict.fromkeys(given))

    def parameter(self, k: int, name: str) -> float | None:
        """The parameter's value during move k: the last the move or those before it gave, else the start's."""
        for move in reversed(self.moves[: k + 1]):
            value = dict(move.parameters).get(name)
            if value is not None:
                return value
        return dict(self.parameters).get(name)


def positions(values: Mapping[str, float], names: Sequence[str], field_name: str) -> tuple[float, ...]:
    """``{axis: value}`` in the axes' order: exactly one finite value per axis, else a 422 naming ``field_name``."""
    unknown = [k for k in values if k not in names]
    missing = [n for n in names if n not in values]
    if unknown or missing:
        parts = ([f"unknown axes {', '.join(unknown)}"] if unknown else []) + (
            [f"missing axes {', '.join(missing)}"] if missing else []
        )
        raise InvalidParameter(
            field_name,
            dict(values),
            f"needs exactly one position per axis ({len(names)}: {', '.join(names)}); {'; '.join(parts)}",
        )
    out = []
    for name in names:
        value = float(values[name])
        if not math.isfinite(value) or abs(value) > MAX_MOVE:
            raise InvalidParameter(f"{field_name}.{name}", value, f"must be finite and within +-{MAX_MOVE:g}")
        out.append(value)
    return tuple(out)


def check_axes(axes: Sequence[ProgramAxis], parameters: Sequence[str] = ()) -> None:
    """Unique names; each table's coordinate an axis or a parameter, its points strictly increasing, one kind (a 422
    naming ``axes[i]...``)."""
    if not 1 <= len(axes) <= MAX_AXES:
        raise InvalidParameter("axes", len(axes), f"a program has 1 to {MAX_AXES} axes")
    seen: dict[str, int] = {}
    for i, axis in enumerate(axes):
        if axis.name in seen:
            raise InvalidParameter(f"axes[{i}].name", axis.name, f"names axes[{seen[axis.name]}] already")
        seen[axis.name] = i
    clash = [p for p in parameters if p in seen]
    if clash:
        raise InvalidParameter("parameters", clash[0], "a parameter may not take an axis's name")
    for i, axis in enumerate(axes):
        if axis.table is not None:
            _check_table(axis.table, f"axes[{i}].plant_table", [*seen, *parameters])


def _check_table(table: PlantTable, where: str, names: Sequence[str]) -> None:
    if table.coordinate not in names:
        raise InvalidParameter(
            f"{where}.coordinate", table.coordinate, f"must name an axis or a parameter ({', '.join(names)})"
        )
    if not 2 <= len(table.points) <= MAX_TABLE_POINTS:
        raise InvalidParameter(f"{where}.points", len(table.points), f"a table has 2 to {MAX_TABLE_POINTS} points")
    first = table.points[0].plant
    for j, point in enumerate(table.points):
        if point.plant.kind not in TABLE_KINDS:
            raise InvalidParameter(
                f"{where}.points[{j}].plant.kind",
                point.plant.kind,
                f"a plant table holds {' or '.join(TABLE_KINDS)} plants (one spring and damper whose parameters "
                "may change with the coordinate)",
            )
        if not math.isfinite(point.at) or abs(point.at) > MAX_MOVE:
            raise InvalidParameter(f"{where}.points[{j}].at", point.at, f"must be finite and within +-{MAX_MOVE:g}")
        if j and not point.at > table.points[j - 1].at:
            raise InvalidParameter(
                f"{where}.points[{j}].at",
                point.at,
                f"the table must be strictly increasing in its coordinate (points[{j - 1}].at = "
                f"{table.points[j - 1].at:g})",
            )
        if type(point.plant) is not type(first) or point.plant.symbolic_key() != first.symbolic_key():
            raise InvalidParameter(
                f"{where}.points[{j}].plant",
                point.plant.kind,
                f"every point's plant must be of the first's kind and shape ({first.kind})",
            )


def check_moves(program: Program) -> None:
    """A program has moves; each dwell finite and bounded."""
    if not 1 <= len(program.moves) <= MAX_MOVES:
        raise InvalidParameter("moves", len(program.moves), f"a program has 1 to {MAX_MOVES} moves")
    for k, move in enumerate(program.moves):
        if not (math.isfinite(move.dwell_s) and 0.0 <= move.dwell_s <= MAX_DWELL_S):
            raise InvalidParameter(f"moves[{k}].dwell_s", move.dwell_s, f"must lie in [0, {MAX_DWELL_S:g}] s")
        if move.coordination not in COORDINATIONS:
            raise InvalidParameter(
                f"moves[{k}].coordination", move.coordination, f"must be one of {', '.join(COORDINATIONS)}"
            )
