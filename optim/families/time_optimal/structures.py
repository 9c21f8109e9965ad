"""Predicted arc structures of a minimum-time answer, tried by Newton before any LP.

The minimum-time command of a rest-to-rest move with modes to cancel is the rigid optimum (bang-bang, or
bang-coast-bang at max_velocity; with a held jerk Ruckig's seven phases) with reversal pulses added: Singh and
Vadali's (1993) symmetric three switches around a bang-bang's switch, or a bang arc split by a short pulse the other
way (the answers measured on bench/time_optimal_random.py's moves are mostly these: +a, coast, -a, +a, -a;
+a, -a, +a, -a; and with two modes one reversal each), or a notch in an arc at the limit one order below the held
derivative (a dip in a coast at max_velocity; with a held jerk, in an arc at max_acceleration). Each start here is
such a structure with a reversal of REVERSALS damped periods per mode; the caller solves its switching times by
damped Newton (optim.families.time_optimal.refine.newton) and keeps it only if its certificate proves it
(optim.families.time_optimal.certify).
"""

from __future__ import annotations

import heapq
import itertools
import math

import numpy as np

from models.rigid_motion import RigidMove
from optim.families.time_optimal.types import Spec

Start = tuple[list[float], list[float], list[bool]]  # durations, levels in the unit, which levels are free
REVERSALS = (1 / 6, 1 / 4)  # a reversal pulse, in damped periods of its mode
MAX_STARTS = 16  # Newton runs at most this many predicted structures (a few ms each)
BEAM = 64  # shapes kept after each mode's reversals (one or two modes never reach it; three gave ~3,300 to sort)
MAX_SHARE = 0.45  # a reversal takes at most this share of the arc it enters
DECAYED = 0.01  # a mode whose free vibration falls below this share over the rigid move's duration has decayed


def three_switch_starts(spec: Spec, rigid: RigidMove | None) -> list[Start]:
    """Singh and Vadali's symmetric three-switch structure (+1, -1, +1, -1) around a bang-bang rigid move, with a
    reversal pulse of REVERSALS damped periods of each zero-residual pole: a start the grid may not show."""
    if rigid is None or rigid.order != 2 or rigid.levels.size != 2:
        return []
    if spec.bands or spec.in_motion or not spec.rest_to_rest:
        return []
    half = rigid.duration_s / 2
    starts: list[Start] = []
    for pole in spec.zero_poles:
        for fraction in REVERSALS:
            pulse = min(fraction * 2 * math.pi / pole.imag, MAX_SHARE * half)
            starts.append(([half - pulse, pulse, pulse, half - pulse], [1.0, -1.0, 1.0, -1.0], [False] * 4))
    return starts


Shape = tuple[list[float], list[float], bool]  # durations, levels, whether the reversal is around a switch


def _held(durations: list[float], levels: list[float], ramp_s: float | None) -> list[float]:
    """+-1 on the arcs at +-the limit one order below the held derivative (a coast at max_velocity, or with a held
    jerk an arc at max_acceleration: reached after ``ramp_s`` of the full held level), 0 elsewhere."""
    if ramp_s is None:
        return [0.0] * len(levels)
    reached = [0.0, *itertools.accumulate(lv * d / ramp_s for lv, d in zip(levels[:-1], durations[:-1], strict=True))]
    return [
        math.copysign(1.0, a) if lv == 0.0 and abs(abs(a) - 1.0) < 1e-6 else 0.0
        for a, lv in zip(reached, levels, strict=True)
    ]


def insertions(durations: list[float], levels: list[float], width: float, ramp_s: float | None) -> list[Shape]:
    """Every way to add one reversal of ``width`` (s): inside a bang arc (at its end, its start or its middle: the
    arc's change kept), at a switch between opposite bangs (Singh and Vadali's +1, -1, +1, -1 around it), or a notch
    in an arc at the limit one order below (a dip in a coast; with a held jerk, in an arc at +-max_acceleration)."""
    held = _held(durations, levels, ramp_s)
    out: list[Shape] = []
    for k, (d, level) in enumerate(zip(durations, levels, strict=True)):
        r = min(width, MAX_SHARE * d)
        head, tail = durations[:k], durations[k + 1 :]
        if level == 0.0:
            if held[k] != 0.0:  # an arc at the limit one order below (a coast, or +-A with a held jerk): a notch
                notch = [*levels[:k], 0.0, -held[k], held[k], 0.0, *levels[k + 1 :]]
                for first in ((d - 2 * r) / 2, d - 2 * r):
                    out.append(([*head, first, r, r, d - 2 * r - first, *tail], notch, False))
            continue
        split = [*levels[:k], level, -level, level, *levels[k + 1 :]]
        for first, last in ((d, r), (r, d), ((d + r) / 2, (d + r) / 2)):  # level (first + last) - level r = level d
            out.append(([*head, first, r, last, *tail], split, False))
        if k + 1 < len(levels) and levels[k + 1] == -level:
            p = min(width, MAX_SHARE * d, MAX_SHARE * durations[k + 1])
            out.append(
                (
                    [*head, d - p, p, p, durations[k + 1] - p, *durations[k + 2 :]],
                    [*levels[:k], level, -level, level, -level, *levels[k + 2 :]],
                    True,
                )
            )
    return out


def _reversal_time(durations: list[float], levels: list[float]) -> float:
    """When the last reversal of a shape starts (its latest arc against the rigid move's direction there)."""
    starts = itertools.accumulate(durations[:-1])
    late = [t for t, a, b in zip(starts, levels[1:], levels[:-1], strict=True) if a * b < 0]
    return max(late, default=0.0)


def predicts(spec: Spec, rigid: RigidMove | None) -> bool:
    """Whether the structures here apply: a rest-to-rest move with modes to cancel (derivative order 0), no band, no
    torque limit, not in motion, and its rigid optimum of the spec's order."""
    if rigid is None or rigid.order != spec.order or spec.derivative_order != 0:
        return False
    return not (spec.bands or spec.torque is not None or spec.in_motion or not spec.rest_to_rest or not spec.zero_poles)


def _ramp_s(spec: Spec) -> float | None:
    """The time the held derivative at its limit takes to bring the one below to its own limit (None: unlimited)."""
    below = spec.max_acceleration if spec.order == 3 else spec.max_velocity  # the limit one order below the held
    return None if below is None else below / spec.scale


def mode_starts(spec: Spec, durations: list[float], levels: list[float], pole: complex) -> list[Start]:
    """A command (``levels`` in the unit) with one reversal of REVERSALS damped periods of ``pole`` added, every
    way ``insertions`` has, the shorter reversal's first and each width's latest reversals first (the proven one was
    1st-3rd so on the 20 three-mode moves of bench/time_optimal_speed.py, 24th-35th in the arcs' order)."""
    out: list[Start] = []
    for fraction in REVERSALS:
        width = fraction * 2 * math.pi / abs(pole.imag)
        shapes = sorted(insertions(durations, levels, width, _ramp_s(spec)), key=lambda x: -_reversal_time(x[0], x[1]))
        out += [(d, lv, [False] * len(lv)) for d, lv, _ in shapes]
    return out


def rigid_arcs(spec: Spec, rigid: RigidMove | None) -> tuple[list[float], list[float]] | None:
    """The rigid optimum's arcs (durations, levels in the unit: Ruckig's phases of zero duration dropped, equal
    neighbours merged); None where the structures here do not apply (``predicts``) or it is not bang-coast-bang."""
    if rigid is None or not predicts(spec, rigid):
        return None
    kept = np.diff(rigid.edges_s) > 0.0
    widths, unit = np.diff(rigid.edges_s)[kept], rigid.levels[kept] / spec.scale
    joined = np.concatenate(([True], np.abs(np.diff(unit)) > 1e-12))
    durations = np.add.reduceat(widths, np.flatnonzero(joined)).tolist()
    unit = unit[joined]
    if np.any(np.abs(unit - np.round(unit)) > 1e-6):
        return None  # not a bang-coast-bang (none seen from Ruckig at rest-to-rest: a safeguard)
    return durations, np.round(unit).tolist()


CRUISE_WIDTHS = ((0.08, 0.17, 0.05), (0.05, 0.1, 0.05), (0.12, 0.2, 0.02))  # cruise_starts': the dip's, the
# notch's, and the hold before the notch, in damped periods (the certified answers' on bench/programs.py; of 96
# designs of two seeds, 9 certified from these, 4, 4 and 1; none from a fourth width, (0.1, 0.2, 0.1), or the mirror)
# two_dip_starts' widths, in damped periods: the first dip's half-width and the cruise before it (0: the dip at the
# entry), the second dip's half-width and the cruise after it, the hold before the deceleration's notch and the notch
# (read off the 600-step LP's optima at their minimum duration: seed 28's design 38, whose certified answer has 0.042,
# 0.081, 0.113, 0.477, 0.035, 0.226, and seed 30's)
TWO_DIPS = ((0.042, 0.08, 0.113, 0.48, 0.035, 0.2255), (0.08, 0.0, 0.113, 0.45, 0.04, 0.22))


def _cruising(spec: Spec, rigid: RigidMove | None) -> tuple[list[float], float] | None:
    """With a held jerk and one mode, the durations of a rigid optimum that cruises at max_velocity between holds at
    +-A (+J, hold at A, -J, cruise, -J, hold at -A, +J) and the mode's damped period; else None."""
    arcs = rigid_arcs(spec, rigid)
    if arcs is None or spec.order != 3 or len(spec.zero_poles) != 1 or spec.max_velocity is None:
        return None
    durations, levels = arcs
    if levels != [1.0, 0.0, -1.0, 0.0, -1.0, 0.0, 1.0]:
        return None
    return durations, 2.0 * math.pi / abs(spec.zero_poles[0].imag)


def cruise_starts(spec: Spec, rigid: RigidMove | None) -> list[Start]:
    """A rigid optimum that cruises (``_cruising``), with the velocity touching the limit and dipping as the cruise
    begins and a notch in the deceleration's hold at -A (+J, -J): the structure of the certified answers on
    bench/programs.py's cruising moves (the touch point is an atom of the velocity limit's measure:
    optim.families.time_optimal.touch_points), at each of CRUISE_WIDTHS. For SLSQP (their duration is not fixed by
    the end conditions alone: optim.families.time_optimal.refine), tried before any LP. (Its mirror in time, the
    notch in the acceleration's hold and the dip as the cruise ends, certified none.)"""
    cruising = _cruising(spec, rigid)
    if cruising is None:
        return []
    (ramp, hold_up, _, cruise, _, hold_down, _), period = cruising
    shape = [1.0, 0.0, -1.0, 1.0, -1.0, 0.0, -1.0, 0.0, 1.0, -1.0, 0.0, 1.0]
    starts: list[Start] = []
    for dip_p, notch_p, before_p in CRUISE_WIDTHS:
        dip, notch, before = dip_p * period, notch_p * period, before_p * period
        if hold_down > before + 2.0 * notch:
            rest = hold_down - before - 2.0 * notch
            lengths = [ramp, hold_up, ramp + dip, 2.0 * dip, dip, cruise, ramp, before, notch, notch, rest, ramp]
            starts.append((lengths, shape, [False] * len(shape)))
    return starts


def two_dip_starts(spec: Spec, rigid: RigidMove | None) -> list[Start]:
    """A rigid optimum that cruises (``_cruising``) with two dips in its cruise, at each of TWO_DIPS (``_two_dips``)."""
    cruising = _cruising(spec, rigid)
    if cruising is None:
        return []
    durations, period = cruising
    return [_two_dips(durations, [share * period for share in shares]) for shares in TWO_DIPS]


def _two_dips(rigid: list[float], widths_s: list[float]) -> Start:
    """The cruise of ``rigid`` (Ruckig's seven arcs) with two dips (-J, +J, -J back to the limit) and a notch in the
    deceleration's hold, of ``widths_s`` (TWO_DIPS' order; a first dip with no cruise before it is entered from the
    acceleration: the velocity overshoots); the cruises and the hold shortened by what the dips and the notch take,
    each to a tenth of it at least (SLSQP sizes them). The structure of the LP's optimum where no single dip's was
    certified (seed 28's design 38: the 600-step LP's vertex at its minimum duration)."""
    ramp, hold_up, _, cruise, _, hold_down, _ = rigid
    first, ahead, second, after, before, notch = widths_s
    after = min(after, 0.4 * cruise)
    between = max(cruise - ahead - after - 4.0 * (first + second) - 2.0 * notch, 0.1 * cruise)
    rest = max(hold_down - before - 2.0 * notch, 0.1 * hold_down)
    if ahead > 0.0:
        entry, entry_levels = [ramp, ahead, first, 2.0 * first, first], [-1.0, 0.0, -1.0, 1.0, -1.0]
    else:
        entry, entry_levels = [ramp + first, 2.0 * first, first], [-1.0, 1.0, -1.0]
    middle = [between, second, 2.0 * second, second, after]
    lengths = [ramp, hold_up, *entry, *middle, ramp, before, notch, notch, rest, ramp]
    levels = [1.0, 0.0, *entry_levels, 0.0, -1.0, 1.0, -1.0, 0.0, -1.0, 0.0, 1.0, -1.0, 0.0, 1.0]
    return lengths, levels, [False] * len(levels)


def reversal_starts(spec: Spec, rigid: RigidMove | None) -> list[Start]:
    """The rigid optimum with one reversal per zero-residual pole (its derivative order 0), shortest reversal first;
    none where the structure is not predicted (``predicts``)."""
    arcs = rigid_arcs(spec, rigid)
    if arcs is None or rigid is None:
        return []
    durations, levels = arcs
    ramp_s = _ramp_s(spec)
    # Where a mode's vibration decays within the move only the last switches' residual is left to cancel: reversals
    # near the end first; else Singh and Vadali's around a switch first (the undamped optimum).
    decays = all(math.exp(pole.real * rigid.duration_s) < DECAYED for pole in spec.zero_poles)

    def rank(shape: Shape) -> tuple[bool, float]:
        return decays or not shape[2], -_reversal_time(shape[0], shape[1])

    starts: list[Start] = []
    for fraction in REVERSALS:
        if len(starts) >= MAX_STARTS:  # (the next width's shapes would come after them: none would be kept)
            break
        shapes: list[Shape] = [(durations, levels, False)]
        for pole in spec.zero_poles:
            if len(shapes) > BEAM:  # with three or more modes only the BEAM most promising are expanded further
                shapes = heapq.nsmallest(BEAM, shapes, key=rank)  # (as sorted(...)[:BEAM], in 1/10 of the time)
            width = fraction * 2 * math.pi / abs(pole.imag)
            shapes = list(itertools.chain.from_iterable(insertions(d, lv, width, ramp_s) for d, lv, _ in shapes))
        best = heapq.nsmallest(MAX_STARTS - len(starts), shapes, key=rank)
        starts += [(d, lv, [False] * len(lv)) for d, lv, _ in best]
    return starts
