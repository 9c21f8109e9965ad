"""Where a held jerk's command meets a state limit at one instant: the arcs' start states, and the touch points the
certificate gives an atom of the limit's measure (optim.families.time_optimal.certify)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from optim.families.time_optimal.types import Spec

Array = NDArray[np.float64]
STATE_TOLERANCE = 1e-7  # of a limit: a derivative this close to it (or to 0) is on it (the arcs sum to it)
BANG, FIRST, SECOND, TOUCH, CORNER = 0, 1, 2, 3, 4  # an arc's kind: a bang, a first-order constrained arc, a coast
# (second order), a touch point of the velocity limit, of the acceleration limit (zero length; ``touches``)


def arc_states(spec: Spec, durations: Array, levels: Array) -> tuple[Array, Array]:
    """At each arc's start, from rest: the derivative one order below q, and (q = 3) the velocity."""
    rates = levels * spec.scale
    below = np.concatenate(([0.0], np.cumsum(rates * durations)[:-1]))
    grow = below * durations + rates * durations**2 / 2  # q = 3: each arc's velocity change
    return below, np.concatenate(([0.0], np.cumsum(grow)[:-1]))


def _on(values: Array, limit: float | None) -> NDArray[np.bool_]:
    """Whether each of ``values`` is at +-``limit`` (within STATE_TOLERANCE of it; never without a limit)."""
    if limit is None:
        return np.zeros(values.shape, dtype=bool)
    return np.asarray(np.abs(np.abs(values) - limit) <= STATE_TOLERANCE * limit)


def touches(
    spec: Spec, durations: Array, levels: Array, variant: int
) -> tuple[Array, Array, NDArray[np.intp], NDArray[np.intp]]:
    """The arcs with a touch point (an arc of zero length, level 0) inserted where a state limit is met at one
    instant (held jerk): TOUCH where the velocity reaches +-max_velocity inside a bang arc (the acceleration crosses
    0 there; the arc split around it), CORNER where a bang arc ends at +-max_acceleration and the next one turns
    back. Their measure is an atom there (nu's, mu's): sigma need not vanish, the bang arcs go on through it. Also
    each arc's index among the arcs given, and each arc's touch kind (BANG: none). ``variant`` (VARIANTS): 0 none,
    1 the touches, 2 the corners too (each atom is one more unknown: a variant is tried where the one before does
    not certify, so that a command proven without atoms is proven as before)."""
    origin = np.arange(durations.size)
    plain = np.full(durations.size, BANG)
    if variant == 0 or spec.order != 3 or (spec.max_velocity is None and spec.max_acceleration is None):
        return durations, levels, origin, plain
    below, velocity = arc_states(spec, durations, levels)
    jerk = levels * spec.scale
    after = below + jerk * durations  # the acceleration at each arc's end
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = np.where(jerk != 0.0, -below / jerk, -1.0)
    peak = velocity + below * tau + jerk * tau**2 / 2
    inside = (tau > STATE_TOLERANCE * durations) & (tau < (1 - STATE_TOLERANCE) * durations)
    limit_v, limit_a = spec.max_velocity, spec.max_acceleration
    touch = (
        inside & (limit_v is not None) & (np.abs(np.abs(peak) - (limit_v or 0.0)) <= STATE_TOLERANCE * (limit_v or 1))
    )
    turns = np.concatenate((levels[:-1] * levels[1:] < 0.0, [False]))  # a bang arc followed by the other level
    corner = (
        turns
        & (variant >= 2)
        & (limit_a is not None)
        & (np.abs(np.abs(after) - (limit_a or 0.0)) <= STATE_TOLERANCE * (limit_a or 1))
    )
    if not np.any(touch | corner):
        return durations, levels, origin, plain
    out: list[tuple[float, float, int, int]] = []  # duration, level, origin, touch kind
    for k, (d, level) in enumerate(zip(durations.tolist(), levels.tolist(), strict=True)):
        if touch[k]:
            out += [(float(tau[k]), level, k, BANG), (0.0, 0.0, k, TOUCH), (d - float(tau[k]), level, k, BANG)]
        else:
            out.append((d, level, k, BANG))
        if corner[k]:
            out.append((0.0, 0.0, k, CORNER))
    d_out, l_out, o_out, t_out = (np.array(column) for column in zip(*out, strict=True))
    return d_out.astype(float), l_out.astype(float), o_out.astype(np.intp), t_out.astype(np.intp)
