"""The time-optimal family against independent computations.

- The known answer (one undamped 40 Hz mode, a = 10, v = 5, D = 0.12): the closed-form symmetric
  three-switch solution, 219.7077 ms with arcs +104.03, -5.83, +5.83, -104.03 ms (the issue's figures,
  reproduced by tests/time_optimal_oracle.py where present). Its residual is computed by integrating
  the mode's ODE arc by arc with scipy (DOP853, rtol 1e-13), not with the service's formulas.
- Robust bands and derivative orders: V recomputed with models.sensitivity + the rigid reference on
  a grid of its own (not the LP's weights, not the family's check points).
- Limits on the returned samples (the pipeline's hard check, 1e-9 relative), the torque on a finer
  resampling simulated with models.simulation, lower_bound_s <= duration_s and >= the kinematic floor.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from models.errors import Infeasible, InvalidParameter, SolverTimedOut
from models.plants import ModePlant, TransferFunctionPlant, TwoInertiaPlant
from models.sensitivity import residual_envelope, sensitivity
from models.simulation import simulate
from optim.families.time_optimal import highs_model
from optim.families.time_optimal.options import Robustness, TimeOptimalOptions
from optim.problem import Limits, Problem
from optim.registry import FAMILIES
from optim.solver import SolveCaps
from optim.synthesis import Result, synthesize

FAMILY = FAMILIES["time_optimal"]
KNOWN = Problem(ModePlant(40.0, 0.0), displacement=0.12, limits=Limits(max_velocity=5.0, max_acceleration=10.0))


def _design(problem: Problem, options: TimeOptimalOptions | None = None) -> Result:
    return synthesize(FAMILY, problem, options or TimeOptimalOptions())


def _ode_residual(result: Result, omega: float, zeta: float) -> float:
    """Free-vibration amplitude of the load's deflection after the command, by integrating
    x'' + 2 zeta w x' + w^2 x = -a(t) (x = load - motor) arc by arc (a is constant on each arc)."""
    state = np.zeros(2)
    for arc in result.summary.arcs:
        level, h = arc.level, arc.duration_s

        def rhs(_t: float, y: np.ndarray, level: float = level) -> list[float]:
            return [y[1], -2 * zeta * omega * y[1] - omega**2 * y[0] - level]

        state = solve_ivp(rhs, (0.0, h), state, method="DOP853", rtol=1e-13, atol=1e-16).y[:, -1]
    wd = omega * math.sqrt(1 - zeta**2)
    x, v = state
    return float(math.hypot(x, (v + zeta * omega * x) / wd))


def _v(problem: Result | Problem, result: Result, ratios: np.ndarray, zeta: float) -> np.ndarray:
    """V (%) recomputed from models.sensitivity and the rigid reference's envelope."""
    assert isinstance(problem, Problem)
    omega = problem.plant.modes()[0].natural_frequency_rad_s
    amplitude = sensitivity(result.design.command, omega, ratios, [zeta]).amplitude[0]
    envelope = residual_envelope(problem.rigid_reference, ratios * omega, np.full(ratios.size, zeta), 0)
    out: np.ndarray = 100 * amplitude / envelope
    return out


def test_known_answer_is_the_closed_form_three_switch_solution() -> None:
    result = _design(KNOWN)
    design = result.summary
    # 219.7077 ms from the issue (the closed form); 0.01 % is its acceptance tolerance.
    assert design.duration_s == pytest.approx(0.2197077, rel=1e-4)
    durations_ms = [1e3 * a.duration_s for a in design.arcs]
    levels = [a.level for a in design.arcs]
    assert levels == [10.0, -10.0, 10.0, -10.0]
    assert durations_ms == pytest.approx([104.03, 5.83, 5.83, 104.03], abs=0.01)  # the two decimals
    # Residual below 1e-9 of the move, by an independent ODE integration (its own error ~1e-13 of the move).
    assert _ode_residual(result, 2 * math.pi * 40.0, 0.0) < 1e-9 * 0.12
    # Certificate: the bound never exceeds the duration and is at least the rigid bang-bang time.
    assert 2 * math.sqrt(0.12 / 10.0) - 1e-12 <= design.lower_bound_s <= design.duration_s
    assert result.limit_violations == ()
    end = result.command.end_index()
    assert result.command.derivatives[0, end] == pytest.approx(0.12, rel=1e-12)
    assert abs(result.command.derivatives[1, end]) < 1e-12


@pytest.mark.parametrize(("frequency_hz", "displacement"), [(40.0, 0.12), (2.0, 0.3), (40.0, 0.02), (10.0, 0.05)])
def test_nominal_matches_the_independent_oracle(frequency_hz: float, displacement: float) -> None:
    """tests/time_optimal_oracle.py: the symmetric three-switch solution by brentq from its structure, proven
    optimal by a maximum-principle check (no coast: the velocity limit is not reached here); 0.01 % is the
    issue's tolerance on the known answer, applied to every such move."""
    from tests import time_optimal_oracle as oracle

    w = 2 * math.pi * frequency_hz
    exact = oracle.minimum_time(w, 10.0, 5.0, displacement)
    problem = Problem(ModePlant(frequency_hz, 0.0), displacement=displacement, limits=Limits(5.0, 10.0))
    assert _design(problem).summary.duration_s == pytest.approx(exact, rel=1e-4)


@pytest.mark.parametrize(
    ("plant", "displacement", "limits"),
    [
        (ModePlant(5.0, 0.05), 0.3, Limits(max_velocity=1.0, max_acceleration=10.0)),
        (ModePlant(2.0, 0.0), 1.0, Limits(max_velocity=2.0, max_acceleration=10.0)),
        (ModePlant(5.0, 0.05), 0.3, Limits(max_velocity=1.0, max_acceleration=10.0, max_jerk=200.0)),
    ],
    ids=["damped_cruise", "long_undamped", "jerk_limited"],
)
def test_nominal_designs_leave_no_residual_and_meet_the_limits(
    plant: ModePlant, displacement: float, limits: Limits
) -> None:
    problem = Problem(plant, displacement=displacement, limits=limits)
    result = _design(problem)
    mode = plant.modes()[0]
    if limits.max_jerk is None:  # the ODE check integrates a constant acceleration per arc
        assert _ode_residual(result, mode.natural_frequency_rad_s, mode.damping_ratio) < 1e-9 * displacement
    amplitude = sensitivity(result.design.command, mode.natural_frequency_rad_s, [1.0], [mode.damping_ratio]).amplitude
    assert float(amplitude[0, 0]) < 1e-9 * displacement
    assert result.limit_violations == ()
    design = result.summary
    assert problem.kinematic_floor_s() - 1e-12 <= design.lower_bound_s <= design.duration_s
    # Faster than ZV shaping of the rigid move (which adds half a damped period to its duration, here
    # D/v + v/a (+ a/j): every case reaches both limits).
    assert limits.max_velocity is not None and limits.max_acceleration is not None
    rigid = displacement / limits.max_velocity + limits.max_velocity / limits.max_acceleration
    rigid += 0.0 if limits.max_jerk is None else limits.max_acceleration / limits.max_jerk
    assert design.duration_s < rigid + 0.5 * mode.damped_period_s


def test_rest_to_velocity() -> None:
    problem = Problem(ModePlant(5.0, 0.05), target_velocity=0.5, limits=Limits(max_acceleration=10.0))
    result = _design(problem)
    end = result.command.end_index()
    assert result.command.derivatives[1, end] == pytest.approx(0.5, rel=1e-12)
    assert abs(result.command.derivatives[2, end]) < 1e-12
    assert result.metrics.residual_velocity_amplitude < 1e-9 * 0.5


@pytest.mark.parametrize("band", [(0.9, 1.1), (0.85, 1.15)])
def test_robust_band_is_covered_on_an_independent_dense_grid(band: tuple[float, float]) -> None:
    problem = Problem(ModePlant(5.0, 0.05), displacement=0.3, limits=Limits(max_velocity=1.0, max_acceleration=10.0))
    result = _design(problem, TimeOptimalOptions(Robustness(frequency_ratio_range=band)))
    ratios = np.linspace(band[0], band[1], 3001)  # not the family's 2001 nor the search's 1500 points
    assert float(np.max(_v(problem, result, ratios, 0.05))) <= 5.0 * (1 + 1e-9)
    robustness = result.summary.robustness
    assert robustness.covers_request
    assert robustness.achieved.frequency_ratio_range[0] <= band[0]
    assert robustness.achieved.frequency_ratio_range[1] >= band[1]
    nominal = _design(problem)
    # Robustness costs time, but less than the ZVD-shaped rigid move's extra period.
    assert nominal.summary.duration_s < result.summary.duration_s
    assert result.summary.duration_s < problem.kinematic_floor_s() + problem.plant.modes()[0].damped_period_s
    assert result.summary.lower_bound_s <= result.summary.duration_s


@pytest.mark.parametrize(
    "problem",
    [KNOWN, Problem(ModePlant(10.0, 0.1), displacement=0.2, limits=Limits(max_acceleration=10.0))],
    ids=["readme", "10Hz-zeta0.1"],
)
def test_a_narrower_band_is_never_longer_than_a_wider_one(problem: Problem) -> None:
    # A wider band's command meets every narrower band inside it, so the narrower answer can be no longer (issue
    # 25). The README's move gave 227.6816 ms for +-5 % against 227.6214 for +-10 % when the search's grid step
    # depended on the band's low end; on one grid (the band-independent upper guess) each answer is the least
    # feasible step count of its band, and a narrower band's feasible set holds the wider's. Equal durations differ
    # by the round-off of summing different arcs: 1e-12 relative is a thousand times that.
    widths = (0.02, 0.05, 0.1, 0.2)
    durations = [
        _design(problem, TimeOptimalOptions(Robustness(frequency_ratio_range=(1 - w, 1 + w)))).summary.duration_s
        for w in widths
    ]
    assert all(a <= b * (1 + 1e-12) for a, b in itertools.pairwise(durations)), durations
    assert durations[0] < durations[-1]  # the band costs time: the check is not between equal answers only


def test_derivative_order_flattens_the_residual_at_the_mode() -> None:
    problem = Problem(ModePlant(5.0, 0.05), displacement=0.3, limits=Limits(max_velocity=1.0, max_acceleration=10.0))
    result = _design(problem, TimeOptimalOptions(Robustness(derivative_order=1)))
    # With F(w0) = F'(w0) = 0 the residual is O(eps^2): halving eps divides V by about 4 (not 2).
    v1, v2 = _v(problem, result, np.array([1.02, 1.01]), 0.05)
    assert 3.5 < v1 / v2 < 4.5


def test_torque_limit_holds_on_a_fine_resampling() -> None:
    plant = TwoInertiaPlant(0.005, 0.005, 12.633093633, 0.0)  # 8 Hz, Cusimano's Table 2 motor with J_L = J_M
    problem = Problem(plant, displacement=3.0, limits=Limits(max_velocity=150.0, max_torque_nm=10.0))
    result = _design(problem)
    fine = result.design.command.resampled(result.summary.duration_s / 20000)
    torque = simulate(plant, fine).motor_torque_nm
    assert torque is not None
    assert float(np.max(np.abs(torque))) <= 10.0 * (1 + 1e-9)
    assert result.metrics.residual_amplitude < 1e-9 * 3.0
    # No faster than the inertia centre allows: T >= 2 sqrt(D (J_M + J_L) / M).
    assert result.summary.duration_s >= 2 * math.sqrt(3.0 * 0.01 / 10.0)


def test_every_mode_of_a_transfer_function_is_cancelled() -> None:
    w1, w2 = 2 * math.pi * 3.0, 2 * math.pi * 11.0
    z1, z2 = 0.02, 0.05
    den = np.polymul([1, 2 * z1 * w1, w1**2], [1, 2 * z2 * w2, w2**2])
    plant = TransferFunctionPlant(numerator=(float(den[-1]),), denominator=tuple(float(c) for c in den))
    problem = Problem(plant, displacement=0.2, limits=Limits(max_velocity=0.5, max_acceleration=5.0))
    result = _design(problem)
    residuals = [m.residual_amplitude for m in result.metrics.modes]
    assert len(residuals) == 2
    assert max(residuals) < 1e-9 * 0.2
    assert [m.constraint for m in result.summary.modes] == ["zero_residual", "zero_residual"]
    # Shorter than ZV shaping for the slow mode alone (rigid 0.5 s + half its period); the cascade of ZV
    # shapers for both modes (0.71 s) once replaced a shorter grid design.
    assert result.summary.duration_s < 0.5 + 0.5 / 3.0


def test_a_band_no_command_can_meet_within_the_cap_is_proven_infeasible() -> None:
    problem = Problem(ModePlant(5.0, 0.0), displacement=0.3, limits=Limits(max_velocity=1.0, max_acceleration=10.0))
    options = TimeOptimalOptions(
        Robustness(frequency_ratio_range=(0.5, 2.0), max_percentage_vibration=0.01), max_duration_s=0.6
    )
    with pytest.raises(Infeasible, match="relaxation"):
        _design(problem, options)


def test_a_band_bound_that_underflows_is_refused_naming_the_field_not_fed_to_the_lp() -> None:
    # The fuzz bench's 500: V_max = 5e-324 % (the schema now asks >= 1e-6 %; the Python API has no schema) made
    # the band's bound 0.0 in double precision, the LP's band rows inf / 0 = NaN, and scipy's linprog refused them.
    problem = Problem(ModePlant(5.0, 0.0), displacement=0.3, limits=Limits(max_velocity=1.0, max_acceleration=10.0))
    options = TimeOptimalOptions(Robustness(frequency_ratio_range=(0.9, 1.1), max_percentage_vibration=5e-324))
    with pytest.raises(InvalidParameter, match="positive finite") as refused:
        _design(problem, options)
    assert refused.value.field == "robustness.max_percentage_vibration"


def test_scales_too_far_apart_for_the_lp_are_refused_not_fed_to_it() -> None:
    # The fuzz bench's second 500: a 1e-9 ramp at 5e11 on a 0.001 Hz mode lasts 2e-21 s; the LP's rows were
    # inf / nan, which scipy's linprog refuses. Nothing is claimed infeasible: a 422 on the body says why.
    problem = Problem(ModePlant(0.001, 0.0), target_velocity=1e-9, limits=Limits(max_acceleration=507287949364.63416))
    options = TimeOptimalOptions(Robustness(derivative_order=1), max_duration_s=1e-6)
    with pytest.raises(InvalidParameter, match="scales too far apart") as refused:
        _design(problem, options)
    assert refused.value.field == "body"


def test_a_solve_over_its_time_limit_is_a_time_out() -> None:
    problem = Problem(
        ModePlant(5.0, 0.0),
        displacement=0.3,
        limits=Limits(max_velocity=1.0, max_acceleration=10.0),
        solver=SolveCaps(max_wall_time_s=1e-4),
    )
    with pytest.raises(SolverTimedOut):
        _design(problem, TimeOptimalOptions(Robustness(frequency_ratio_range=(0.8, 1.2))))


def test_tradeoff_rows_grow_with_the_band() -> None:
    options = TimeOptimalOptions(tradeoff=(0.0, 0.05, 0.1))
    result = _design(KNOWN, options)
    rows = result.extras.tradeoff
    durations = [r.duration_s for r in rows]
    assert durations[0] == pytest.approx(result.summary.duration_s, rel=1e-12)
    assert durations[0] < durations[1] <= durations[2]
    assert all(r.lower_bound_s <= r.duration_s for r in rows)
    # The solver report counts the rows' LPs too (each row is a search of its own).
    assert result.solver is not None and result.solver.solves > result.summary.search.lp_solves
    assert result.solver.status == "refined"


def test_jerk_limited_robust_band() -> None:
    # Review finding: the relaxed LP's jerk rows were padded without the band's variables (a crash).
    limits = Limits(max_velocity=1.0, max_acceleration=10.0, max_jerk=200.0)
    problem = Problem(ModePlant(5.0, 0.05), displacement=0.3, limits=limits)
    result = _design(problem, TimeOptimalOptions(Robustness(frequency_ratio_range=(0.9, 1.1))))
    assert result.limit_violations == ()
    assert float(np.max(_v(problem, result, np.linspace(0.9, 1.1, 3001), 0.05))) <= 5.0 * (1 + 1e-9)
    assert result.summary.lower_bound_s <= result.summary.duration_s


def test_band_only_is_no_longer_and_still_covers_the_band() -> None:
    problem = Problem(ModePlant(5.0, 0.05), displacement=0.3, limits=Limits(max_velocity=1.0, max_acceleration=10.0))
    both = _design(problem, TimeOptimalOptions(Robustness(frequency_ratio_range=(0.8, 1.2))))
    band_only = Robustness(frequency_ratio_range=(0.8, 1.2), zero_residual_at_modes=False)
    band = _design(problem, TimeOptimalOptions(band_only))
    # Fewer constraints: no longer, up to one step of the 4x finer grid both are optima of.
    assert band.summary.duration_s <= both.summary.duration_s + band.summary.grid.step_s
    assert float(np.max(_v(problem, band, np.linspace(0.8, 1.2, 3001), 0.05))) <= 5.0 * (1 + 1e-9)
    assert both.percentage_vibration is not None and both.percentage_vibration < 1e-6


def test_a_band_reaching_low_frequencies_keeps_a_fine_grid() -> None:
    # Review finding: a band edge at 1 mHz made the search's guess (and its step) huge under a large cap.
    # Its LPs take up to ~1 s each on the 2-core machine: a 60 s wall-clock last resort per LP, so that a loaded
    # machine does not time it out (this test is about the grid, not the time).
    problem = Problem(
        ModePlant(5.0, 0.05),
        displacement=0.3,
        limits=Limits(max_velocity=1.0, max_acceleration=10.0),
        solver=SolveCaps(max_wall_time_s=60.0),
    )
    options = TimeOptimalOptions(Robustness(frequency_range_hz=(0.001, 6.0)), max_duration_s=1e4)
    result = _design(problem, options)
    grid = result.summary.grid
    assert grid.steps >= 48  # the grid fits the duration found (half of STEPS = 96), not the guess
    # Under the default cap the same band gives 1.196 s (the review's run); with the huge guess it gave 33.87 s.
    # 3 s separates the two with room for grid differences.
    assert result.summary.duration_s < 3.0


def test_snapped_grid_commands_keep_the_acceleration_limit(monkeypatch: pytest.MonkeyPatch) -> None:
    # Found with a coarser search grid: snapping a held jerk to its bang levels moved the acceleration at the
    # nodes past max_acceleration by 4e-8 (the pipeline's hard check refused the design).
    from optim.families.time_optimal import search

    monkeypatch.setattr(search, "STEPS", 80)
    limits = Limits(max_velocity=1.0, max_acceleration=20.0, max_jerk=1000.0)
    result = _design(Problem(ModePlant(10.0, 0.0), displacement=0.53, limits=limits))
    assert result.limit_violations == ()
    assert result.metrics.peak_acceleration <= 20.0 * (1 + 1e-9)


def test_an_lp_stopped_at_its_simplex_cap_is_answered_by_the_interior_point_method(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # A move whose grid once made HiGHS's simplex stall for 9.5 s (scipy 1.1x's HiGHS; 1.17's no longer stalls on
    # it): each LP is capped in iterations, then retried with the interior-point method. With the cap at 40 the
    # simplex stops on every LP of the search and the interior-point method (about 15 iterations here) answers
    # each: the same grid optimum as uncapped, runs at the cap counted, no LP counted as not found.
    from optim.families.time_optimal.family import selected_modes, spec_of
    from optim.families.time_optimal.search import GridSearch

    problem = Problem(ModePlant(3.0, 0.03), displacement=0.2, limits=Limits(None, 2.0, 100.0))
    options = TimeOptimalOptions()
    spec = spec_of(problem, options, selected_modes(problem, options)[0])
    free = GridSearch(spec).grid_optimum()
    monkeypatch.setattr(highs_model, "MAX_LP_ITERATIONS", 40)
    search = GridSearch(spec)
    capped = search.grid_optimum()
    assert (capped.steps, capped.step_s) == (free.steps, free.step_s)
    assert search.counter.capped_runs >= 1 and search.counter.capped_lps == 0
    assert search.counter.solves == 2 * search.counter.capped_runs  # each capped run retried once, and answered


def test_an_lp_at_its_iteration_cap_counts_as_not_found_and_says_so(monkeypatch: pytest.MonkeyPatch) -> None:
    # With 12 HiGHS iterations per method, some LPs of a jerk-limited search end at the cap with both methods:
    # they count as "no command found", and the design says so. (A jerk-limited move whose predicted structures
    # and their repairs are not certified, so that the search runs: bench/time_optimal_speed.py's held-jerk move 0,
    # rounded.)
    monkeypatch.setattr(highs_model, "MAX_LP_ITERATIONS", 12)
    result = _design(Problem(ModePlant(558.0, 0.0243), displacement=0.01, limits=Limits(0.0461, 2.333, 23.54)))
    search = result.summary.search
    assert search.max_lp_iterations == 12
    assert search.lps_not_found_at_iteration_cap >= 1
    assert search.lp_runs_at_iteration_cap >= 2 * search.lps_not_found_at_iteration_cap  # both methods
    assert any("counted as 'no command found'" in w for w in result.warnings)


@pytest.mark.parametrize(
    ("frequency_hz", "displacement", "velocity", "acceleration"),
    [(40.0, 0.3, 0.2, 30.0), (10.0, 2.0, 0.3, 5.0), (20.0, 1.0, 0.5, 10.0)],
)
def test_never_slower_than_zv_shaping_of_the_rigid_move(
    frequency_hz: float, displacement: float, velocity: float, acceleration: float
) -> None:
    # Long cruises with short ramps (a ramp shorter than a search step) once came out slower than ZV shaping:
    # the shaped rigid move is now a start of the refinement and a candidate itself. ZV ends half a damped
    # period after the rigid trapezoid D/v + v/a.
    plant = ModePlant(frequency_hz, 0.02)
    limits = Limits(max_velocity=velocity, max_acceleration=acceleration)
    result = _design(Problem(plant, displacement=displacement, limits=limits))
    zv_end = displacement / velocity + velocity / acceleration + 0.5 * plant.modes()[0].damped_period_s
    assert result.summary.duration_s <= zv_end * (1 + 1e-9)
    assert result.limit_violations == ()
    assert result.metrics.residual_amplitude < 1e-9 * displacement


def test_the_band_check_is_computed_in_blocks_of_bounded_memory_with_the_same_ratios() -> None:
    """worst_ratios on 20,000 band points x 600 pieces (a fuzzed robust request's dense check, which took a worker
    to 650 MiB): blocked, numpy's traced peak stays under 160 MiB (about six 16 MiB temporaries per block, plus
    the 0.3 MiB outputs), where the whole moment matrix is 183 MiB a temporary; and the ratios equal those of the
    moment matrix computed directly (one exponential per point and piece, lp.acceleration_moment) at every 50th point.
    Tolerance: worst_ratios' running product exp(delta s)^j, started again every check.RESTART = 32 points, carries
    about 32 eps of relative round-off per term: measured 1.9e-15 of the sum of the breakpoint terms' moduli at a
    point, held to 2e-14 (a product over the whole row of 20,000 points was 1.8e-13 off: it fails)."""
    import tracemalloc
    from types import SimpleNamespace

    from optim.families.time_optimal import check
    from optim.families.time_optimal.lp import acceleration_moment
    from optim.families.time_optimal.weights import mode_poles

    points, pieces, total_s = 20_000, 600, 3.0
    omega = np.linspace(2 * np.pi * 5.0, 2 * np.pi * 80.0, points)
    zeta = np.full(points, 0.02)
    bound = np.full(points, 1e-3)
    grid = check.BandGrid(None, omega, zeta, mode_poles(omega, zeta), bound, points)  # type: ignore[arg-type]
    edges = np.linspace(0.0, total_s, pieces + 1)
    level = np.sin(np.arange(pieces))
    spec = SimpleNamespace(order=2)
    tracemalloc.start()
    blocked = check.worst_ratios(spec, grid, edges[:-1], edges[1:], level, total_s)  # type: ignore[arg-type]
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert peak < 160 * 2**20
    some = slice(0, points, 50)
    poles = grid.poles[some]
    moments = acceleration_moment(spec, poles, edges[:-1], edges[1:], total_s, 0)  # type: ignore[arg-type]
    direct = np.abs(moments @ level) / grid.bound[some]
    times, jumps = check.breakpoints(*check.runs(edges[:-1], edges[1:], level))
    moduli = np.abs(np.exp(np.outer(poles, total_s - times)) * jumps / poles[:, None]).sum(axis=1) / grid.bound[some]
    assert np.all(np.abs(blocked[some] - direct) <= 2e-14 * moduli)
