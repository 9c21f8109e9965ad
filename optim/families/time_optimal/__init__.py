"""The minimum-time command without residual vibration, nominal or robust over a band (a family's core).

``solve(spec)`` returns the arcs of the shortest command on the search grid refined to exact switching
times, with a proven lower bound (optim.families.time_optimal.search); ``command_of`` turns arcs into the exact
piecewise-polynomial command.
"""

from optim.families.time_optimal.arcs import command_of
from optim.families.time_optimal.search import solve
from optim.families.time_optimal.types import Arc, Band, GridSolution, Solution, Spec, Torque

__all__ = ["Arc", "Band", "GridSolution", "Solution", "Spec", "Torque", "command_of", "solve"]
