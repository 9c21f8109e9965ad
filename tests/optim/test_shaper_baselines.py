"""Baselines under an acceleration limit (optim.families.input_shaped.shapers): modified, multi-step, single ramp.

The paper is Chatlatanagulchai & Pongpanich (papers/chatlatanagulchai-zvd-acceleration-limit.txt);
PAPER-NOTES.md gives the exact-pole values.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from models.drives import rate_limit
from models.errors import Infeasible, InvalidParameter
from models.metrics import metrics
from models.plants import Mode, example_plants
from models.shapers import RampTrain
from models.simulation import simulate
from optim.families.input_shaped.shapers import (
    design_baseline,
    design_for_modes,
    design_shaper,
    fastest_cruise_velocity,
    fastest_single_ramp_cruise,
    fastest_steps,
    modified_baseline,
    multi_step_baseline,
    single_ramp_baseline,
    single_ramp_time_s,
)

PLANT = example_plants()["chatlatanagulchai_eq3"]
MODE = PLANT.modes()[0]


def exact_pole() -> complex:
    """The oscillatory pole of eq. (3)'s denominator, computed here with numpy's roots."""
    _, den = PLANT.command_transfer_function()
    return complex(max(np.roots(den), key=lambda p: p.imag))


def dense_slope(train: RampTrain, end: float) -> float:
    """max |dv/dt| by finite differences of v(t) on a fine grid (independent of the command's
    own slopes); a grid step of 1e-4 s resolves every piece of these commands."""
    t = np.arange(0.0, end, 1e-4)
    return float(np.max(np.abs(np.diff(train.velocity(t)) / 1e-4)))


# ------------------------------------------------------------------------------------------
# The paper's plant, ZVD and the modified baseline (acceptance items)


def test_eq3_mode_and_zvd_impulses_from_the_exact_poles():
    # Issue 6 / PAPER-NOTES: omega_n = 0.57703 rad/s, zeta = 0.057724 (eq. 3 as printed).
    assert MODE.natural_frequency_rad_s == pytest.approx(0.57703, abs=5e-6)
    assert MODE.damping_ratio == pytest.approx(0.057724, abs=5e-7)
    zvd = design_shaper("zvd", MODE).impulses
    # Sec. 4 prints A = (0.2973, 0.4959, 0.2068) to 4 decimals: half a unit of the last digit.
    np.testing.assert_allclose(zvd.amplitudes, [0.2973, 0.4959, 0.2068], atol=5e-5)
    # PAPER-NOTES: the exact poles give t = (0, 5.45352, 10.90705) s (the paper's 5.4538 and
    # 10.9076 come from rounded omega_n, zeta); 5 decimals printed: 5e-6.
    np.testing.assert_allclose(zvd.times_s, [0.0, 5.45352, 10.90705], atol=5e-6)
    # Eq. (9): t_2 = pi / omega_d with omega_d the imaginary part of the pole (round-off only).
    assert zvd.times_s[1] == pytest.approx(math.pi / exact_pole().imag, rel=1e-12)
    assert zvd.amplitudes.sum() == pytest.approx(1.0, abs=1e-15)  # eq. (6)


def test_modified_baseline_ramp_time_is_4_959_s():
    zvd = design_shaper("zvd", MODE).impulses
    baseline = modified_baseline(1.0, zvd, 0.1)
    # Sec. 4: Delta = a1 A2 / a = 4.959 s (4 digits printed; exact 0.495898 / 0.1).
    assert baseline.ramp_time_s == pytest.approx(4.959, abs=5e-4)
    assert baseline.ramp_time_s == pytest.approx(zvd.amplitudes.max() / 0.1, rel=1e-15)


def test_modified_command_respects_the_limit_ends_at_the_target_and_removes_the_residual():
    zvd = design_shaper("zvd", MODE).impulses
    baseline = modified_baseline(1.0, zvd, 0.1)
    shaped = baseline.train().shaped(zvd)
    command = shaped.to_command()
    # Slope never above a = 0.1: by finite differences (the velocity is piecewise linear, so the
    # differences are exact slopes up to round-off of 1e-12 / 1e-4) and by the exact peak.
    assert dense_slope(shaped, 20.0) <= 0.1 * (1 + 1e-7)
    assert command.peak_abs(2) <= 0.1 * (1 + 1e-12)
    assert command.evaluate(1, np.array([15.9, 1e3]))[1] == pytest.approx(1.0, abs=1e-15)  # eq. (6)
    # It passes the drive's limiter unchanged (Fig. 8 bottom: v_s = v_a).
    limited = rate_limit(command, 0.1)
    t = np.linspace(0.0, 30.0, 3001)
    np.testing.assert_allclose(limited.evaluate(1, t), command.evaluate(1, t), atol=1e-14)
    # Residual of x1: the modified command against the rate-limited plain ZVD step (Fig. 9).
    step = rate_limit(RampTrain.single(0.0, 0.0, 1.0).shaped(zvd).to_command(), 0.1)
    modified = metrics(simulate(PLANT, limited)).residual_amplitude
    degraded = metrics(simulate(PLANT, step)).residual_amplitude
    assert degraded > 1e-3  # the limiter does degrade the plain shaped step (measured 8.2e-3)
    assert modified * 100 <= degraded  # acceptance: at least 100 times smaller (measured ~1e-17)


def test_no_overlap_condition_is_required_and_explained():
    zvd = design_shaper("zvd", MODE).impulses
    # Delta = 0.4959/a <= t2 - t1 = 5.4535 holds for a >= 0.090932 (PAPER-NOTES' corrected condition).
    threshold = zvd.amplitudes.max() / np.diff(zvd.times_s).min()
    assert modified_baseline(1.0, zvd, threshold * 1.001).ramp_time_s <= np.diff(zvd.times_s).min()
    with pytest.raises(Infeasible) as info:
        modified_baseline(1.0, zvd, threshold * 0.99)
    assert info.value.field == "acceleration_limit"
    assert "t_(i+1) - t_i >= Delta" in info.value.reason
    assert f"{threshold:.6g}" in info.value.reason  # tells the user the smallest limit that works


# ------------------------------------------------------------------------------------------
# Multi-step baselines (Fig. 10)


def test_two_step_baseline_works_for_zv():
    zv = design_shaper("zv", MODE).impulses
    a1_amp, a2_amp = zv.amplitudes
    assert a1_amp > a2_amp  # the paper's assumption holds for ZV with damping
    baseline = multi_step_baseline(1.0, zv, 0.1)
    assert "two-step relations" in baseline.method
    heights, delta = baseline.step_heights, baseline.ramp_time_s
    # The paper's relations themselves: a1 + a2 = V, a1 A1/Delta = (a1 A2 + a2 A1)/Delta = a.
    assert heights.sum() == pytest.approx(1.0, abs=1e-15)
    assert heights[0] * a1_amp / delta == pytest.approx(0.1, rel=1e-12)
    assert (heights[0] * a2_amp + heights[1] * a1_amp) / delta == pytest.approx(0.1, rel=1e-12)
    shaped = baseline.train().shaped(zv)
    assert dense_slope(shaped, 30.0) <= 0.1 * (1 + 1e-7)
    # The LP construction finds the same (the relations are its optimum when they hold).
    lp_heights, lp_delta = fastest_steps(1.0, zv, 0.1, zv.times_s.copy())
    np.testing.assert_allclose(lp_heights, heights, atol=1e-9)
    assert lp_delta == pytest.approx(delta, rel=1e-9)
    # ... and the shaped command passes the limiter unchanged and leaves no residual.
    command = shaped.to_command()
    assert metrics(simulate(PLANT, rate_limit(command, 0.1))).residual_amplitude < 1e-12


def test_zvd_does_not_use_the_invalid_two_step_relations():
    zvd = design_shaper("zvd", MODE).impulses
    a1_amp, a2_amp, _ = zvd.amplitudes
    # PAPER-NOTES: for ZVD (A2 > A1) the relations give a2 < 0 and a slope of 2a. Built here by hand:
    b1 = a1_amp / (2 * a1_amp - a2_amp)
    paper_train = RampTrain(zvd.times_s[:2], np.full(2, b1 * a1_amp / 0.1), np.array([b1, 1 - b1]))
    assert 1 - b1 < 0
    assert dense_slope(paper_train.shaped(zvd), 40.0) > 1.5 * 0.1
    baseline = multi_step_baseline(1.0, zvd, 0.1)
    assert "linear programming" in baseline.method
    assert np.all(baseline.step_heights >= 0.0) and baseline.step_heights.sum() == pytest.approx(1.0, abs=1e-12)
    shaped = baseline.train().shaped(zvd)
    assert dense_slope(shaped, 40.0) <= 0.1 * (1 + 1e-7)
    assert metrics(simulate(PLANT, rate_limit(shaped.to_command(), 0.1))).residual_amplitude < 1e-12
    # It is the fastest: a brute-force scan over b1 (step 5e-3) with, for each, the smallest valid
    # Delta found by bisection, is never faster, and the scan comes within its resolution (Delta
    # moves by about (A2 - A1)/a = 2 s per unit of b1: 5e-3 in b1 is 1e-2 s).
    best = min(_smallest_delta(zvd, np.array([b, 1 - b])) for b in np.linspace(0.0, 1.0, 201))
    assert baseline.ramp_time_s <= best + 1e-6
    assert baseline.ramp_time_s >= best - 1.5e-2


def _smallest_delta(shaper, heights: np.ndarray) -> float:
    """Smallest Delta in [0.01, 10] s (bisection, to 1e-7 s) with shaped slope <= 0.1, assuming
    validity is monotone in Delta on that bracket (true for these two-step ZVD baselines)."""

    def ok(delta: float) -> bool:
        train = RampTrain(shaper.times_s[:2], np.full(2, delta), heights)
        return train.shaped(shaper).max_slope() <= 0.1 * (1 + 1e-12)

    low, high = 0.01, 10.0
    if not ok(high):
        return math.inf
    while high - low > 1e-7:
        mid = 0.5 * (low + high)
        low, high = (low, mid) if ok(mid) else (mid, high)
    return high


@pytest.mark.parametrize(("limit", "expected"), [(0.08, 0.79323683 / 0.08), (0.05, 20.0)])
def test_single_ramp_lengthened_past_the_overlap(limit, expected):
    # ZVD with a < 0.0909: the ramps must overlap. With Delta in (t2, 2 t2] two neighbours
    # overlap, slope (A1 + A2) V / Delta, so Delta = (A1 + A2)/a when that fits (a = 0.08:
    # 9.9155 s <= 10.907); otherwise all three overlap and Delta = V/a (a = 0.05: 20 s).
    zvd = design_shaper("zvd", MODE).impulses
    baseline = multi_step_baseline(1.0, zvd, limit, steps=1)
    assert baseline.ramp_time_s == pytest.approx(expected, rel=1e-7)  # 8 digits of A1 + A2 above
    shaped = baseline.train().shaped(zvd)
    assert shaped.max_slope() <= limit * (1 + 1e-9)
    # A slightly shorter ramp breaks the limit: it is the smallest.
    shorter = RampTrain.single(0.0, baseline.ramp_time_s * 0.999, 1.0).shaped(zvd)
    assert shorter.max_slope() > limit


def test_negative_velocities_mirror_the_positive_ones():
    zv = design_shaper("zv", MODE).impulses
    plus = multi_step_baseline(2.0, zv, 0.1)
    minus = multi_step_baseline(-2.0, zv, 0.1)
    np.testing.assert_allclose(minus.step_heights, -plus.step_heights)
    assert minus.ramp_time_s == plus.ramp_time_s
    zvd = design_shaper("zvd", MODE).impulses
    lp_plus = multi_step_baseline(2.0, zvd, 0.1)
    lp_minus = multi_step_baseline(-2.0, zvd, 0.1)
    np.testing.assert_allclose(lp_minus.step_heights, -lp_plus.step_heights, atol=1e-12)


def test_baseline_inputs_are_checked():
    zvd = design_shaper("zvd", MODE).impulses
    with pytest.raises(InvalidParameter) as info:
        design_baseline("modified", 1.0, zvd, None)
    assert info.value.field == "acceleration_limit"
    with pytest.raises(InvalidParameter) as info:
        multi_step_baseline(1.0, zvd, 0.1, steps=4)
    assert info.value.field == "baseline_steps"


def test_fastest_cruise_velocity_minimises_the_modified_move_time():
    # Move time of a modified rest-to-rest move: D/V + V max A/a + t_n, with Delta <= min gap.
    ei = design_shaper("ei", MODE).impulses
    biggest, gap = ei.amplitudes.max(), np.diff(ei.times_s).min()
    for displacement, limit in ((0.5, 0.1), (10.0, 0.1), (10.0, 1.0)):
        speeds = np.linspace(1e-3, limit * gap / biggest, 200001)  # the valid speeds
        times = displacement / speeds + speeds * biggest / limit
        best = speeds[np.argmin(times)]
        # The scan's step is (limit gap / biggest) / 2e5: agreement to a few steps.
        step = speeds[1] - speeds[0]
        assert fastest_cruise_velocity(displacement, ei, limit) == pytest.approx(best, abs=5 * step)


# ------------------------------------------------------------------------------------------
# The single ramp (modified where it fits, lengthened where it would overlap) and the cruise


@pytest.mark.parametrize("seed", range(4))
def test_single_ramp_closed_form_is_the_linear_programme(seed):
    # Random shapers (one or two modes) and limits: Delta from the window sums equals the one-step
    # linear programme's (an independent route: HiGHS over overlap patterns), to its 1e-9.
    rng = np.random.default_rng(seed)
    for _ in range(10):
        name = str(rng.choice(["zv", "mzv", "zvd", "zvdd", "ei", "2hump_ei"]))
        modes = tuple(
            Mode(2 * math.pi * rng.uniform(0.5, 5.0), rng.uniform(0.0, 0.15)) for _ in range(rng.integers(1, 3))
        )
        shaper = design_for_modes(name, modes).impulses
        velocity, limit = rng.uniform(0.1, 10.0), 10 ** rng.uniform(-1.0, 2.0)
        delta, _ = single_ramp_time_s(velocity, shaper, limit)
        assert delta == pytest.approx(fastest_steps(velocity, shaper, limit, shaper.times_s[:1].copy())[1], rel=1e-9)
        # ... and the shaped ramp's own slope (RampTrain.max_slope, a third route) is at the limit.
        assert RampTrain.single(0.0, delta, velocity).shaped(shaper).max_slope() == pytest.approx(limit, rel=1e-12)


def test_single_ramp_is_the_modified_baseline_where_that_fits():
    zvd = design_shaper("zvd", MODE).impulses
    assert single_ramp_baseline(1.0, zvd, 0.1).kind == "modified"  # Delta 4.959 <= t2 = 5.4535
    lengthened = single_ramp_baseline(1.0, zvd, 0.08)  # (A1 + A2)/a = 9.9155 s, as the test above
    assert lengthened.kind == "multi_step" and lengthened.ramp_time_s == pytest.approx(0.79323683 / 0.08, rel=1e-7)


def _end_by_bisection(shaper, displacement: float, velocity: float, limit: float) -> float:
    """D/V + the smallest valid ramp + t_n. Which shaped ramps overlap changes only where Delta crosses a
    difference of impulse times, and between two such the slope falls as Delta grows: so the first
    interval whose right end is valid (RampTrain.max_slope <= a) holds the answer, found there by
    bisection to 1e-12 relative."""

    def ok(delta: float) -> bool:
        return RampTrain.single(0.0, delta, velocity).shaped(shaper).max_slope() <= limit * (1 + 1e-12)

    t = shaper.times_s
    differences = np.unique(np.round((t[None, :] - t[:, None])[np.triu_indices(t.size, 1)], 12))
    edges = [0.0, *[d for d in differences if d < velocity / limit], velocity / limit]
    for low, high in itertools.pairwise(edges):
        if not ok(high):
            continue
        while high - low > 1e-12 * high:
            mid = 0.5 * (low + high)
            low, high = (low, mid) if ok(mid) else (mid, high)
        return displacement / velocity + high + shaper.duration_s
    raise AssertionError("a ramp at the limit is always valid")


@pytest.mark.parametrize(("displacement", "limit", "top"), [(10.0, 0.05, None), (2.0, 0.1, None), (10.0, 0.05, 0.6)])
def test_fastest_single_ramp_cruise_is_the_scan_minimum(displacement, limit, top):
    # ZVD on the paper's plant, where the fastest move's ramps overlap (a = 0.05) or not (2 m at 0.1):
    # a scan of 200 speeds up to max_velocity (or 2) with each ramp found by bisection never ends sooner
    # (1e-9 s: the bisection's resolution), and comes within one scan step of the optimum. (Here the
    # optimum sits where the modified ramp just fits, Delta = t_2: a = 0.05, 10 m.)
    zvd = design_shaper("zvd", MODE).impulses
    best = fastest_single_ramp_cruise(displacement, zvd, limit, top)
    speeds = np.linspace(1e-3, top or 2.0, 200)
    ends = [_end_by_bisection(zvd, displacement, v, limit) for v in speeds]
    ours = _end_by_bisection(zvd, displacement, best, limit)
    assert ours <= min(ends) + 1e-9
    assert top is None or best <= top
    step = speeds[1] - speeds[0]  # near the optimum the end changes by at most (D/V^2 + W/a) x step
    assert ours >= min(ends) - (displacement / best**2 + 1 / limit) * step


def test_explicit_modified_cruise_is_capped_by_max_velocity():
    ei = design_shaper("ei", MODE).impulses
    free = fastest_cruise_velocity(10.0, ei, 0.1)
    assert fastest_cruise_velocity(10.0, ei, 0.1, 0.5 * free) == 0.5 * free
    assert fastest_cruise_velocity(10.0, ei, 0.1, 2.0 * free) == free
