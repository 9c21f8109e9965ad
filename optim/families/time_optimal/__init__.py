"""The minimum-time command without residual vibration, nominal or robust over a band (a family's core).

``solve(spec)`` returns the arcs of the shortest command found, with exact switching times where a structure
checks out and never longer than the shaped rigid optimum, with a proven lower bound
(optim.families.time_optimal.minimum_time); ``command_of`` turns arcs into the exact
piecewise-polynomial command.
"""

from optim.families.time_optimal.arcs import command_of
from optim.families.time_optimal.minimum_time import solve
from optim.families.time_optimal.types import Arc, Band, GridSolution, Solution, Spec, Torque

__all__ = ["Arc", "Band", "GridSolution", "Solution", "Spec", "Torque", "command_of", "solve"]
