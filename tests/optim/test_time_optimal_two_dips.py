"""Cruises whose optimum dips twice (issue 28's speed work): structures.two_dip_starts, refined by SLSQP before any
LP and kept where the certificate proves them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.lp_reference import GridMove
from models.plants import ModePlant
from optim.families.time_optimal.arcs import exact_peaks, merged
from optim.families.time_optimal.certify import arc_states
from optim.families.time_optimal.family import selected_modes, spec_of
from optim.families.time_optimal.options import TimeOptimalOptions
from optim.families.time_optimal.shaped import rigid_of
from optim.families.time_optimal.structures import two_dip_starts
from optim.problem import Limits, Problem
from optim.registry import FAMILIES
from optim.synthesis import synthesize

# bench/programs.py's x axis: 14 Hz, zeta 0.03, within 1.5 m/s, 15 m/s^2, 1500 m/s^3
LIMITS = Limits(max_velocity=1.5, max_acceleration=15.0, max_jerk=1500.0)
PLANT = ModePlant(14.0, 0.03)
SEPARATE = [1, 0, -1, 0, -1, 1, -1, 0, -1, 1, -1, 0, -1, 0, 1, -1, 0, 1]  # a cruise, a small dip, a cruise, a dip...
FROM_ENTRY = [1, 0, -1, 1, -1, 0, -1, 1, -1, 0, -1, 0, 1, -1, 0, 1]  # the velocity overshoots into the first dip


@pytest.mark.parametrize(
    ("displacement", "before_s", "levels", "cruises"),
    [(-0.3984145401724464, 0.3794841171820951, SEPARATE, 3), (0.3896394864452512, 0.374565, FROM_ENTRY, 2)],
    ids=["seed-28-design-38", "seed-30-design-38"],
)
def test_a_cruise_that_dips_twice_is_certified_before_any_lp(
    displacement: float, before_s: float, levels: list[int], cruises: int
) -> None:
    # The 20-move programs' designs 38 of seeds 28 and 30 (bench/programs.py alone_problems). With one dip in the
    # cruise no start was certified: the search's answers were 379.484 ms (SLSQP at its cap, from a 4x grid's vertex)
    # and 374.565 ms, unproven, after 12 LPs and about 1 s each. The 600-step LP's vertex at its least duration (bench/
    # lp_reference.py's LP) dips twice: a first dip after a short cruise or at the entry, a second mid-cruise, and a
    # notch in the deceleration's hold. From those structures the certificate proves 379.478 and 374.406 ms with no
    # LP; the independent 800-step LP finds no command 1e-5 shorter (its grid costs it up to a step, 0.05 %) and one
    # 0.2 % longer (the check can tell). The answers' levels are the LP's structure: the velocity at its limit on
    # ``cruises`` coasts, the other coasts holds at -+A.
    problem = Problem(PLANT, displacement=displacement, limits=LIMITS)
    result = synthesize(FAMILIES["time_optimal"], problem, TimeOptimalOptions())
    summary = result.summary
    solution = result.design.detail.solution  # type: ignore[attr-defined]
    assert "certifies" in summary.refinement and solution.lp_solves == 0
    assert summary.duration_s < before_s * (1 - 1e-5)
    arcs = merged(solution.arcs)
    unit = [round(a.level / 1500.0) for a in arcs]
    assert unit == levels  # (the solution moves the positive way: the spec's move is |displacement|)
    spec = spec_of(problem, TimeOptimalOptions(), selected_modes(problem, TimeOptimalOptions())[0])
    acceleration, velocity = arc_states(spec, np.array([a.duration_s for a in arcs]), np.array(unit, dtype=float))
    coasts = np.flatnonzero(np.array(unit) == 0)
    cruising = coasts[np.abs(acceleration[coasts]) < 1e-9 * 15.0]
    holding = coasts[np.abs(np.abs(acceleration[coasts]) - 15.0) < 1e-9 * 15.0]
    assert len(cruising) == cruises and len(cruising) + len(holding) == len(coasts)
    assert np.allclose(np.abs(velocity[cruising]), 1.5, rtol=1e-12, atol=0)
    assert exact_peaks(arcs, spec.order, spec.start_state()).velocity <= 1.5 * (1 + 1e-12)
    pole = complex(-0.03 * 2 * math.pi * 14.0, 2 * math.pi * 14.0 * math.sqrt(1 - 0.03**2))
    reference = GridMove(abs(displacement), (pole,), 1.5, 15.0, 1500.0)
    assert not reference.feasible(summary.duration_s * (1 - 1e-5), 800)
    assert reference.feasible(summary.duration_s * (1 + 2e-3), 800)
    assert result.metrics.residual_amplitude < 1e-9 * abs(displacement)


def test_two_dip_starts_are_the_cruise_with_two_dips_and_a_notch_and_none_without_a_cruise() -> None:
    # Ruckig's optimum of seed 28's design 38 cruises 155.6 ms between 90 ms holds (its seven arcs); each start keeps
    # the ramps, has the levels of SEPARATE or FROM_ENTRY, and sizes every arc positive. A 2 cm move never cruises.
    problem = Problem(PLANT, displacement=0.3984145401724464, limits=LIMITS)
    spec = spec_of(problem, TimeOptimalOptions(), selected_modes(problem, TimeOptimalOptions())[0])
    starts = two_dip_starts(spec, rigid_of(spec))
    assert [lv for _, lv, _ in starts] == [[float(v) for v in SEPARATE], [float(v) for v in FROM_ENTRY]]
    for durations, _, free in starts:
        assert min(durations) > 0.0 and not any(free)
        assert durations[0] == pytest.approx(0.01, rel=1e-12) and durations[-1] == pytest.approx(0.01, rel=1e-12)
    short = Problem(PLANT, displacement=0.02, limits=LIMITS)
    short_spec = spec_of(short, TimeOptimalOptions(), selected_modes(short, TimeOptimalOptions())[0])
    assert two_dip_starts(short_spec, rigid_of(short_spec)) == []
