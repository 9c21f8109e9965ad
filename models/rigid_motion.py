"""The rigid time-optimal move under velocity, acceleration and jerk limits, by Ruckig (Berscheid and Kroeger
2021): the reference no vibration-aware command may beat, and the profile the ZV-shaped recipe shapes.

A move is rest-to-rest (``rest_to_rest``: position 0 -> ``move``, possibly starting and ending in motion) or
rest-to-velocity (velocity 0 -> ``move``,
acceleration back to 0). A limit left as None is unbounded. Ruckig's profile has seven phases of constant
jerk; without a jerk limit its phases hold the acceleration instead (the jerk is impulsive).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True)
class RigidMove:
    """The rigid optimum as held steps: ``levels[k]`` of the derivative of ``order`` on [edges[k], edges[k + 1])
    (order 3: jerk, order 2: acceleration), zero after the last edge."""

    edges_s: Array
    levels: Array
    order: int

    @property
    def duration_s(self) -> float:
        return float(self.edges_s[-1])


def _length_scale(move: float, speed: float, max_acceleration: float | None, max_jerk: float | None) -> float:
    """A length near the move's own: |move|, or the distance to brake from ``speed`` if that is larger."""
    brake = speed * speed / max_acceleration if max_acceleration is not None else 0.0
    if max_jerk is not None and max_acceleration is None:
        brake = speed**1.5 / math.sqrt(max_jerk)
    return max(abs(move), brake) or 1.0


def rigid_move(
    move: float,
    rest_to_rest: bool,
    max_velocity: float | None,
    max_acceleration: float | None,
    max_jerk: float | None,
    *,
    current_velocity: float = 0.0,
    current_acceleration: float = 0.0,
    target_velocity: float = 0.0,
    target_acceleration: float = 0.0,
) -> RigidMove:
    """The time-optimal rigid move of ``move`` (> 0 from rest) within the limits (at least one of acceleration or
    jerk). A rest-to-rest move (``rest_to_rest``) may start and end in motion (Ruckig's current_ and target_
    velocity and acceleration; then ``move`` is signed).

    Ruckig runs on the move scaled to 1 and time scaled to the move's own (sqrt(move / A), or (move / J)^(1/3)),
    so that its numbers stay near 1 whatever the units (it refuses a move of 1e9 at 1e-6 m/s^2 as given); the
    profile is scaled back exactly (a power of the scales per derivative)."""
    from ruckig import ControlInterface, InputParameter, Result, Ruckig, RuckigError, Trajectory

    if max_acceleration is None and max_jerk is None:
        raise ValueError("the rigid optimum needs an acceleration or a jerk limit")
    if rest_to_rest:
        speed = max(abs(current_velocity), abs(target_velocity))
        length = _length_scale(move, speed, max_acceleration, max_jerk)
        tau = math.sqrt(length / max_acceleration) if max_acceleration is not None else (length / max_jerk) ** (1 / 3)  # type: ignore[operator]
    else:  # to speed ``move``: its time at the acceleration limit, or under the jerk alone
        tau = move / max_acceleration if max_acceleration is not None else math.sqrt(move / max_jerk)  # type: ignore[operator]
    unit = length if rest_to_rest else move * tau  # position unit: the move, or the distance at speed ``move`` in tau

    def scaled(limit: float | None, order: int) -> float:
        return math.inf if limit is None else limit * tau**order / unit

    given = InputParameter(1)
    given.current_position = [0.0]
    given.current_velocity = [current_velocity * tau / unit]
    given.current_acceleration = [current_acceleration * tau**2 / unit]
    given.max_velocity = [scaled(max_velocity, 1) if rest_to_rest else math.inf]
    given.max_acceleration = [scaled(max_acceleration, 2)]
    given.max_jerk = [scaled(max_jerk, 3)]
    if rest_to_rest:
        given.target_position = [move / unit]
        given.target_velocity = [target_velocity * tau / unit]
        given.target_acceleration = [target_acceleration * tau**2 / unit]
    else:
        given.control_interface = ControlInterface.Velocity
        given.target_velocity = [move * tau / unit]
    trajectory = Trajectory(1)
    try:
        status = Ruckig(1).calculate(given, trajectory)
    except RuckigError as exc:
        raise ValueError(f"Ruckig found no rigid move: {str(exc).strip().splitlines()[0]}") from None
    if status not in (Result.Working, Result.Finished):
        raise ValueError(f"Ruckig found no rigid move ({status})")
    profile = trajectory.profiles[0][0]
    if profile.brake.duration > 0.0:  # a start outside the limits: Ruckig's brake breaks them, no rigid optimum
        raise ValueError("Ruckig found no rigid move within the limits from this state (it needs a brake phase)")
    phases = np.asarray(profile.t, dtype=float)
    order = 3 if max_jerk is not None else 2
    held = np.asarray(profile.j if order == 3 else profile.a[:-1], dtype=float) * unit / tau**order
    keep = phases > 0.0
    edges = np.concatenate(([0.0], np.cumsum(phases[keep]))) * tau
    return RigidMove(edges, held[keep], order)


def synchronized_moves(
    moves: list[float],
    max_velocity: list[float | None],
    max_acceleration: list[float | None],
    max_jerk: list[float | None],
) -> list[RigidMove | None]:
    """Ruckig's time-synchronized rigid optimum of several axes from rest to rest (one DoF per axis, its own
    limits, every axis arriving when the slowest can): a RigidMove per moving axis, None for an axis that stays.
    Each axis runs on its move scaled to 1 and all on one time scale (the slowest axis's own), so that the
    numbers stay near 1 (as ``rigid_move``); the profiles are scaled back exactly. Every moving axis needs an
    acceleration or a jerk limit; held jerk if any axis has a jerk limit (the others' then jerk-impulsive: they
    are given a jerk limit of 1e9 times their own time scale's)."""
    from ruckig import InputParameter, Result, Ruckig, RuckigError, Trajectory

    moving = [i for i, d in enumerate(moves) if d != 0.0]
    if not moving:
        return [None] * len(moves)
    order = 3 if any(max_jerk[i] is not None for i in moving) else 2
    scales = []
    for i in moving:
        a, j, d = max_acceleration[i], max_jerk[i], abs(moves[i])
        if a is None and j is None:
            raise ValueError("every moving axis needs an acceleration or a jerk limit")
        scales.append(math.sqrt(d / a) if a is not None else (d / j) ** (1 / 3))  # type: ignore[operator]
    tau = max(scales)
    n = len(moving)
    given = InputParameter(n)
    given.current_position = [0.0] * n
    given.target_position = [math.copysign(1.0, moves[i]) for i in moving]

    def scaled(limits: list[float | None], power: int, absent: float) -> list[float]:
        return [absent if (v := limits[i]) is None else v * tau**power / abs(moves[i]) for i in moving]

    given.max_velocity = scaled(max_velocity, 1, math.inf)
    given.max_acceleration = scaled(max_acceleration, 2, math.inf)
    given.max_jerk = scaled(max_jerk, 3, 1e9 if order == 3 else math.inf)
    trajectory = Trajectory(n)
    try:
        status = Ruckig(n).calculate(given, trajectory)
    except RuckigError as exc:
        raise ValueError(f"Ruckig found no synchronized move: {str(exc).strip().splitlines()[0]}") from None
    if status not in (Result.Working, Result.Finished):
        raise ValueError(f"Ruckig found no synchronized move ({status})")
    out: list[RigidMove | None] = [None] * len(moves)
    for k, i in enumerate(moving):
        profile = trajectory.profiles[0][k]
        phases = np.asarray(profile.t, dtype=float)
        unit = abs(moves[i])
        held = np.asarray(profile.j if order == 3 else profile.a[:-1], dtype=float) * unit / tau**order
        keep = phases > 0.0
        edges = np.concatenate(([0.0], np.cumsum(phases[keep]))) * tau
        out[i] = RigidMove(edges, held[keep], order)
    return out
