"""Where a held jerk's command meets a state limit at one instant: the arcs' start states, and the touch points the
certificate gives an atom of the limit's measure (optim.families.time_optimal.certify)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from optim.families.time_optimal.types import Spec

Array = NDArray[np.float64]
STATE_TOLERANCE = 1e-7  # of a limit: a derivative this close to it (or to 0) is on it (the arcs sum to it)
BANG, FIRST, SECOND, TOUCH = 0, 1, 2, 3  # an arc's kind: a bang, a first-order constrained arc, a coast (second
# order), a touch point of the velocity limit (zero length: ``touches``)


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
    spec: Spec, durations: Array, levels: Array, with_atoms: bool
) -> tuple[Array, Array, NDArray[np.intp], NDArray[np.intp]]:
    """The arcs with a TOUCH arc (zero length, level 0) inserted where the velocity touches +-max_velocity inside a
    bang arc (held jerk: the acceleration crosses 0 there, at v = +-V; the arc split around it): a touch point of
    the second-order state constraint, whose measure nu has an atom there; sigma need not vanish (the bang arc goes
    on through it). Also each arc's index among the arcs given and its kind (BANG or TOUCH). Without ``with_atoms``
    the arcs as given (each atom is one more unknown: the certificate tries without first, so that a command proven
    without atoms is proven as before)."""
    origin = np.arange(durations.size)
    plain = np.full(durations.size, BANG)
    if not with_atoms or spec.order != 3 or spec.max_velocity is None:
        return durations, levels, origin, plain
    below, velocity = arc_states(spec, durations, levels)
    jerk = levels * spec.scale
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = np.where(jerk != 0.0, -below / jerk, -1.0)
    peak = velocity + below * tau + jerk * tau**2 / 2
    inside = (tau > STATE_TOLERANCE * durations) & (tau < (1 - STATE_TOLERANCE) * durations)
    touch = inside & (np.abs(np.abs(peak) - spec.max_velocity) <= STATE_TOLERANCE * spec.max_velocity)
    if not np.any(touch):
        return durations, levels, origin, plain
    out: list[tuple[float, float, int, int]] = []  # duration, level, origin, kind
    for k, (d, level) in enumerate(zip(durations.tolist(), levels.tolist(), strict=True)):
        if touch[k]:
            out += [(float(tau[k]), level, k, BANG), (0.0, 0.0, k, TOUCH), (d - float(tau[k]), level, k, BANG)]
        else:
            out.append((d, level, k, BANG))
    d_out, l_out, o_out, t_out = (np.array(column) for column in zip(*out, strict=True))
    return d_out.astype(float), l_out.astype(float), o_out.astype(np.intp), t_out.astype(np.intp)
