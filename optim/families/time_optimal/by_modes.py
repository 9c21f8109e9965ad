"""Mode by mode: the minimum-time command of n modes from that of its n - 1 lowest, with one reversal added.

With three modes the predicted structures (optim.families.time_optimal.structures: the rigid optimum with one
reversal per mode) converge on 2 of bench/time_optimal_speed.py's 20 three-mode moves, and the LP search then took
100-500 ms a move. The minimum-time command with one more mode is often the one without it plus a reversal pulse of
the added mode (structures.mode_starts, the latest first), or that with one to REPAIRS notches where the switching
function says (repair.next_repair). So the modes are added the lowest first: the k lowest modes' structures with a
reversal of mode k + 1 are solved by Newton on the switching times and the multipliers (shooting.shoot;
refine.newton where the structure has as many arcs as end conditions), each repaired at most REPAIRS times, until
the certificate (optim.families.time_optimal.certify) proves one that meets the limits, else the k + 1 lowest's own
predicted structures are tried (the lowest mode's first); the first count of modes neither proves ends it. That
proves 9 of the 20 three-mode moves, and 12 of its 20 two-mode moves (11 before).

Where the k lowest modes' command is proven but not the whole spec's, that command is a relaxation's minimum (fewer
end conditions): no command of the spec is shorter. Shaped by a ZV at each mode above the k lowest it is a command of
the spec (zero residual at every mode, every limit met: shaped.shaped_command), at most those ZVs' half periods
longer than the minimum: with modes far above the move's bandwidth the gap is 1e-4 of the move or less
(``Relaxed``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

from models.rigid_motion import RigidMove
from optim.families.time_optimal.arcs import merged
from optim.families.time_optimal.candidates import duration_s
from optim.families.time_optimal.certify import Certificate, certificate
from optim.families.time_optimal.refine import newton
from optim.families.time_optimal.repair import next_repair
from optim.families.time_optimal.shaped import as_start, nominal_shaper, shaped_command
from optim.families.time_optimal.shooting import shoot
from optim.families.time_optimal.structures import mode_starts, predicts
from optim.families.time_optimal.types import Arc, Spec

Arcs = tuple[Arc, ...]
Proven = tuple[Arcs, Certificate]


@dataclass(frozen=True)
class Relaxed:
    """The proven minimum-time command of the ``modes`` lowest modes (``bound_s`` long: a lower bound on the
    spec's minimum), and ``arcs``: it shaped by ZV at each mode above them, a command of the spec, or a shorter
    command of the spec within the limits that Newton solved on the way (not proven)."""

    arcs: Arcs
    bound_s: float
    modes: int
    shaped: bool  # arcs are that command shaped; else a shorter command of the spec Newton found on the way

    def describe(self) -> str:
        return (
            f"the proven minimum-time command of the {self.modes} lowest modes (a relaxation: fewer end conditions, "
            "no command of the move is shorter; optim.families.time_optimal.by_modes)"
        )

    def note(self) -> str:
        """How ``arcs`` were found."""
        if self.shaped:
            return f"{self.describe()}, shaped by ZV at the modes above them"
        return f"Newton on the switching times of {self.describe()} with a reversal of the next mode"


@dataclass(frozen=True)
class ByModes:
    proven: Proven | None  # the spec's proven minimum-time command and its certificate
    relaxed: Relaxed | None  # else the deepest proven lower modes' command, shaped


MAX_SOLVES = 160  # Newton solves at most a design (0.1-1 ms each): the work is counted, not timed
LONGER = 1e-9  # (relative) a solved command this much longer than one known is dropped: round-off
STARTS = 12  # structures tried a mode added (structures.mode_starts: the shorter reversal's, the latest first)
REPAIRS = 3  # notches where the multipliers say, after a structure's Newton, before the next structure


def _solved(spec: Spec, durations: list[float], levels: list[float]) -> Arcs | None:
    """The structure's durations by Newton: with its multipliers where it has more arcs than end conditions."""
    arcs = shoot(spec, durations, levels)
    if arcs is None:
        result = newton(spec, durations, levels)
        arcs = None if result is None else result.arcs
    return None if arcs is None else merged(arcs)


class _Search:
    def __init__(self, spec: Spec, accepts: Callable[[Arcs], bool], predicted: Callable[[Spec], Proven | None]) -> None:
        self.spec, self.accepts, self.predicted = spec, accepts, predicted
        self.poles = sorted(spec.zero_poles, key=lambda pole: abs(pole.imag))
        self.solves = 0
        self.deepest: tuple[int, Proven] | None = None  # the most modes whose command is proven, and that command
        self.shortest: Arcs | None = None  # the shortest command of the spec solved (not proven) within the limits
        self.shortest_s = math.inf

    def proven(
        self, spec: Spec, durations: list[float], levels: list[float], repairs: int, longest_s: float = math.inf
    ) -> Proven | None:
        """The structure solved, then repaired up to ``repairs`` times, until one is proven and meets the limits;
        None once a solved command is longer than ``longest_s`` (a command known: no minimum is longer)."""
        for _ in range(repairs + 1):
            if self.solves >= MAX_SOLVES:
                return None
            self.solves += 1
            arcs = _solved(spec, durations, levels)
            if arcs is None:
                return None
            total = duration_s(arcs)
            if total > longest_s:
                return None
            proof = certificate(spec, arcs)
            if proof is not None:
                return (arcs, proof) if self.accepts(arcs) else None
            if len(spec.zero_poles) == len(self.poles) and total < self.shortest_s and self.accepts(arcs):
                self.shortest, self.shortest_s = arcs, total  # not proven, but a command of the spec
            start, _ = next_repair(spec, arcs, notching=True)
            if start is None:
                return None
            durations, levels = start[0], start[1]
        return None

    def added(self, spec: Spec, below: Proven) -> Proven | None:
        """The proven command of ``spec`` from ``below`` (its modes but the highest, proven) with a reversal of the
        highest mode: STARTS structures at most, the latest reversals first."""
        durations, levels, _ = as_start(spec, below[0])
        pole = self.poles[len(spec.zero_poles) - 1]
        zv = nominal_shaper(replace(spec, zero_poles=(pole,)))
        longest_s = sum(durations) + float(zv.times_s[-1])  # the command below, shaped: a command of spec
        for more_d, more_l, _ in mode_starts(spec, durations, levels, pole)[:STARTS]:
            found = self.proven(spec, more_d, more_l, REPAIRS, longest_s * (1 + LONGER))
            if found is not None:
                return found
        return None

    def upwards(self) -> Proven | None:
        """The proven command of every mode, the lowest first: each count of the lowest modes from the count below
        with a reversal of the next (``added``), else from its own predicted structures (the caller's for all the
        modes: not here); None at the first count neither proves (no base for the next)."""
        below: Proven | None = None
        for count in range(1, len(self.poles) + 1):
            spec = replace(self.spec, zero_poles=tuple(self.poles[:count]))
            found = None if below is None else self.added(spec, below)
            if found is None and count < len(self.poles):
                found = self.predicted(spec)
            if found is None:
                return None
            self.deepest, below = (count, found), found
        return below

    def relaxed(self) -> Relaxed | None:
        """The deepest proven lower modes' command shaped at the modes above them (None: none proven)."""
        if self.deepest is None:
            return None
        count, (arcs, _) = self.deepest
        shaper = nominal_shaper(replace(self.spec, zero_poles=tuple(self.poles[count:])))
        shaped = shaped_command(arcs, shaper)
        found = self.shortest if self.shortest_s < duration_s(shaped) else None
        return Relaxed(shaped if found is None else found, duration_s(arcs), count, found is None)


def mode_by_mode(
    spec: Spec,
    rigid: RigidMove | None,
    accepts: Callable[[Arcs], bool],
    predicted: Callable[[Spec], Proven | None],
) -> ByModes:
    """The proven minimum-time command of ``spec`` found mode by mode (see the module) and its certificate, else
    the deepest proven lower modes' command shaped (``Relaxed``; neither: not found within MAX_SOLVES, or the
    structures do not apply). ``accepts(arcs)``: they meet every limit;
    ``predicted(spec)``: the proven command from spec's predicted structures, or None (the caller's, with all the
    modes already tried: not again)."""
    if rigid is None or len(spec.zero_poles) < 2 or not predicts(spec, rigid):
        return ByModes(None, None)
    search = _Search(spec, accepts, predicted)
    proven = search.upwards()
    return ByModes(proven, None if proven is not None else search.relaxed())
