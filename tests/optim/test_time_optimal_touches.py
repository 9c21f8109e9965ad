"""Touch points of the velocity limit with a held jerk (issue 28's speed work): the refinement keeps the velocity
where the acceleration crosses 0 inside an arc within the limit (refine.velocity_peaks), and the certificate gives
the velocity limit's measure an atom where the command touches it (certify.touches)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.lp_reference import GridMove
from models.plants import ModePlant
from optim.families.time_optimal import refine
from optim.families.time_optimal.arcs import exact_peaks, merged
from optim.families.time_optimal.certify import BANG, TOUCH, arc_states, certificate, touches
from optim.families.time_optimal.family import selected_modes, spec_of
from optim.families.time_optimal.options import TimeOptimalOptions
from optim.families.time_optimal.types import Spec
from optim.problem import Limits, Problem
from optim.registry import FAMILIES
from optim.synthesis import synthesize

# bench/programs.py's z axis, move 14 of its 20-move program: 35 Hz, zeta 0.05, within 0.8 m/s, 10 m/s^2, 1000 m/s^3
MOVE_M = 0.0899396261421737
LIMITS = Limits(max_velocity=0.8, max_acceleration=10.0, max_jerk=1000.0)


def _spec(displacement: float = MOVE_M) -> Spec:
    problem = Problem(ModePlant(35.0, 0.05), displacement=displacement, limits=LIMITS)
    options = TimeOptimalOptions()
    return spec_of(problem, options, selected_modes(problem, options)[0])


def test_the_velocity_peak_rows_are_the_sampled_extremum_and_their_jacobian_the_finite_differences() -> None:
    # A held-jerk structure with free levels; each arc's v* against the velocity sampled on 20,001 points of the arc
    # (numpy, from the arcs' start states: the extremum where the acceleration crosses 0, else an end), and the
    # Jacobian against central differences (step 1e-7: truncation and round-off about 1e-8 of its size).
    spec = _spec()
    durations = [0.01, 0.0706, 0.0146, 0.0079, 0.003, 0.0133, 0.0033, 0.0054, 0.0054, 0.0594, 0.01]
    levels = [1.0, 0.0, -1.0, 1.0, 0.3, -1.0, 0.0, 1.0, -1.0, 0.0, 1.0]
    free = [k in (4, 7) for k in range(len(levels))]
    model = refine._Model(spec, durations, levels, free, [])
    z = model.z0 * 1.03
    z[model.count + 1] = 0.9
    values, jac = model.velocity_peaks(z, True)
    d, lv = model.durations_and_levels(z)
    acceleration, velocity = arc_states(spec, d, lv)
    assert values.size == 2 * model.count  # a row pair per arc
    for k in range(model.count):  # the arc's largest speed is at an end or at v*
        t = np.linspace(0.0, d[k], 20_001)
        sampled = velocity[k] + acceleration[k] * t + lv[k] * spec.scale * t**2 / 2
        peak = (1.0 - values[k]) * 0.8
        largest = max(abs(sampled[0]), abs(sampled[-1]), abs(peak))  # (the samples miss the extremum by < 1e-10)
        assert np.max(np.abs(sampled)) - 1e-15 <= largest <= np.max(np.abs(sampled)) + 1e-9
        assert np.min(np.abs(sampled - peak)) <= 1e-9  # v* is a velocity the arc takes
    numeric = np.zeros_like(jac)
    for i in range(z.size):
        step = np.zeros_like(z)
        step[i] = 1e-7
        numeric[:, i] = (model.velocity_peaks(z + step, False)[0] - model.velocity_peaks(z - step, False)[0]) / 2e-7
    assert np.max(np.abs(numeric - jac)) <= 1e-7 * np.max(np.abs(jac))


def test_touches_split_a_bang_arc_where_the_velocity_touches_its_limit() -> None:
    # +J for 10 ms reaches A = 10; held 70 ms: v = 0.75; -J for 14 ms: the acceleration crosses 0 at 10 ms, where
    # v = 0.75 + 0.05 = 0.8 (the limit), and ends at -4; +J 6 ms (-4 -> +2): it crosses 0 again at 4 ms, at
    # v = 0.8 - 2 x 0.008 = 0.784 (below the limit: no touch)
    spec = _spec()
    durations = np.array([0.01, 0.07, 0.014, 0.006, 0.012, 0.004])
    levels = np.array([1.0, 0.0, -1.0, 1.0, -1.0, 1.0])
    d1, _l1, origin1, kind1 = touches(spec, durations, levels, True)
    assert d1.tolist() == pytest.approx([0.01, 0.07, 0.01, 0.0, 0.004, 0.006, 0.012, 0.004], abs=1e-15)
    assert kind1.tolist() == [BANG, BANG, BANG, TOUCH, BANG, BANG, BANG, BANG]
    assert origin1.tolist() == [0, 1, 2, 2, 2, 3, 4, 5]
    same = touches(spec, durations, levels, False)
    assert same[0] is durations and same[3].tolist() == [BANG] * 6


def test_a_touch_point_command_is_certified_and_an_independent_lp_finds_none_shorter() -> None:
    # Before the velocity peaks were held, SLSQP's commands broke the limit where the acceleration crosses 0 inside
    # an arc (v = 0.8056 against 0.8) and the answer was a refined local optimum, 203.130 ms, not certified. Now the
    # answer touches the limit inside its first -J arc, dips and coasts; the certificate proves it with an atom of
    # the velocity limit's measure at the touch (203.023 ms). The independent LP of bench/lp_reference.py (held jerk
    # on 1,600 steps, the velocity checked at every node and mid-step: exact at its nodes) finds no command 1e-5
    # shorter (the LP's grid: one step is 1.3e-4 s, so this says the certificate is not wrong by more than its grid).
    problem = Problem(ModePlant(35.0, 0.05), displacement=MOVE_M, limits=LIMITS)
    result = synthesize(FAMILIES["time_optimal"], problem, TimeOptimalOptions())
    summary = result.summary
    assert "certifies" in summary.refinement
    assert summary.lower_bound_s == pytest.approx(summary.duration_s, rel=2e-9)
    assert summary.duration_s < 0.203130 * (1 - 1e-4)  # the local optimum before
    solution = result.design.detail.solution  # type: ignore[attr-defined]
    spec = _spec()
    arcs = merged(solution.arcs)
    durations = np.array([a.duration_s for a in arcs])
    levels = np.array([a.level for a in arcs]) / spec.scale
    assert TOUCH in touches(spec, durations, levels, True)[3]
    proof = certificate(spec, arcs)
    assert proof is not None and len(proof.atoms) >= 1
    peaks = exact_peaks(arcs, spec.order, spec.start_state())
    assert peaks.velocity <= 0.8 * (1 + 1e-12)
    pole = complex(-0.05 * 2 * math.pi * 35.0, 2 * math.pi * 35.0 * math.sqrt(1 - 0.05**2))
    reference = GridMove(abs(MOVE_M), (pole,), 0.8, 10.0, 1000.0)
    assert not reference.feasible(summary.duration_s * (1 - 1e-5), 1600)
    assert result.metrics.residual_amplitude < 1e-9 * abs(MOVE_M)


def test_a_cruising_move_is_certified_from_the_cruise_structures_before_any_lp() -> None:
    # bench/programs.py's x axis, move 1 of its 20-move program (14 Hz, zeta 0.03; 0.426 m within 1.5 m/s, 15 m/s^2,
    # 1500 m/s^3: it cruises). No predicted structure converged certified and the search answered a refined local
    # optimum, 395.937 ms, after 13 LPs (1.8 s). From structures.cruise_starts (a touch and dip of the velocity, a
    # notch in the deceleration's hold), refined and repaired, the certificate proves 395.645 ms with no LP solved;
    # the independent 800-step LP of bench/lp_reference.py finds no command 1e-5 shorter, and one 0.2 % longer (its
    # own grid costs it up to a step, 0.05 %: the check can tell).
    from optim.families.time_optimal.shaped import rigid_of
    from optim.families.time_optimal.structures import cruise_starts

    displacement = 0.42591696799107887
    limits = Limits(max_velocity=1.5, max_acceleration=15.0, max_jerk=1500.0)
    problem = Problem(ModePlant(14.0, 0.03), displacement=displacement, limits=limits)
    options = TimeOptimalOptions()
    spec = spec_of(problem, options, selected_modes(problem, options)[0])
    starts = cruise_starts(spec, rigid_of(spec))
    assert len(starts) == 3 and all(lv == starts[0][1] for _, lv, _ in starts)
    result = synthesize(FAMILIES["time_optimal"], problem, options)
    summary = result.summary
    assert "certifies" in summary.refinement and result.design.detail.solution.lp_solves == 0  # type: ignore[attr-defined]
    assert summary.duration_s < 0.395937 * (1 - 5e-4)
    pole = complex(-0.03 * 2 * math.pi * 14.0, 2 * math.pi * 14.0 * math.sqrt(1 - 0.03**2))
    reference = GridMove(displacement, (pole,), 1.5, 15.0, 1500.0)
    assert not reference.feasible(summary.duration_s * (1 - 1e-5), 800)
    assert reference.feasible(summary.duration_s * (1 + 2e-3), 800)
    assert result.metrics.residual_amplitude < 1e-9 * displacement
    short = Problem(ModePlant(14.0, 0.03), displacement=0.02, limits=limits)  # no cruise: no such start
    short_spec = spec_of(short, options, selected_modes(short, options)[0])
    assert cruise_starts(short_spec, rigid_of(short_spec)) == []


def test_switching_times_made_stationary_turn_slsqps_near_optimum_into_a_certified_one(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # bench/programs.py's x axis, move 10 (0.298 m, 14 Hz): from the cruise structure with the second widths, SLSQP
    # and its repairs stop 1e-5 of a period off the optimum (the duration is flat in the free switching time there),
    # where sigma has the wrong sign by 2e-6 of its size next to a switch: not certified. Newton on the KKT
    # conditions (stationary.py) moves the switching times by about that and the certificate proves the result; its
    # duration is SLSQP's to 1e-9 (flat) and not longer (a proven minimum).
    from functools import partial

    from optim.families.time_optimal import candidates, structures
    from optim.families.time_optimal.certify import certificate
    from optim.families.time_optimal.family import limits_met
    from optim.families.time_optimal.search import GridSearch
    from optim.families.time_optimal.shaped import rigid_of
    from optim.families.time_optimal.stationary import stationary

    problem = Problem(ModePlant(14.0, 0.03), displacement=0.29773393760726236, limits=Limits(1.5, 15.0, 1500.0))
    options = TimeOptimalOptions()
    spec = spec_of(problem, options, selected_modes(problem, options)[0])
    start = structures.cruise_starts(spec, rigid_of(spec))[1]  # (0.05, 0.1, 0.05) periods
    with monkeypatch.context() as patched:  # SLSQP's point alone: not certified
        patched.setattr(candidates, "stationary", lambda spec, arcs: None)
        alone = candidates.Best(spec, GridSearch(spec), partial(limits_met, problem, spec))
        alone.refine_from(start)
        assert alone.found is not None and alone.proof is None
    trial = candidates.Best(spec, GridSearch(spec), partial(limits_met, problem, spec))
    trial.refine_from(start)
    assert trial.found is not None and trial.proof is not None  # made stationary within offer
    assert "made stationary" in trial.found.note
    found = trial.found.arcs
    assert certificate(spec, found) is not None
    exact = stationary(spec, found)  # a stationary command stays where it is
    assert exact is not None
    assert [a.duration_s for a in exact] == pytest.approx([a.duration_s for a in found], abs=1e-12)
    assert trial.found.duration_s == pytest.approx(alone.found.duration_s, rel=1e-9)
    assert trial.found.duration_s <= alone.found.duration_s * (1 + 1e-12)


def test_a_touch_point_the_certificate_refuses_becomes_a_short_cruise_that_it_proves() -> None:
    # bench/programs.py's seed-28 move 19, z axis (-0.0787 m): the search's answer, 189.59649 ms, touched the
    # velocity limit where its acceleration crosses 0 inside a -J arc, and no multipliers proved it (with the atom,
    # sigma has the wrong sign around the touch, 5e-3 of its size). repair.touch_cruises puts a cruise of
    # CRUISE_SHARE of the duration there (here: the arcs before, from those times); refined, it rides the limit
    # 0.067 ms and the certificate proves it, 189.59632 ms (0.33 s of search before, now 0.02). The independent
    # 800-step LP of bench/lp_reference.py finds no command 1e-5 shorter, and one 0.2 % longer.
    from optim.families.time_optimal.repair import CRUISE_SHARE, touch_cruises

    displacement = -0.07868467750781113
    spec = _spec(displacement)
    durations = [0.01, 0.0620547, 0.0080362, 0.0071636, 0.0191274, 0.0055623, 0.0056697, 0.0056697, 0.0563129, 0.01]
    levels = [1.0, 0.0, -1.0, 1.0, -1.0, 0.0, 1.0, -1.0, 0.0, 1.0]
    start = touch_cruises(spec, durations, levels)
    assert start is not None
    cruise_d, cruise_l, free = start
    total = sum(durations)
    assert cruise_l == [*levels[:5], 0.0, -1.0, *levels[5:]] and not any(free)
    assert cruise_d[5] == pytest.approx(CRUISE_SHARE * total, rel=1e-12) and sum(cruise_d) == pytest.approx(total)
    assert touch_cruises(spec, [0.01, 0.07, 0.01], [1.0, 0.0, -1.0]) is None  # (0.75 m/s at most: no touch)
    problem = Problem(ModePlant(35.0, 0.05), displacement=displacement, limits=LIMITS)
    result = synthesize(FAMILIES["time_optimal"], problem, TimeOptimalOptions())
    summary = result.summary
    assert "certifies" in summary.refinement and summary.duration_s < 0.18959649 * (1 - 5e-7)
    arcs = merged(result.design.detail.solution.arcs)  # type: ignore[attr-defined]
    lengths = np.array([a.duration_s for a in arcs])
    below, velocity = arc_states(spec, lengths, np.array([a.level for a in arcs]) / spec.scale)
    cruising = (np.array([a.level for a in arcs]) == 0.0) & (np.abs(below) < 1e-9) & (np.abs(velocity) > 0.8 - 1e-9)
    assert np.any(cruising) and float(np.max(lengths[cruising])) > 1e-5
    pole = complex(-0.05 * 2 * math.pi * 35.0, 2 * math.pi * 35.0 * math.sqrt(1 - 0.05**2))
    reference = GridMove(abs(displacement), (pole,), 0.8, 10.0, 1000.0)
    assert not reference.feasible(summary.duration_s * (1 - 1e-5), 800)
    assert reference.feasible(summary.duration_s * (1 + 2e-3), 800)
    assert result.metrics.residual_amplitude < 1e-9 * abs(displacement)
