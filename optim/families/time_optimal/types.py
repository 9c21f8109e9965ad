"""The time-optimal problem in the core's own terms, and its solution."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from models.commands import PiecewiseCommand

MAX_MODES = 6  # modes cancelled at most: each adds 2 (x derivative order + 1) equalities
DEFAULT_MAX_PERCENTAGE_VIBRATION = 5.0
# The smallest band bound, %: zero-vibration designs leave 1e-13 to 5e-9 % by rounding alone (the README's
# examples), so a bound below 1e-6 % could not be told from their noise; and 5e-324 % underflowed the LP's
# band rows to 0 (a division by zero, NaN in HiGHS's input: a 500 found by the fuzz bench).
MIN_PERCENTAGE_VIBRATION = 1e-6


@dataclass(frozen=True)
class Band:
    """|residual| <= max_percentage_vibration % of the rigid reference's envelope for every natural
    frequency in [low, high] (rad/s) and damping ratio in ``damping_ratios`` (a range: its ends and middle)."""

    low_rad_s: float
    high_rad_s: float
    damping_ratios: tuple[float, ...]
    max_percentage_vibration: float = DEFAULT_MAX_PERCENTAGE_VIBRATION


@dataclass(frozen=True)
class Torque:
    """The motor torque J_M a + J_L a_L of a two-inertia plant, a_L = G a, G = (2 zeta w s + w^2) / (s^2 +
    2 zeta w s + w^2) given by its upper pole (Cusimano eq. 4)."""

    motor_inertia_kgm2: float
    load_inertia_kgm2: float
    max_torque_nm: float
    pole: complex


@dataclass(frozen=True)
class Spec:
    """A rest-to-rest move of ``move`` (> 0) or a rest-to-velocity ramp to ``move``, within the limits,
    with zero residual at ``zero_poles`` (and its first ``derivative_order`` derivatives in frequency) and
    below each band's bound over the band. ``reference`` is the rigid command V is measured against."""

    move: float
    rest_to_rest: bool
    max_velocity: float | None
    max_acceleration: float | None
    max_jerk: float | None
    torque: Torque | None
    zero_poles: tuple[complex, ...]
    derivative_order: int
    bands: tuple[Band, ...]
    reference: PiecewiseCommand
    floor_s: float  # a proven lower bound on the duration (the rigid kinematics)
    upper_guess_s: float  # a duration at which a command is expected to exist (the search starts there)
    max_duration_s: float
    sufficient_s: float | None = None  # TimeOptimalOptions.sufficient_duration_s
    lp_time_limit_s: float = 10.0  # each LP's wall-clock last resort (HiGHS's time_limit): reached, SolverTimedOut
    # A rest-to-rest move may start and end in motion (the motor's velocity and acceleration, in the move's
    # direction; the load quasi-static in that motion): the accelerations are 0 unless the jerk is held.
    start_velocity: float = 0.0
    start_acceleration: float = 0.0
    end_velocity: float = 0.0
    end_acceleration: float = 0.0

    @property
    def order(self) -> int:
        """q: the derivative held piecewise constant (2: acceleration, 3: jerk)."""
        return 3 if self.max_jerk is not None else 2

    @property
    def in_motion(self) -> bool:
        """The move starts or ends with a non-zero velocity or acceleration."""
        return any((self.start_velocity, self.start_acceleration, self.end_velocity, self.end_acceleration))

    def start_state(self) -> tuple[float, ...]:
        """(position 0, velocity[, acceleration]) at the start: the motor's derivatives below the held one."""
        return (0.0, self.start_velocity, self.start_acceleration)[: self.order]

    def free_motion(self, m: int, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """The start state's share of the m-th derivative at times ``t``: sum_(k >= m) s_k t^(k - m) / (k - m)!
        (the command's own share is linear in its held levels)."""
        times = np.asarray(t, dtype=float)
        out = np.zeros_like(times)
        if not (self.start_velocity or self.start_acceleration):
            return out  # from rest (the common case: the refinement calls this at every evaluation)
        state = self.start_state()
        for k in range(m, len(state)):
            if state[k] != 0.0:
                out += state[k] * times ** (k - m) / math.factorial(k - m)
        return out

    def position_scale(self, total_s: float) -> float:
        """The size of the positions a move of ``total_s`` passes through: the move, or the distance its start and
        end velocities cover in that time if larger (a reversal from speed travels far beyond a short move)."""
        return max(self.move, (abs(self.start_velocity) + abs(self.end_velocity)) * total_s)

    def end_targets(self) -> dict[int, float]:
        """The motor's derivatives fixed at the end, {order: value}, ascending: the position of a rest-to-rest
        move, the velocity (the end state's, or the target speed) and, with a held jerk, the acceleration."""
        targets = {0: self.move} if self.rest_to_rest else {}
        targets[1] = self.end_velocity if self.rest_to_rest else self.move
        if self.order == 3:
            targets[2] = self.end_acceleration
        return targets

    @property
    def scale(self) -> float:
        """The unit of the decision variables: max_jerk, max_acceleration, or the torque's M / (J_M + J_L)."""
        if self.max_jerk is not None:
            return self.max_jerk
        if self.max_acceleration is not None:
            return self.max_acceleration
        assert self.torque is not None
        return self.torque.max_torque_nm / (self.torque.motor_inertia_kgm2 + self.torque.load_inertia_kgm2)


@dataclass(frozen=True)
class Arc:
    start_s: float
    duration_s: float
    level: float  # the held derivative's value (acceleration or jerk)


@dataclass(frozen=True)
class GridSolution:
    step_s: float
    steps: int
    values: NDArray[np.float64]  # the held derivative on each step
    infeasible_steps: int  # the largest step count for which the bisection found no command (not a proof)


@dataclass(frozen=True)
class Solution:
    arcs: tuple[Arc, ...]
    order: int
    duration_s: float
    lower_bound_s: float
    lower_bound_method: str
    grid: GridSolution | None  # None: the grid search found no command, the shaped rigid optimum is the answer
    method: str  # "refined", "shaped_rigid" or "grid" (optim.families.time_optimal.minimum_time)
    refinement: str
    lp_solves: int
    lp_iterations: int
    solve_time_s: float  # reported only
    cut_frequencies: int
    notes: tuple[str, ...] = field(default=())
    max_lp_iterations: int = 0  # the caps the search ran with (optim.families.time_optimal.lp)
    max_lp_solves: int = 0
    capped_runs: int = 0  # HiGHS runs stopped at max_lp_iterations
    capped_lps: int = 0  # LPs counted as "not found" because both methods stopped there

    @property
    def refined(self) -> bool:
        """Exact switching times: a refined structure, or the shaped rigid optimum (exact by construction)."""
        return self.method != "grid"
