"""Three modes mode by mode (optim.families.time_optimal.by_modes): the proven command of the two lowest modes with
a reversal of the third, solved by Newton and proven by the certificate before any LP; else that command, a
relaxation's minimum, bounds the answer from below. Checked against the search without it (a second method: never
shorter than a proven minimum), the independent LP of bench/lp_reference.py, ZV-shaped Ruckig in closed form and
the residual by QUADPACK (bench/time_optimal_random.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.lp_reference import GridMove
from bench.time_optimal import product_of_modes
from bench.time_optimal_random import residual_fraction, zv_ruckig_s
from models.plant_base import Mode
from models.plants import TransferFunctionPlant
from models.rigid_motion import rigid_move
from models.shapers import zv_family
from optim.families.time_optimal import minimum_time
from optim.families.time_optimal.options import TimeOptimalOptions
from optim.families.time_optimal.shaped import shaped_arcs, shaped_command
from optim.families.time_optimal.types import Arc
from optim.problem import Limits, Problem
from optim.registry import FAMILIES
from optim.synthesis import synthesize
from vibfree import synthesize as synthesize_request

# Three-mode moves 10 and 4 of bench/time_optimal_speed.py, rounded (each mode 1.5-4 times faster than the one
# before, all cancelled). Move 10 (a held jerk): the search answered the shaped rigid optimum, 1.1 % longer than the
# proven minimum found mode by mode. Move 4 (a held acceleration, modes at 1.6, 6.3 and 24.8 kHz): nothing is proven
# for three modes, but the two lowest modes' minimum is, and the third mode's half period is 8e-5 of the move.
MOVE_10 = ([(269.0, 0.195), (926.0, 0.075), (2291.0, 0.188)], 0.0501, {"max_acceleration": 21.37, "max_jerk": 402.0})
MOVE_4 = (
    [(1598.0, 0.101), (6344.0, 0.1), (24790.0, 0.106)],
    0.01904,
    {"max_velocity": 0.09865, "max_acceleration": 1.4612},
)
THREE = TimeOptimalOptions(modes=(0, 1, 2))


def _problem(modes: list[tuple[float, float]], move: float, limits: dict[str, float]) -> Problem:
    tf = product_of_modes(modes)
    plant = TransferFunctionPlant(tuple(tf["numerator"]), tuple(tf["denominator"]))
    return Problem(plant, displacement=move, limits=Limits(**limits))


def _poles(modes: list[tuple[float, float]]) -> tuple[complex, ...]:
    return tuple(complex(-z * 2 * math.pi * f, 2 * math.pi * f * math.sqrt(1 - z * z)) for f, z in modes)


def _request(modes: list[tuple[float, float]], move: float, limits: dict[str, float]) -> dict[str, object]:
    return {"plant": product_of_modes(modes), "displacement": move, "limits": limits, "modes": [0, 1, 2]}


def test_three_modes_are_proven_mode_by_mode_before_any_lp(monkeypatch: pytest.MonkeyPatch) -> None:
    modes, move, limits = MOVE_10
    problem = _problem(*MOVE_10)
    proven = synthesize(FAMILIES["time_optimal"], problem, THREE).summary
    assert proven.search.lp_solves == 0 and "found mode by mode" in proven.refinement
    assert proven.lower_bound_s >= proven.duration_s * (1 - 2e-9)  # certified
    # the recipe, in closed form: the double-S plus half a damped period per mode (measured 1.1 % longer)
    request = _request(*MOVE_10)
    rigid_s, zv_s = zv_ruckig_s(request, [(2 * math.pi * f, z) for f, z in modes])
    assert rigid_s < proven.duration_s < zv_s
    # the search alone (measured: the shaped rigid optimum, 161.24 ms) finds nothing shorter (weak duality)
    monkeypatch.setattr(minimum_time, "BY_MODES", 99)
    searched = synthesize(FAMILIES["time_optimal"], problem, THREE).summary
    assert searched.search.lp_solves > 0 and searched.duration_s >= proven.duration_s * (1 - 1e-9)
    # the independent LP on 1,600 steps finds no command 1e-6 shorter than the proven one (it would if the
    # certificate were wrong by more than its grid's restriction allows)
    reference = GridMove(move, _poles(modes), None, limits["max_acceleration"], limits["max_jerk"])
    assert not reference.feasible(proven.duration_s * (1 - 1e-6), 1600)


def test_a_near_rigid_third_mode_is_answered_within_1e4_of_a_proven_bound(monkeypatch: pytest.MonkeyPatch) -> None:
    modes, move, limits = MOVE_4
    problem = _problem(*MOVE_4)
    near = synthesize(FAMILIES["time_optimal"], problem, THREE).summary
    assert near.search.lp_solves == 0 and "2 lowest modes (a relaxation" in near.lower_bound_method
    assert near.lower_bound_s <= near.duration_s <= near.lower_bound_s * (1 + minimum_time.NEAR)
    # the bound is the two lowest modes' minimum: the LP finds no command of those two modes 1e-6 shorter
    relaxed = GridMove(move, _poles(modes[:2]), limits["max_velocity"], limits["max_acceleration"], None)
    assert not relaxed.feasible(near.lower_bound_s * (1 - 1e-6), 1600)
    # the search alone finds nothing below the bound (measured: the shaped rigid optimum, 0.11 % longer)
    monkeypatch.setattr(minimum_time, "BY_MODES", 99)
    searched = synthesize(FAMILIES["time_optimal"], problem, THREE).summary
    assert searched.duration_s >= near.lower_bound_s and searched.duration_s > near.duration_s
    monkeypatch.undo()
    # the answer leaves no residual at any of the three modes (QUADPACK per arc), and beats the closed-form recipe
    request = _request(*MOVE_4)
    design = synthesize_request("time-optimal", request).answer["design"]
    assert design["duration_s"] == pytest.approx(near.duration_s, rel=1e-12)
    assert residual_fraction(design, [(2 * math.pi * f, z) for f, z in modes], move) < 1e-9
    assert design["duration_s"] < zv_ruckig_s(request, [(2 * math.pi * f, z) for f, z in modes])[1]


def test_a_shaped_command_is_the_shaped_rigid_move_arc_for_arc() -> None:
    # shaped.shaped_command (any command's arcs, convolved) against shaped_arcs (the rigid move's phases): the same
    # arcs to round-off on a double-S shaped by a ZV at 40 Hz, zeta 0.1 (the rigid move's levels are absolute).
    rigid = rigid_move(0.3, True, 1.0, 5.0, 120.0)
    shaper = zv_family(Mode(2 * math.pi * 40.0, 0.1), 0)
    widths = np.diff(rigid.edges_s)
    arcs = tuple(
        Arc(float(s), float(d), float(v))
        for s, d, v in zip(rigid.edges_s[:-1], widths, rigid.levels, strict=True)
        if d > 0
    )
    ours = shaped_command(arcs, shaper)
    theirs = shaped_arcs(rigid, shaper)
    assert len(ours) == len(theirs)
    for a, b in zip(ours, theirs, strict=True):
        assert a.start_s == pytest.approx(b.start_s, abs=1e-12) and a.level == pytest.approx(b.level, rel=1e-12)
