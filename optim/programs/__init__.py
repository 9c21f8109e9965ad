"""Machine programs: several axes, a cycle of moves between stops, plants that change with position
(optim.programs.types); designed move by move by a family (moves), laid end to end and checked (cycle, run)."""

from optim.programs.run import ProgramResult, assemble, check_program, design_moves, solve_program
from optim.programs.types import (
    COORDINATIONS,
    PlantTable,
    Program,
    ProgramAxis,
    ProgramMove,
    TablePoint,
    positions,
)

__all__ = [
    "COORDINATIONS",
    "PlantTable",
    "Program",
    "ProgramAxis",
    "ProgramMove",
    "ProgramResult",
    "TablePoint",
    "assemble",
    "check_program",
    "design_moves",
    "positions",
    "solve_program",
]
