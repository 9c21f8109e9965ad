"""A refined command's off-limit arcs made bang: the start of a structure the certificate can prove.

A minimum-time command holds its derivative at +-its limit except on arcs where a lower derivative rides its own
limit (optim.families.time_optimal.certify). A local optimum refined with free levels often keeps arcs that are
neither: a fractional level, or a rest below every limit. Each becomes the bang arcs of the same change one order
below (the velocity for a held acceleration, the acceleration for a held jerk):

- between two neighbours on different levels (bang or constrained, the latter counted as level 0) and within them:
  the switch inside it, split in proportion (a grid step's switch);
- otherwise a notch in the nearest bang level B: B, then -B for d (B - level) / (2 B), then B, centred.

The LP optimum of a two-mode move (bench/time_optimal.py's, 3,200 steps) has exactly such notches where SLSQP's
local optimum held fractional levels; refined again with every level fixed, its structure is the certified one.

``notched``: a command with no off-limit arc whose junctions some multipliers fit, but whose switching function
has the other sign than a bang arc somewhere on it (certify.wrong_sign), gets a notch of the other level there:
where sigma says the command should switch (bench/time_optimal.py's three-mode move: sigma > 0 on 13.6 ms of its
long -A arc; with a +A notch there, refined, it is certified 0.002 % shorter). Where sigma agrees but the state
constraint's multiplier has the wrong sign on an arc at the limit one order below (with a held jerk, an arc at
+-max_acceleration), the notch leaves the limit there (held-jerk moves 4, 5, 7 and 17 of bench/time_optimal_speed.py
are certified so, in minimum_time's chain before any LP). A coast at +-max_velocity with a held jerk where the
second-order constraint's multiplier has the wrong sign gets a dip.

``touch_cruises``: with a held jerk, a command whose velocity touches +-max_velocity at one instant inside a bang
arc (certify.touches) gets a short cruise there (a coast at the limit, CRUISE_SHARE of the duration) for SLSQP to
size: the certificate with an atom at the touch finds sigma of the wrong sign around it, and the optimum rides the
limit for a while instead (bench/programs.py's seed-28 move 19, z axis: a 0.067 ms cruise, certified 9e-7 shorter;
three of the 144 designs of seeds 28-30 certified so, none before).

``coast_dips``: a held acceleration whose move lasts many periods of its mode and rides the velocity limit ends its
coast, in the LP's optimum, with a train of dips (-A, +A), one a damped period, growing towards the deceleration
(bench/time_optimal_random.py's move 150: 11 dips on 3,200 steps); a local optimum holds one or none. The coast's
last periods are given n such dips for SLSQP to size.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from optim.families.time_optimal.certify import (
    LEVEL_TOLERANCE,
    SECOND,
    TOUCH,
    arc_states,
    constraints,
    on_a_limit,
    touches,
    wrong_sign,
)
from optim.families.time_optimal.shaped import as_start
from optim.families.time_optimal.structures import Start
from optim.families.time_optimal.types import Arc, Spec

DIP_WIDTH = 0.08  # of a period: each dip's -A and +A arcs start this long (SLSQP sizes them)
NOTCH_SHARE = 0.1  # of the wrong-signed run: the notch's starting width (SLSQP sizes it)
CRUISE_SHARE = 1e-3  # of the duration: a touch point's cruise's starting width (1e-4 and 1e-2 certified the same)
Where = tuple[int, float, float]  # certify.wrong_sign's answer: the arc, the first and the last time of its run


def bang_start(spec: Spec, durations: Sequence[float], levels: Sequence[float]) -> Start | None:
    """The arcs (``levels`` in the unit) with every off-limit arc made bang (see the module), all levels fixed; None
    if there is none."""
    length = np.asarray(durations, dtype=float)
    level = np.asarray(levels, dtype=float)
    bang = np.abs(np.abs(level) - 1.0) <= LEVEL_TOLERANCE
    kept = bang | on_a_limit(spec, length, level)
    if np.all(kept):
        return None
    held = [float(np.sign(v)) if b else 0.0 for v, b in zip(level, bang, strict=True)]  # kept arcs' levels
    out_durations: list[float] = []
    out_levels: list[float] = []
    for k, duration in enumerate(length.tolist()):
        if kept[k]:
            pieces = [(duration, held[k])]
        else:
            left = held[k - 1] if k > 0 and kept[k - 1] else None
            right = held[k + 1] if k + 1 < level.size and kept[k + 1] else None
            pieces = _switch(duration, float(level[k]), left, right) or _notch(duration, float(level[k]), left, right)
        out_durations += [d for d, _ in pieces]
        out_levels += [v for _, v in pieces]
    return out_durations, out_levels, [False] * len(out_levels)


def switched(durations: Sequence[float], levels: Sequence[float], free: Sequence[bool]) -> Start:
    """A grid structure (arcs.structure) whose free arcs between two fixed neighbours on different levels, their
    level between them, are the switch inside (split in proportion, each side joined to its neighbour); the other
    arcs as they are (a coast stays a coast: bang_start would notch one not yet exactly on its limit)."""
    out_d: list[float] = []
    out_l: list[float] = []
    out_f: list[bool] = []
    for k, (duration, level) in enumerate(zip(durations, levels, strict=True)):
        inner = 0 < k < len(levels) - 1 and free[k] and not free[k - 1] and not free[k + 1]
        pieces = _switch(duration, level, levels[k - 1], levels[k + 1]) if inner else []
        for piece, piece_level in pieces or [(duration, level)]:
            if out_l and out_l[-1] == piece_level and not out_f[-1] and (pieces or not free[k]):
                out_d[-1] += piece
            else:
                out_d.append(piece)
                out_l.append(piece_level)
                out_f.append(free[k] and not pieces)
    return out_d, out_l, out_f


def _switch(duration: float, level: float, left: float | None, right: float | None) -> list[tuple[float, float]]:
    """The switch from ``left`` to ``right`` inside the arc, if its level lies between them; [] otherwise."""
    if left is None or right is None or left == right or not min(left, right) <= level <= max(left, right):
        return []
    share = (level - right) / (left - right)
    return [(share * duration, left), ((1.0 - share) * duration, right)]


def _notch(duration: float, level: float, left: float | None, right: float | None) -> list[tuple[float, float]]:
    """B, -B, B with the arc's change one order below: B the nearest bang neighbour's level (or the arc's sign)."""
    bangs = [b for b in (left, right) if b is not None and b != 0.0]
    sign = bangs[0] if bangs else (1.0 if level >= 0.0 else -1.0)
    width = duration * (sign - level) / (2.0 * sign)
    side = 0.5 * (duration - width)
    return [(side, sign), (width, -sign), (side, sign)]


def coast_dips(
    spec: Spec, durations: Sequence[float], levels: Sequence[float], period_s: float, count: int
) -> Start | None:
    """The command (``levels`` in the unit, held acceleration) with ``count`` dips (-s, +s and a coast, one
    ``period_s`` each) in the last ``count`` periods of its longest coast at the velocity limit; None if it has no
    such coast that long."""
    length = np.asarray(durations, dtype=float)
    level = np.asarray(levels, dtype=float)
    coasts = np.flatnonzero(on_a_limit(spec, length, level))
    if spec.order != 2 or coasts.size == 0:
        return None
    k = int(coasts[np.argmax(length[coasts])])
    if length[k] <= count * period_s:
        return None
    below, _ = arc_states(spec, length, level)
    sign = float(np.sign(below[k]))  # the coast's velocity: a dip is -sign, +sign
    width = DIP_WIDTH * period_s
    dips_d = [width, width, period_s - 2.0 * width] * count
    dips_l = [-sign, sign, 0.0] * count
    out_d = [*length[:k].tolist(), float(length[k] - count * period_s), *dips_d, *length[k + 1 :].tolist()]
    out_l = [*level[:k].tolist(), 0.0, *dips_l, *level[k + 1 :].tolist()]
    return out_d, out_l, [False] * len(out_l)


def notched(
    spec: Spec,
    durations: Sequence[float],
    levels: Sequence[float],
    arc: int,
    first_s: float,
    last_s: float,
    share: float = NOTCH_SHARE,
) -> Start:
    """The command (``levels`` in the unit) with a notch centred on the run [first_s, last_s] (times from the
    command's start) where the multipliers contradict ``arc`` (certify.wrong_sign), ``share`` of that run wide (at
    least 1e-3 of the arc): in a bang arc B, -B, B; in an arc on the limit one order below (level 0, at +-L), 0, -s,
    +s, 0 (the lower derivative leaves the limit and comes back); in a coast at +-V with a held jerk, 0, -s, +s
    (twice as long), -s, 0 (the velocity dips and comes back with the acceleration at 0)."""
    start = float(np.sum(durations[:arc]))
    length = float(durations[arc])
    level = float(levels[arc])
    run = max(share * (last_s - first_s), 1e-3 * length)
    on_limit = constraints(spec, np.asarray(durations, dtype=float), np.asarray(levels, dtype=float))[arc]
    if on_limit is not None and on_limit[0] == SECOND:  # a coast at +-max_velocity: a dip, the acceleration back to 0
        sign = on_limit[1]
        width = min(0.125 * length, 0.5 * run)
        pieces, widths = [0.0, -sign, sign, -sign, 0.0], [width, 2.0 * width, width]
    elif on_limit is not None:  # at +-the limit one order below: off it and back
        sign = on_limit[1]
        pieces, widths = [0.0, -sign, sign, 0.0], [min(0.25 * length, run)] * 2
    else:
        pieces, widths = [level, -level, level], [min(0.5 * length, run)]
    inner = sum(widths)
    left = min(max(0.5 * (first_s + last_s) - start - 0.5 * inner, 0.0), length - inner)
    out_d = [*durations[:arc], left, *widths, length - left - inner, *durations[arc + 1 :]]
    out_l = [*levels[:arc], *pieces, *levels[arc + 1 :]]
    return [float(d) for d in out_d], [float(v) for v in out_l], [False] * len(out_l)


def touch_cruises(spec: Spec, durations: Sequence[float], levels: Sequence[float]) -> Start | None:
    """The arcs (``levels`` in the unit) with a cruise of CRUISE_SHARE of the duration at each touch point of the
    velocity limit (certify.touches; taken half from each side of the split bang arc), all levels fixed; None if
    the velocity touches its limit nowhere."""
    length, level, _, kind = touches(spec, np.asarray(durations, dtype=float), np.asarray(levels, dtype=float), True)
    at = np.flatnonzero(kind == TOUCH)
    if at.size == 0:
        return None
    width = CRUISE_SHARE * float(np.sum(length))
    for k in at.tolist():  # (a touch is strictly inside its arc: both halves are there)
        take = min(0.5 * width, 0.5 * length[k - 1], 0.5 * length[k + 1])
        length[k - 1] -= take
        length[k + 1] -= take
        length[k] = 2.0 * take
    return [float(d) for d in length], [float(v) for v in level], [False] * level.size


def next_repair(spec: Spec, arcs: tuple[Arc, ...], notching: bool) -> tuple[Start | None, Where | None]:
    """The start of the next repair of ``arcs``: their off-limit arcs made bang (``bang_start``); else, with
    ``notching``, a cruise at each touch point of the velocity limit (``touch_cruises``), else a notch where the
    multipliers contradict them (``notched``), and that place (certify.wrong_sign: None for the others); (None,
    None) where none applies."""
    durations, levels, _ = as_start(spec, arcs)
    start = bang_start(spec, durations, levels)
    if start is not None or not notching:
        return start, None
    cruise = touch_cruises(spec, durations, levels)
    if cruise is not None:
        return cruise, None
    where = wrong_sign(spec, arcs)
    return (None if where is None else notched(spec, durations, levels, *where)), where
