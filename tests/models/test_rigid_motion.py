"""models.rigid_motion (Ruckig) against the closed-form double-S of Biagiotti and Melchiorri, "Trajectory Planning
for Automatic Machines and Robots" (2008), Sec. 3.4 with zero boundary velocities and accelerations.

Closed form (rest to rest, D > 0): with v_lim = V, a_lim = A, j = J,
- V J >= A^2: T_j = A / J, T_a = T_j + V / A; else T_j = sqrt(V / J), T_a = 2 T_j; T_v = D / V - T_a;
- T_v < 0 (V not reached): D >= 2 A^3 / J^2: T_j = A / J, T_a = T_j / 2 + sqrt(T_j^2 / 4 + D / A); else
  T_j = (D / (2 J))^(1/3), T_a = 2 T_j; T_v = 0;
- T = 2 T_a + T_v.
Both are exact: the tolerance 1e-12 is round-off of durations near 1 s.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from models.commands import PiecewiseCommand
from models.rigid_motion import rigid_move


def double_s_s(d: float, v: float, a: float, j: float) -> float:
    tj, ta = (a / j, a / j + v / a) if v * j >= a * a else (math.sqrt(v / j), 2 * math.sqrt(v / j))
    tv = d / v - ta
    if tv < 0:
        tv = 0.0
        if d >= 2 * a**3 / j**2:
            tj = a / j
            ta = tj / 2 + math.sqrt(tj * tj / 4 + d / a)
        else:
            tj = (d / (2 * j)) ** (1 / 3)
            ta = 2 * tj
    return 2 * ta + tv


CASES = [  # (D, V, A, J): velocity and acceleration reached; only A; neither; V without A; the moves
    (1.0, 0.5, 2.0, 10.0),
    (1.0, 5.0, 2.0, 10.0),
    (0.01, 5.0, 2.0, 10.0),
    (1.0, 0.2, 2.0, 100.0),
    (0.17148, 0.52916, 6.4285, 4964.7),
    (0.86714, 0.27188, 27.488, 4942.4),
]


@pytest.mark.parametrize(("d", "v", "a", "j"), CASES)
def test_ruckig_is_the_double_s_minimum(d: float, v: float, a: float, j: float) -> None:
    move = rigid_move(d, True, v, a, j)
    assert move.duration_s == pytest.approx(double_s_s(d, v, a, j), rel=1e-12)
    command = PiecewiseCommand.from_held_steps(move.edges_s, [*move.levels, 0.0], 3)
    end = command.derivatives[:, -1]
    assert end[0] == pytest.approx(d, rel=1e-12) and abs(end[1]) < 1e-12 * v and abs(end[2]) < 1e-12 * a
    peaks = np.max(np.abs(command.derivatives[1:3]), axis=1)
    assert peaks[0] <= v * (1 + 1e-12) and peaks[1] <= a * (1 + 1e-12)  # the breakpoints hold the peaks


def test_without_a_jerk_limit_it_is_the_bang_bang_or_the_trapezoid() -> None:
    assert rigid_move(1.2, True, None, 1.92, None).duration_s == pytest.approx(2 * math.sqrt(1.2 / 1.92), rel=1e-14)
    assert rigid_move(1.0, True, 0.5, 2.0, None).duration_s == pytest.approx(1.0 / 0.5 + 0.5 / 2.0, rel=1e-14)


def test_a_speed_up_ramps_the_acceleration() -> None:
    # To speed V from rest: V / A + A / J when A is reached (V >= A^2 / J), else 2 sqrt(V / J).
    assert rigid_move(1.0, False, None, 2.0, 10.0).duration_s == pytest.approx(1.0 / 2.0 + 2.0 / 10.0, rel=1e-12)
    assert rigid_move(0.1, False, None, 2.0, 10.0).duration_s == pytest.approx(2 * math.sqrt(0.1 / 10.0), rel=1e-12)


@pytest.mark.parametrize(("d", "v0", "vf"), [(1.0, 0.2, 0.1), (1.0, -0.3, 0.4), (0.3, 0.5, 0.5), (-0.2, 0.4, -0.1)])
def test_between_velocities_it_is_the_trapezoid(d: float, v0: float, vf: float) -> None:
    """Without a jerk limit, from v0 to vf over D > 0 at V = 0.5, A = 2 (both v0, vf toward the target or a reversal
    first): the trapezoid's closed form, t = (V - v0) / A + (V - vf) / A + (D - (V^2 - v0^2) / 2A - (V^2 - vf^2) / 2A)
    / V (the ramps' signed distances), where its cruise is long enough (these cases; D < 0 is the mirror image)."""
    sign = math.copysign(1.0, d)
    top, accel = 0.5, 2.0
    u0, uf = sign * v0, sign * vf
    cruise = (abs(d) - (top**2 - u0**2) / (2 * accel) - (top**2 - uf**2) / (2 * accel)) / top
    expected = (top - u0) / accel + (top - uf) / accel + cruise
    assert cruise >= 0.0
    move = rigid_move(d, True, top, accel, None, current_velocity=v0, target_velocity=vf)
    assert move.duration_s == pytest.approx(expected, rel=1e-12)
    command = PiecewiseCommand.from_held_steps(move.edges_s, [*move.levels, 0.0], 2, initial=(0.0, v0))
    assert command.derivatives[0, -1] == pytest.approx(d, rel=1e-12)
    assert command.derivatives[1, -1] == pytest.approx(vf, abs=1e-12)
    assert np.max(np.abs(command.derivatives[1])) <= top * (1 + 1e-12)


def test_between_accelerations_it_ends_in_the_target_state() -> None:
    """Ruckig's current_/target_ acceleration: the command integrated from (0, v0, a0) ends at (D, vf, af) and
    holds V, A, J; it is no shorter than the same move's time with the accelerations' velocity change alone."""
    move = rigid_move(
        0.5,
        True,
        0.5,
        2.0,
        20.0,
        current_velocity=0.3,
        current_acceleration=0.5,
        target_velocity=0.1,
        target_acceleration=-0.5,
    )
    command = PiecewiseCommand.from_held_steps(move.edges_s, [*move.levels, 0.0], 3, initial=(0.0, 0.3, 0.5))
    assert command.derivatives[:3, -1] == pytest.approx([0.5, 0.1, -0.5], abs=1e-12)
    peaks = np.max(np.abs(command.derivatives[1:4]), axis=1)
    assert np.all(peaks <= np.array([0.5, 2.0, 20.0]) * (1 + 1e-12))
