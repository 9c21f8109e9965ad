"""The time-optimal family's grid search (optim.families.time_optimal.search) and its band check
(optim.families.time_optimal.check): the bisection's order of LPs, the check on a grid command's runs, and the
band's cutting-plane rounds solved warm in the HiGHS model the grid LP keeps (optim.families.time_optimal.lp)."""

from __future__ import annotations

import os

import numpy as np
import pytest


@pytest.mark.parametrize(
    ("least", "bands", "asked"),
    [
        (7, False, [7, 6]),
        (12, False, [7, 9, 10, 11, 12]),
        (None, False, [7, 9, 10, 11, 12]),
        (7, True, [8, 6, 7]),
        (12, True, [8, 10, 11, 12]),
    ],
)
def test_bisection_solves_its_upper_count_only_where_no_shorter_count_is_feasible(
    least: int | None, bands: bool, asked: list[int]
) -> None:
    # GridSearch.bisect on (5, 12] with feasibility from ``least`` steps on (None: nowhere): its first count 7
    # (FIRST_PROBE = 0.15 of the 7 counts above 5, rounded up), with bands 8 (halves throughout), then halves (6, or
    # 9, 10 and 11), and the upper count 12 only where none below it is feasible; the least feasible count, or None.
    from optim.families.time_optimal.search import GridSearch

    search = object.__new__(GridSearch)
    search.dense = [object()] if bands else []  # type: ignore[list-item]
    seen: list[int] = []

    def feasible(steps: int, dt: float, weights: object = None) -> np.ndarray | None:
        seen.append(steps)
        return None if least is None or steps < least else np.full(steps, 0.5)

    search.feasible = feasible  # type: ignore[method-assign]
    found = search.bisect(0.01, 5, 12)
    assert seen == asked
    if least is None:
        assert found is None
    else:
        assert found is not None
        assert (found.steps, found.infeasible_steps, found.values.size) == (least, least - 1, least)


@pytest.mark.parametrize(("shortest_s", "least_steps", "upper_asked"), [(0.9, 87, 0), (1.5, 72, 1)])
def test_the_grid_optimum_solves_its_upper_guess_last(shortest_s: float, least_steps: int, upper_asked: int) -> None:
    # GridSearch.grid_optimum from 1 s on 96 steps, the rigid floor 0.8 s, a command only from ``shortest_s`` on:
    # at 0.9 s the least count is ceil(0.9 * 96) = 87 and the 96 steps over the guess are never solved; at 1.5 s
    # none is feasible on steps of 1/96 s (96 solved last, once), the guess is doubled and on steps of 2/96 s the
    # least count is 1.5 * 48 = 72.
    from types import SimpleNamespace

    from optim.families.time_optimal.search import STEPS, GridSearch

    search = object.__new__(GridSearch)
    search.dense = []
    search.spec = SimpleNamespace(floor_s=0.8, upper_guess_s=1.0, max_duration_s=10.0)  # type: ignore[assignment]
    seen: list[tuple[int, float]] = []

    def feasible(steps: int, dt: float, weights: object = None) -> np.ndarray | None:
        seen.append((steps, dt))
        return np.full(steps, 0.5) if steps * dt >= shortest_s * (1 - 1e-12) else None

    search.feasible = feasible  # type: ignore[method-assign]
    found = search.grid_optimum(1.0)
    assert found.steps == least_steps and found.step_s == (1.0 if upper_asked == 0 else 2.0) / STEPS
    assert sum(1 for steps, dt in seen if steps == STEPS and dt == 1.0 / STEPS) == upper_asked
    assert all(steps < STEPS for steps, dt in seen if dt != 1.0 / STEPS)


def test_the_band_check_merges_a_grid_command_into_runs_with_the_same_ratios() -> None:
    """A grid command of 400 steps holding +-1 and 0 on long runs, with a few fractional steps: check.runs leaves 7
    pieces (the runs that are not at 0), and worst_ratios on them equals the ratios of the moment matrix over every
    step, computed here directly (F_0 is additive over adjacent pieces; the exponentials differ in the last bits:
    1e-12 of the largest term's contribution)."""
    from types import SimpleNamespace

    from optim.families.time_optimal import check
    from optim.families.time_optimal.lp import acceleration_moment
    from optim.families.time_optimal.weights import mode_poles

    steps, total_s = 400, 0.4
    level = np.concatenate([np.ones(90), [0.3], np.zeros(100), [-0.5], -np.ones(90), [0.7], np.ones(17)])
    level = np.concatenate([level, -np.ones(steps - level.size)])
    edges = np.linspace(0.0, total_s, steps + 1)
    start, end, merged = check.runs(edges[:-1], edges[1:], level)
    assert merged.tolist() == [1.0, 0.3, -0.5, -1.0, 0.7, 1.0, -1.0]
    assert start[0] == 0.0 and end[0] == edges[90] and start[2] == edges[191] and end[-1] == total_s
    omega = np.linspace(2 * np.pi * 5.0, 2 * np.pi * 40.0, 300)
    zeta = np.full(omega.size, 0.05)
    poles = mode_poles(omega, zeta)
    grid = check.BandGrid(None, omega, zeta, poles, np.full(omega.size, 1e-3), omega.size)  # type: ignore[arg-type]
    for order in (2, 3):
        spec = SimpleNamespace(order=order)
        moments = acceleration_moment(spec, poles, edges[:-1], edges[1:], total_s, 0)  # type: ignore[arg-type]
        direct = np.abs(moments @ level) / grid.bound
        scale = float(np.max(np.abs(moments) @ np.abs(level) / grid.bound))
        ratios = check.worst_ratios(spec, grid, edges[:-1], edges[1:], level, total_s)  # type: ignore[arg-type]
        np.testing.assert_allclose(ratios, direct, rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize("order", [2, 3])
def test_the_band_check_on_several_damping_ratios_in_small_blocks_equals_the_moments(
    order: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """worst_ratios on a band grid of three damping ratios (0, 0.25, 0.5: three rows of evenly spaced poles, each
    its own running product), in blocks of 96 points that split the rows (MOMENT_BLOCK_ELEMENTS lowered), for a
    command of 30 arcs whose ends and next starts differ by round-off: the ratios of the moment matrix computed
    directly (lp.acceleration_moment, one exponential per point and piece), within 2e-14 of the breakpoint terms'
    moduli at each point (the product's round-off, 32 eps a term; the review measured 4e-13 at most over 30 commands
    with other block sizes). A delta taken from the wrong row, or a row's product carried into the next, fails."""
    from types import SimpleNamespace

    from optim.families.time_optimal import check
    from optim.families.time_optimal.family import selected_modes, spec_of
    from optim.families.time_optimal.lp import acceleration_moment
    from optim.families.time_optimal.options import Robustness, TimeOptimalOptions
    from tests.optim.test_time_optimal import KNOWN

    band = Robustness(frequency_ratio_range=(0.5, 2.0), damping_ratio_range=(0.0, 0.5))
    options = TimeOptimalOptions(band)
    spec = spec_of(KNOWN, options, selected_modes(KNOWN, options)[0])
    grid = check.band_grid(spec, spec.bands[0], 500)
    assert len(spec.bands[0].damping_ratios) == 3 and grid.row_length == 500
    rng = np.random.default_rng(7)
    durations = rng.uniform(0.1, 1.0, 30)
    durations *= 0.4 / durations.sum()
    start = np.concatenate([[0.0], np.cumsum(durations)[:-1]])
    end = start + durations * (1 + 1e-15)  # (the next start differs by round-off: two breakpoints)
    level = rng.choice([-1.0, 0.0, 0.3, 1.0], 30)
    total_s = float(end[-1])
    monkeypatch.setattr(check, "MOMENT_BLOCK_ELEMENTS", 96 * 61)
    held = SimpleNamespace(order=order)
    ratios = check.worst_ratios(held, grid, start, end, level, total_s)  # type: ignore[arg-type]
    moments = acceleration_moment(held, grid.poles, start, end, total_s, 0)  # type: ignore[arg-type]
    direct = np.abs(moments @ level) / grid.bound
    times, jumps = check.breakpoints(*check.runs(start, end, level))
    power = order - 1
    terms = np.exp(np.outer(grid.poles, total_s - times)) * jumps / grid.poles[:, None] ** power
    moduli = np.abs(terms).sum(axis=1) / grid.bound
    assert np.all(np.abs(ratios - direct) <= 2e-14 * moduli)


def test_refined_candidates_longer_than_the_grid_send_the_fallback_to_a_finer_grid() -> None:
    # The 25 Hz, zeta 0.02 held-jerk move of docs/benchmarks.md (0.3 m within 0.5 m/s, 10 m/s^2, 2000 m/s^3): every
    # refinement from the 4x finer grid broke a limit or was longer than the coarse grid's command, and the answer was
    # that grid's, 657.79 ms, 0.23 % above the independent 800-step LP (bench/lp_reference.py, GridMove.minimum_s over
    # [0.64, 0.67] s: 656.2703 ms). With the 8x grid the answer was refined, within the 0.05 % of that LP (it
    # cannot be shorter than the LP's by more than the LP's own grid error: 0.05 % too); since the refinements of
    # later sessions the 4x grid's structure refines within it, and the 8x grid is not searched here. With one BLAS
    # thread, as the service's workers (tests/conftest.py sets it); with two, SLSQP's last bits lead elsewhere:
    # 657.21 ms.
    from tests.conftest import NUMPY_BEFORE_CONFTEST

    assert not NUMPY_BEFORE_CONFTEST and os.environ["OPENBLAS_NUM_THREADS"] == "1"
    from models.plants import ModePlant
    from optim.families.time_optimal.options import TimeOptimalOptions
    from optim.problem import Limits, Problem
    from optim.registry import FAMILIES
    from optim.synthesis import synthesize

    problem = Problem(ModePlant(25.0, 0.02), displacement=0.3, limits=Limits(0.5, 10.0, 2000.0))
    result = synthesize(FAMILIES["time_optimal"], problem, TimeOptimalOptions())
    lp_800_s = 0.6562702941894532
    assert result.summary.duration_s == pytest.approx(lp_800_s, rel=5e-4)
    assert result.design.detail.solution.method == "refined"  # type: ignore[attr-defined]


def test_the_8x_grid_s_bisection_is_bounded_by_the_4x_grid_s_optimum() -> None:
    # bench/programs.py's seed-29 move 5, a straight line through three modes (14, 22 and 35 Hz): every refined
    # candidate is longer than the coarse grid's command, so the 4x and then the 8x grid are searched, and the
    # answer is the 8x grid's optimum. Its bisection starts below the 4x optimum's duration (twice its steps,
    # feasible on the 8x grid too), not below the coarse grid's: no 8x LP at or above it (a 668-step LP, 0.23 s, saved);
    # the answer is the least feasible count of the 8x grid that the search found. (The 4x grid's command at its least
    # duration, minimum_time._least, proves this move before any 8x LP: it is off here.)
    from models.plants import ModePlant
    from optim.families.time_optimal import minimum_time
    from optim.families.time_optimal.options import TimeOptimalOptions
    from optim.families.time_optimal.search import GridSearch
    from optim.problem import Limits, Problem
    from optim.programs.moves import path_plant
    from optim.registry import FAMILIES
    from optim.synthesis import synthesize

    solved: list[tuple[int, float, bool]] = []  # (steps, step, found) of each feasibility LP
    feasible = GridSearch.feasible

    def recorded(self: GridSearch, steps: int, dt: float, weights: np.ndarray | None = None) -> np.ndarray | None:
        x = feasible(self, steps, dt, weights)
        if weights is None:
            solved.append((steps, dt, x is not None))
        return x

    plant = path_plant([ModePlant(14.0, 0.03), ModePlant(22.0, 0.02), ModePlant(35.0, 0.05)])
    limits = Limits(1.5022455108882162, 15.022455108882161, 1502.2455108882161)  # (x's, projected: as bench's)
    problem = Problem(plant, 0.39874664910835217, limits=limits)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(GridSearch, "feasible", recorded)
        patch.setattr(minimum_time, "_least", lambda best, search, fine: False)  # (it proves this move: no 8x grid)
        result = synthesize(FAMILIES["time_optimal"], problem, TimeOptimalOptions())
    dt8 = min(dt for _, dt, _ in solved)
    best4 = min(steps for steps, dt, found in solved if found and dt == 2.0 * dt8)
    assert max(steps for steps, dt, _ in solved if dt == dt8) < 2 * best4  # (its count: solved only if the least)
    best8 = min(steps for steps, dt, found in solved if found and dt == dt8)
    assert best8 < 2 * best4 and not any(found for steps, dt, found in solved if dt == dt8 and steps < best8)
    assert result.design.detail.solution.method == "grid"  # type: ignore[attr-defined]
    assert result.summary.duration_s == pytest.approx(best8 * dt8, rel=1e-12)


def test_a_warm_round_holds_every_band_point_as_the_lp_built_with_them_and_prints_nothing(
    capfd: pytest.CaptureFixture[str],
) -> None:
    # The README's robust move (+-10 %) on the grid its search ends on (341 steps of 0.668 ms): the LP with the
    # search's first band points (one every 1.2 rad of phase), then the points the dense check adds, added to the kept
    # HiGHS model (GridLp.add_cuts, solved warm). Its command must hold every band point, checked here by the band's
    # own moments (acceleration_moment @ level, not the LP's rows), within the LP's margin (BAND_MARGIN 0.3 % below
    # the bound, less HiGHS's feasibility tolerance 1e-7 on rows scaled to 1: 1e-6 of the bound); and the LP built
    # anew with all the points must be feasible too (the same decision). HiGHS prints nothing on stdout (highspy's
    # Highs class prints a banner: the CLI's --json - writes there).
    from optim.families.time_optimal.family import selected_modes, spec_of
    from optim.families.time_optimal.highs_model import LpCounter
    from optim.families.time_optimal.lp import BAND_MARGIN, GridLp, acceleration_moment, pieces
    from optim.families.time_optimal.options import Robustness, TimeOptimalOptions
    from optim.families.time_optimal.search import GridSearch
    from tests.optim.test_time_optimal import KNOWN

    options = TimeOptimalOptions(Robustness(frequency_ratio_range=(0.9, 1.1)))
    spec = spec_of(KNOWN, options, selected_modes(KNOWN, options)[0])
    search = GridSearch(spec)
    first = list(search.cuts)
    steps, dt = 341, 0.22785639803048094 / 341
    start, end = pieces(steps, dt)
    lp = GridLp(spec, steps, dt, first, LpCounter())
    x = lp.solve()
    assert x is not None
    added = search.new_cuts(start, end, spec.scale * x, steps * dt)
    assert added  # the first points alone let the command break the band between them: a round is needed
    lp.add_cuts(added)
    warm = lp.solve()
    assert warm is not None
    every = first + added
    poles = np.array([c.pole for c in every])
    bound = np.array([c.bound for c in every])
    moment = acceleration_moment(spec, poles, start, end, steps * dt, 0)
    ratio = np.abs(moment @ (spec.scale * warm)) / bound
    assert float(np.max(ratio)) <= (1.0 - BAND_MARGIN) * (1 + 1e-6)
    assert float(np.max(ratio)) > 0.9  # the band binds: the check is not of a command far inside it
    assert GridLp(spec, steps, dt, every, LpCounter()).solve() is not None
    assert capfd.readouterr().out == ""


def test_each_run_of_a_kept_model_has_its_own_time_limit(monkeypatch: pytest.MonkeyPatch) -> None:
    # HiGHS's clock runs on over the runs of one model (a band's warm rounds): a time_limit of 10 s stopped a round
    # after 0.35 s of its own once the rounds before it had run 9.65 s. Each run's limit is set past the model's run
    # time so far: here the second run's limit is the first's plus what HiGHS counted for the first.
    from optim.families.time_optimal import highs_model
    from optim.families.time_optimal.family import selected_modes, spec_of
    from optim.families.time_optimal.lp import GridLp
    from optim.families.time_optimal.options import TimeOptimalOptions
    from tests.optim.test_time_optimal import KNOWN

    limits: list[tuple[float, float]] = []
    real_run = highs_model.highs_run

    def highs_run(highs: object, options: dict[str, object]) -> tuple[int, int]:
        limits.append((float(options["time_limit"]), float(highs.getRunTime())))  # type: ignore[attr-defined,arg-type]
        return real_run(highs, options)

    monkeypatch.setattr(highs_model, "highs_run", highs_run)
    options = TimeOptimalOptions()
    spec = spec_of(KNOWN, options, selected_modes(KNOWN, options)[0])
    lp = GridLp(spec, 96, 0.23 / 96, [], highs_model.LpCounter(time_limit_s=10.0))
    assert lp.solve() is not None and lp.solve() is not None
    (first, at_first), (second, at_second) = limits
    assert at_first == 0.0 and first == 10.0
    assert at_second > 0.0 and second == 10.0 + at_second


def test_a_wide_band_the_coarse_start_cannot_hold_gets_the_dense_start() -> None:
    # The README's move over 0.3-3 times its frequency (V <= 5 %): its LPs need some 500 band points; starting from
    # one every 1.2 rad and adding a dozen a round, the rounds of one LP ran out at lengths that are feasible, and the
    # answer was 868.66 ms. After COARSE_ROUNDS rounds the search adds the dense start (one point every 0.15 rad, as
    # before issue 25's warm rounds): 279.308 ms, d9b987e's answer (which started dense), and the band is met on the
    # report's own check of the exact command (models.sensitivity).
    from optim.families.time_optimal.options import Robustness, TimeOptimalOptions
    from optim.registry import FAMILIES
    from optim.synthesis import synthesize
    from tests.optim.test_time_optimal import KNOWN

    options = TimeOptimalOptions(Robustness(frequency_ratio_range=(0.3, 3.0)))
    result = synthesize(FAMILIES["time_optimal"], KNOWN, options)
    assert result.summary.duration_s == pytest.approx(0.2793078, abs=1e-6)
    assert result.summary.robustness is not None and result.summary.robustness.covers_request


def test_the_grid_lp_without_state_bounds_is_the_state_lp_with_its_states_eliminated(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # The README's move (0.12 m, 10 m/s^2, within 5 m/s, which no command of <= 0.5 s within 10 m/s^2 reaches): its
    # grid LP is written on the held values alone (lp._grid_held_lp: the end state and the residual as dense rows) and
    # must decide as the LP with the motor's states at every node (lp.states_free forced False) at lengths around its
    # answer, 96 steps each, nominal and with the +-10 % band's first points. Its command is checked here by exact
    # integration of the held acceleration (the end position and velocity, to 1e-9 of the move: HiGHS's tolerance
    # 1e-7 on rows scaled to 1, over 96 steps) and by the residual's own moment at the mode (to 1e-9 of the bang-bang
    # residual envelope 4 A / w^2); also from 0.5 m/s, where the start state's share of the end state is in the rows'
    # right-hand side. A low max_velocity (1 m/s, reached after 0.1 s) keeps the states.
    from dataclasses import replace

    from optim.families.time_optimal import lp as lp_module
    from optim.families.time_optimal.family import selected_modes, spec_of
    from optim.families.time_optimal.highs_model import LpCounter
    from optim.families.time_optimal.options import Robustness, TimeOptimalOptions
    from optim.families.time_optimal.search import GridSearch
    from optim.families.time_optimal.weights import exponential_moment
    from tests.optim.test_time_optimal import KNOWN

    nominal = TimeOptimalOptions()
    spec = spec_of(KNOWN, nominal, selected_modes(KNOWN, nominal)[0])
    banded = TimeOptimalOptions(Robustness(frequency_ratio_range=(0.9, 1.1)))
    band_spec = spec_of(KNOWN, banded, selected_modes(KNOWN, banded)[0])
    moving = replace(spec, start_velocity=0.5)  # (from 0.5 m/s: the start state's share of the end state)
    cases = [(spec, []), (band_spec, GridSearch(band_spec).cuts), (moving, [])]
    lengths = (0.16, 0.18, 0.2, 0.21, 0.2197, 0.222, 0.228, 0.25)
    decided: dict[bool, list[bool]] = {}
    for held in (True, False):
        if not held:
            monkeypatch.setattr(lp_module, "states_free", lambda *_: False)
        found = []
        for s, cuts in cases:
            for total in lengths:
                assert lp_module.states_free(s, total, total / 96) is held
                x = lp_module.GridLp(s, 96, total / 96, cuts, LpCounter()).solve()
                found.append(x is not None)
                if x is None or not held:
                    continue
                start, end = lp_module.pieces(96, total / 96)
                accel = s.scale * x
                v0 = s.start_velocity
                assert abs(v0 + float(np.sum(accel * (end - start)))) <= 1e-9 * s.move / total
                moved = v0 * total + float(np.sum(accel * (end - start) * (total - 0.5 * (start + end))))
                assert moved == pytest.approx(s.move, abs=1e-9 * s.move)
                pole = np.asarray(s.zero_poles)
                residual = abs(complex((exponential_moment(pole, start, end, total, 0) @ accel)[0]))
                assert residual <= 1e-9 * 4 * s.max_acceleration / abs(pole[0]) ** 2
        decided[held] = found
    assert decided[True] == decided[False]
    for case in range(len(cases)):  # lengths both sides of each grid optimum
        verdicts = decided[True][case * len(lengths) : (case + 1) * len(lengths)]
        assert any(verdicts) and not all(verdicts)
    assert not lp_module.states_free(replace(spec, max_velocity=1.0), 0.22, 0.22 / 96)


def test_the_relaxation_with_an_implied_velocity_limit_proves_what_the_one_with_velocity_states_proves(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # relaxed_lp on the README's move (its 5 m/s is beyond the 10 m/s^2 x 0.25 s any command reaches) without the
    # velocity at every node (lp.velocity_implied) and with it (forced False), nominal, with the +-10 % band's first
    # points, and from 0.5 m/s: the same verdicts at lengths both sides of what each proves (at rest the rigid
    # minimum is 219.089 ms).
    from dataclasses import replace

    from optim.families.time_optimal import lp as lp_module
    from optim.families.time_optimal.family import selected_modes, spec_of
    from optim.families.time_optimal.highs_model import LpCounter
    from optim.families.time_optimal.options import Robustness, TimeOptimalOptions
    from optim.families.time_optimal.search import GridSearch
    from tests.optim.test_time_optimal import KNOWN

    banded = TimeOptimalOptions(Robustness(frequency_ratio_range=(0.9, 1.1)))
    spec = spec_of(KNOWN, banded, selected_modes(KNOWN, banded)[0])
    cases = [(spec, []), (spec, GridSearch(spec).cuts), (replace(spec, start_velocity=0.5), [])]
    lengths = (0.15, 0.17, 0.19, 0.2, 0.215, 0.219, 0.2195, 0.225, 0.25)
    verdicts = {}
    for implied in (True, False):
        if not implied:
            monkeypatch.setattr(lp_module, "velocity_implied", lambda *_: False)
        assert all(lp_module.velocity_implied(s, t) is implied for s, _ in cases for t in lengths)
        verdicts[implied] = [lp_module.relaxed_lp(s, t, 250, c, LpCounter()) for s, c in cases for t in lengths]
    assert verdicts[True] == verdicts[False]
    for case in range(len(cases)):  # lengths both sides of what each proves
        proven = verdicts[True][case * len(lengths) : (case + 1) * len(lengths)]
        assert any(proven) and not all(proven)


def test_a_probe_s_lp_starts_from_the_last_basis_on_as_many_steps_and_ends_at_the_same_vertex() -> None:
    # bench/programs.py's seed-28 move 16, x axis (14 Hz, zeta 0.03; 0.3984 m within 1.5 m/s, 15 m/s^2, 1500 m/s^3):
    # its probes solve the weighted LP on 364 steps at step lengths 0.2 % apart. Started from the last one's basis
    # (GridSearch.bases), HiGHS ends at the vertex the LP solved from nothing ends at (to 1e-8 of the unit box:
    # HiGHS's feasibility tolerance 1e-7 on rows scaled to 1 leaves the same vertex's values to round-off, 3e-11
    # seen) in a fifth of the simplex iterations (255 against 1973 seen).
    from models.plants import ModePlant
    from optim.families.time_optimal.family import selected_modes, spec_of
    from optim.families.time_optimal.options import TimeOptimalOptions
    from optim.families.time_optimal.search import GridSearch
    from optim.problem import Limits, Problem

    problem = Problem(ModePlant(14.0, 0.03), 0.3984, limits=Limits(1.5, 15.0, 1500.0))
    options = TimeOptimalOptions()
    spec = spec_of(problem, options, selected_modes(problem, options)[0])
    warm, cold = GridSearch(spec), GridSearch(spec)
    assert warm.late_vertex(364, 1.0458e-3) is not None and 364 in warm.bases
    before = warm.counter.iterations
    again = warm.late_vertex(364, 1.0439e-3)
    fresh = cold.late_vertex(364, 1.0439e-3)
    assert again is not None and fresh is not None
    assert float(np.max(np.abs(again - fresh))) <= 1e-8
    assert 5 * (warm.counter.iterations - before) < cold.counter.iterations
