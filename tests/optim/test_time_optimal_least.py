"""The 4x grid's command at its least duration (issue 28's speed work): where every refined candidate is longer than
the coarse grid's command, the 4x grid's command is bisected to its least duration on as many steps, its cruise's
chatter removed and its switches inside a step split, and refined before any 8x grid (minimum_time._least)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.lp_reference import GridMove
from models.plants import ModePlant
from optim.families.time_optimal.family import selected_modes, spec_of
from optim.families.time_optimal.options import TimeOptimalOptions
from optim.families.time_optimal.repair import switched
from optim.families.time_optimal.search import GridSearch, without_chatter
from optim.problem import Limits, Problem
from optim.programs.moves import path_plant
from optim.registry import FAMILIES
from optim.synthesis import synthesize

MODES = ((14.0, 0.03), (22.0, 0.02), (35.0, 0.05))


def test_a_three_mode_straight_line_is_proven_from_the_4x_grid_at_its_least_duration() -> None:
    # bench/programs.py's seed-29 move 5 (its 13th design alone): a straight line through three modes, 14, 22 and
    # 35 Hz, the projected limits of bench's. Every refined candidate is longer than the coarse grid's command; the
    # answer was the 8x grid's, 380.572 ms, unproven, after 15 LPs and 1.4 s. The 4x grid's vertex at its least
    # duration cruises with three dips (its chatter removed): refined, the certificate proves 380.349 ms (0.059 %
    # shorter) and no 8x LP is solved. The independent 800-step LP of bench/lp_reference.py finds no command 1e-5
    # shorter (its own grid costs it up to a step, 0.05 %) and one 0.2 % longer (the check can tell).
    steps_solved: list[float] = []
    feasible = GridSearch.feasible

    def recorded(self: GridSearch, steps: int, dt: float, weights: np.ndarray | None = None) -> np.ndarray | None:
        steps_solved.append(dt)
        return feasible(self, steps, dt, weights)

    plant = path_plant([ModePlant(*mode) for mode in MODES])
    limits = Limits(1.5022455108882162, 15.022455108882161, 1502.2455108882161)
    problem = Problem(plant, 0.39874664910835217, limits=limits)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(GridSearch, "feasible", recorded)
        result = synthesize(FAMILIES["time_optimal"], problem, TimeOptimalOptions())
    summary = result.summary
    assert "certifies" in summary.refinement
    assert summary.lower_bound_s == pytest.approx(summary.duration_s, rel=2e-9)
    assert summary.duration_s < 0.380572 * (1 - 5e-4)
    coarse = max(steps_solved)
    assert min(steps_solved) > coarse / 4 * (1 - 1e-3)  # the 4x grid's steps at most (a bisection's a hair less)
    poles = tuple(complex(-z * 2 * math.pi * f, 2 * math.pi * f * math.sqrt(1 - z * z)) for f, z in MODES)
    reference = GridMove(0.39874664910835217, poles, 1.5022455108882162, 15.022455108882161, 1502.2455108882161)
    assert not reference.feasible(summary.duration_s * (1 - 1e-5), 800)
    assert reference.feasible(summary.duration_s * (1 + 2e-3), 800)
    assert result.metrics.residual_amplitude < 1e-9 * 0.39874664910835217


def test_without_chatter_clears_the_one_step_pulses_of_a_cruise_and_keeps_the_ramps() -> None:
    # Held jerk 1500 m/s^3 on 2 ms steps: 5 steps of +J reach 15 m/s^2, 45 held, 5 of -J end at 1.5 m/s (the limit)
    # with no acceleration; then a chatter of 0.4 steps +, -, -, + (the velocity within 2.4e-3 above the limit, the
    # acceleration at most 1.2 m/s^2, under a tenth of A) and a cruise, then the mirror. The chatter's four steps are
    # cleared, nothing else (every ramp step starts or ends at 3 m/s^2 or more); without a velocity limit nothing is.
    ramp = [1.0] * 5 + [0.0] * 45 + [-1.0] * 5
    values = np.array([*ramp, 0.4, -0.4, -0.4, 0.4, *([0.0] * 25), *[-v for v in ramp]])
    problem = Problem(ModePlant(14.0, 0.03), 1.0, limits=Limits(1.5, 15.0, 1500.0))
    spec = spec_of(problem, TimeOptimalOptions(), selected_modes(problem, TimeOptimalOptions())[0])
    cleared = without_chatter(spec, values, 2e-3)
    expected = values.copy()
    expected[55:59] = 0.0
    assert cleared.tolist() == expected.tolist()
    free = Problem(ModePlant(14.0, 0.03), 1.0, limits=Limits(None, 15.0, 1500.0))
    free_spec = spec_of(free, TimeOptimalOptions(), selected_modes(free, TimeOptimalOptions())[0])
    assert without_chatter(free_spec, values, 2e-3) is values


def test_switched_splits_a_free_arc_between_two_levels_and_keeps_a_coast() -> None:
    # A free arc at 0.5 between +1 and -1 is the switch inside it: 3/4 of it at +1, 1/4 at -1 (the same change of
    # the level below), each joined to its neighbour; a free arc between two coasts stays free, a coast stays.
    assert switched([1.0, 1.0, 1.0], [1.0, 0.5, -1.0], [False, True, False]) == ([1.75, 1.25], [1.0, -1.0], [False] * 2)
    kept = ([1.0, 2.0, 1.0], [0.0, 0.3, 0.0], [False, True, False])
    assert switched(*kept) == ([1.0, 2.0, 1.0], [0.0, 0.3, 0.0], [False, True, False])


def test_the_least_duration_is_bisected_warm_and_its_vertex_solved_from_nothing() -> None:
    # The seed-29 straight line's coarse grid (96 steps): GridSearch.least_duration bisects the step with each LP
    # started from the last feasible one's basis, then solves the least duration's LP from nothing. The same
    # bisection with every LP from nothing (written here) reaches the same step length and the same vertex, bit for
    # bit: the warm LPs decide feasibility as the cold ones, and the vertex the refinement starts from is the cold one.
    from optim.families.time_optimal.lp import GridLp
    from optim.families.time_optimal.search import LEAST_RTOL

    plant = path_plant([ModePlant(*mode) for mode in MODES])
    limits = Limits(1.5022455108882162, 15.022455108882161, 1502.2455108882161)
    problem = Problem(plant, 0.39874664910835217, limits=limits)
    spec = spec_of(problem, TimeOptimalOptions(), selected_modes(problem, TimeOptimalOptions())[0])
    search = GridSearch(spec)
    grid = search.grid_optimum(spec.upper_guess_s)
    before = search.counter.solves
    least = search.least_duration(grid)
    low, high, values = grid.step_s * (grid.steps - 1) / grid.steps, grid.step_s, grid.values
    cold = 0
    while high - low > LEAST_RTOL * high:
        mid = 0.5 * (low + high)
        x = GridLp(spec, grid.steps, mid, [], search.counter).solve()
        cold += 1
        low, high, values = (mid, high, values) if x is None else (low, mid, x)
    assert least.step_s == high < grid.step_s  # (shorter than the grid optimum's: the bisection moved)
    assert np.array_equal(least.values, values)
    assert search.counter.solves - before - cold == cold + 1  # as many warm LPs, and the vertex's from nothing
