"""Machine programs (optim.programs): the three coordinations against designs made apart, the cycle's stops
against closed forms, the plant tables, and the inputs refused."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from models.errors import InvalidParameter
from models.plants import ModePlant, TransferFunctionPlant, TwoInertiaPlant
from models.simulation import simulate
from models.varying_mode import deflection
from optim.families.time_optimal.options import TimeOptimalOptions
from optim.problem import Limits, Problem
from optim.programs import PlantTable, Program, ProgramAxis, ProgramMove, TablePoint, assemble, positions, solve_program
from optim.programs.moves import stretched
from optim.programs.run import design_moves, heaviest_first
from optim.programs.tables import mode_function, modes_at, plant_at
from optim.registry import FAMILIES
from optim.synthesis import synthesize

X = ProgramAxis("x", ModePlant(5.0, 0.05), Limits(1.0, 4.0))
Y = ProgramAxis("y", ModePlant(7.0, 0.02), Limits(0.8, 3.0))
TIME_OPTIMAL = FAMILIES["time_optimal"]


def _design(plant: ModePlant | TransferFunctionPlant, move: float, limits: Limits) -> np.ndarray:
    """The single-axis time-optimal design's exact command, made apart (the family endpoint's pipeline)."""
    result = synthesize(TIME_OPTIMAL, Problem(plant, move, limits=limits), TimeOptimalOptions())
    assert result.design.command is not None
    return result.design.command


def _program(*moves: ProgramMove, axes: tuple[ProgramAxis, ...] = (X, Y)) -> Program:
    return Program(axes, (0.0, 0.0), moves)


def test_a_straight_line_is_the_single_axis_design_on_its_path_parameter() -> None:
    """The path: L = |(0.3, 0.1)|, u = (0.3, 0.1) / L, each limit the least of limit_i / |u_i|, a plant whose
    poles are both axes' (built here from the modes' quadratics); axis i's command is u_i times the path's, to
    1e-9 of the move (round-off: the same design, scaled)."""
    result = solve_program(_program(ProgramMove((0.3, 0.1), "straight_line")))
    length = math.hypot(0.3, 0.1)
    u = (0.3 / length, 0.1 / length)
    limits = Limits(min(1.0 / u[0], 0.8 / u[1]), min(4.0 / u[0], 3.0 / u[1]))
    wx, wy = 2 * math.pi * 5.0, 2 * math.pi * 7.0
    den = np.polymul([1.0, 2 * 0.05 * wx, wx * wx], [1.0, 2 * 0.02 * wy, wy * wy])
    path = _design(TransferFunctionPlant((wx * wx * wy * wy,), tuple(den)), length, limits)
    move = result.moves[0]
    assert move.design.duration_s == pytest.approx(float(path.time_s[-1]), rel=1e-12)
    for i, axis in enumerate(move.design.axes):
        assert axis.command is not None
        t = np.linspace(0.0, move.design.duration_s, 997)
        for m in range(4):
            got = axis.command.evaluate_at_instants(t, 4)[m]
            want = u[i] * path.evaluate_at_instants(t, 4)[m]
            assert np.max(np.abs(got - want)) <= 1e-9 * max(1.0, float(np.max(np.abs(want)))), (i, m)
        # each axis's limits hold on its own share (the path's are the tightest)
        assert axis.command.max_abs(1) <= (1.0, 0.8)[i] * (1 + 1e-9)
        assert axis.command.max_abs(2) <= (4.0, 3.0)[i] * (1 + 1e-9)
    assert max(a.stop_residual_fraction or 0.0 for a in move.axes) < 1e-12


def test_synchronized_axes_start_and_arrive_together_within_their_limits_and_still() -> None:
    """The move lasts as long as the slower axis's own minimum-time design (both made apart here); the faster
    axis's is the shaped rigid optimum (its design with the slower's duration as sufficient_duration_s, made apart),
    as (p(t) + p(t - delta)) / 2 (evaluated here), so both end together; limits and a zero residual hold (exact
    simulation)."""
    result = solve_program(_program(ProgramMove((0.3, 0.05), "synchronized")))
    alone = [_design(ModePlant(5.0, 0.05), 0.3, X.limits), _design(ModePlant(7.0, 0.02), 0.05, Y.limits)]
    ends = [float(c.time_s[-1]) for c in alone]
    move = result.moves[0]
    assert move.design.duration_s == pytest.approx(max(ends), rel=1e-12)
    slow, fast = (0, 1) if ends[0] > ends[1] else (1, 0)
    enough = TimeOptimalOptions(sufficient_duration_s=ends[slow])
    problem = Problem(ModePlant(*((5.0, 0.05), (7.0, 0.02))[fast]), (0.3, 0.05)[fast], limits=(X, Y)[fast].limits)
    paced = synthesize(TIME_OPTIMAL, problem, enough)
    assert paced.design.command is not None and paced.summary.method == "shaped_rigid"
    assert getattr(move.design.axes[fast].summary, "method", None) == "shaped_rigid"
    own = {fast: paced.design.command, slow: alone[slow]}
    ends[fast] = float(own[fast].time_s[-1])
    assert ends[fast] <= ends[slow]
    delta = ends[slow] - ends[fast]
    t = np.linspace(-0.01, max(ends) + 0.01, 1501)
    got = move.design.axes[fast].command
    assert got is not None and float(got.time_s[-1]) == pytest.approx(max(ends), rel=1e-12)
    want = 0.5 * (own[fast].evaluate(0, t) + own[fast].evaluate(0, t - delta))
    assert np.max(np.abs(got.evaluate(0, t) - want)) <= 1e-12
    for i, axis in enumerate((X, Y)):
        command = move.design.axes[i].command
        assert command is not None
        assert command.max_abs(1) <= axis.limits.max_velocity * (1 + 1e-9)  # type: ignore[operator]
        assert command.max_abs(2) <= axis.limits.max_acceleration * (1 + 1e-9)  # type: ignore[operator]
        assert move.axes[i].stop_residual_fraction is not None and move.axes[i].stop_residual_fraction < 1e-12


def test_independent_axes_keep_their_own_designs_and_the_cycle_adds_moves_and_dwells() -> None:
    """Each axis's command is its single-axis design (to round-off); the cycle time is the sum of each move's
    longest axis and its dwell."""
    result = solve_program(
        _program(ProgramMove((0.3, 0.05), "independent", 0.25), ProgramMove((0.0, 0.0), "independent", 0.1))
    )
    first = [_design(ModePlant(5.0, 0.05), 0.3, X.limits), _design(ModePlant(7.0, 0.02), 0.05, Y.limits)]
    back = [_design(ModePlant(5.0, 0.05), -0.3, X.limits), _design(ModePlant(7.0, 0.02), -0.05, Y.limits)]
    for i in range(2):
        command = result.moves[0].design.axes[i].command
        assert command is not None
        assert np.array_equal(command.time_s, first[i].time_s)
        assert np.max(np.abs(command.derivatives - first[i].derivatives)) <= 1e-12
    durations = [max(float(c.time_s[-1]) for c in pair) for pair in (first, back)]
    assert result.cycle_time_s == pytest.approx(durations[0] + 0.25 + durations[1] + 0.1, rel=1e-12)
    assert [m.start_s for m in result.moves] == pytest.approx([0.0, durations[0] + 0.25], rel=1e-12)


def test_a_stop_where_the_load_need_not_be_still_rings_on_into_the_next() -> None:
    """Move 0 is the rigid optimum (nothing cancelled), its residual the closed form of its free vibration; X then
    rests while Y moves: X's residual at the next stop is the first decayed by exp(-zeta w t) over the dwell and the
    second move (a damped mode's free amplitude sqrt(A^2 + B^2) decays exactly so)."""
    result = solve_program(
        _program(ProgramMove((0.3, 0.0), "independent", 0.2, still_at_stop=False), ProgramMove((0.3, 0.1)))
    )
    first, second = result.moves
    rigid = Problem(X.plant, 0.3, limits=X.limits).rigid_move(1.0, 4.0, None)
    assert first.design.duration_s == pytest.approx(rigid.duration_s, rel=1e-12)
    alone = simulate(X.plant, first.design.axes[0].command)  # type: ignore[arg-type]
    a0 = float(np.sum(alone.free_amplitudes(alone.time_s.size - 1, 0)[alone.modal.oscillatory]))
    assert first.axes[0].stop_residual_amplitude == pytest.approx(a0, rel=1e-9)
    assert a0 > 1e-3
    decay = math.exp(-0.05 * 2 * math.pi * 5.0 * (0.2 + second.design.duration_s))
    assert second.axes[0].stop_residual_amplitude == pytest.approx(a0 * decay, rel=1e-9)
    assert second.axes[1].stop_residual_fraction is not None and second.axes[1].stop_residual_fraction < 1e-12
    assert any(w.startswith("moves[1]: the load is not still at this stop (x ") for w in result.warnings), (
        result.warnings
    )


def test_the_varying_mode_is_the_exact_response_when_the_mode_is_constant() -> None:
    """models.varying_mode's DOP853 against models.simulation's closed form (load - motor) on a jerk-limited
    design: 1e-9 of the largest deflection (the integrator's tolerance is 1e-12, its error accumulates)."""
    command = _design(ModePlant(7.0, 0.02), 0.2, Limits(0.8, 3.0, 60.0))
    sampled = command.resampled(1e-3, end_s=float(command.time_s[-1]) + 0.5)  # the corners kept: exact
    t = sampled.time_s
    exact = simulate(ModePlant(7.0, 0.02), sampled)
    want = exact.load_position - sampled.derivative(0)
    got = deflection(command, lambda _t: (2 * math.pi * 7.0, 0.02), t, np.array([]))
    assert np.max(np.abs(got.deflection - want)) <= 1e-9 * float(np.max(np.abs(want)))


def test_a_table_interpolates_each_parameter_linearly() -> None:
    """plant_at: a mode's frequency and damping ratio halfway are the points' means; mode_function (plain floats)
    is plant_at's mode to round-off (and modes_at, on arrays), two_inertia's w = sqrt(k / J_L) of the interpolated
    k and J_L."""
    table = PlantTable("x", (TablePoint(0.0, ModePlant(10.0, 0.02)), TablePoint(0.4, ModePlant(14.0, 0.04))))
    half = plant_at(table, 0.2)
    assert half.natural_frequency_hz == pytest.approx(12.0) and half.damping_ratio == pytest.approx(0.03)  # type: ignore[attr-defined]
    two = PlantTable(
        "y",
        (
            TablePoint(-1.0, TwoInertiaPlant(1e-3, 2e-3, 50.0, 0.01)),
            TablePoint(1.0, TwoInertiaPlant(1e-3, 6e-3, 80.0, 0.03)),
        ),
    )
    for table_ in (table, two):
        f = mode_function(table_)
        coordinates = np.linspace(table_.low, table_.high, 7)
        omegas, zetas = modes_at(table_, coordinates)  # the same on arrays (a cycle's samples)
        for c, omega, zeta in zip(coordinates, omegas, zetas, strict=True):
            mode = plant_at(table_, float(c)).modes()[0]
            assert f(float(c)) == pytest.approx((mode.natural_frequency_rad_s, mode.damping_ratio), rel=1e-12)
            assert (omega, zeta) == pytest.approx((mode.natural_frequency_rad_s, mode.damping_ratio), rel=1e-12)
    k, j = 0.75 * 50.0 + 0.25 * 80.0, 0.75 * 2e-3 + 0.25 * 6e-3
    assert mode_function(two)(-0.5)[0] == pytest.approx(math.sqrt(k / j), rel=1e-12)


@pytest.mark.parametrize(
    ("program", "field"),
    [
        (Program((X, replace(Y, name="x")), (0.0, 0.0), (ProgramMove((0.1, 0.1)),)), "axes[1].name"),
        (
            Program(
                (X, replace(Y, table=PlantTable("x", (TablePoint(0.0, Y.plant), TablePoint(0.0, Y.plant))))),
                (0.0, 0.0),
                (ProgramMove((0.1, 0.1)),),
            ),
            "axes[1].plant_table.points[1].at",
        ),
        (
            Program(
                (X, replace(Y, table=PlantTable("x", (TablePoint(0.0, Y.plant), TablePoint(0.2, Y.plant))))),
                (0.0, 0.0),
                (ProgramMove((0.1, 0.1)), ProgramMove((0.3, 0.1))),
            ),
            "moves[1].target.x",
        ),
        (
            Program((X, replace(Y, table=PlantTable("z", (TablePoint(0.0, Y.plant),)))), (0.0, 0.0), ()),
            "axes[1].plant_table.coordinate",
        ),
    ],
)
def test_bad_programs_are_refused_naming_the_field_and_index(program: Program, field: str) -> None:
    with pytest.raises(InvalidParameter) as caught:
        solve_program(program)
    assert caught.value.field == field


def test_targets_need_one_position_per_axis() -> None:
    with pytest.raises(InvalidParameter) as caught:
        positions({"x": 0.1}, ("x", "y"), "moves[3].target")
    assert caught.value.field == "moves[3].target" and "missing axes y" in caught.value.rule
    with pytest.raises(InvalidParameter) as caught:
        positions({"x": 0.1, "y": 0.0, "z": 1.0}, ("x", "y"), "start")
    assert "unknown axes z" in caught.value.rule


def test_stretched_keeps_a_command_s_end_state() -> None:
    command = _design(ModePlant(7.0, 0.02), 0.2, Limits(0.8, 3.0, 60.0))
    longer = stretched(command, float(command.time_s[-1]) + 0.123)
    assert float(longer.time_s[-1]) == pytest.approx(float(command.time_s[-1]) + 0.123, rel=1e-12)
    assert float(longer.derivatives[0, -1]) == pytest.approx(0.2, rel=1e-12)
    assert np.max(np.abs(longer.derivatives[1:, -1])) <= 1e-12


TABLE_Y = replace(
    Y,
    table=PlantTable("x", (TablePoint(0.0, ModePlant(7.0 * 0.85, 0.02)), TablePoint(0.4, ModePlant(7.0 * 1.15, 0.02)))),
)


def test_a_plant_that_changes_during_the_move_is_left_still_by_its_effective_mode() -> None:
    """Y's mode follows X by +-15 %: the band design alone leaves 1e-3 or so of the move on the true plant; the
    effective modes' designs (a stretched axis: one for each half) leave 1e-11 (Newton's target) by the move's own
    integration, and below 1e-10 by the cycle's (the whole cycle from its start, DOP853 through it)."""
    program = Program(
        (X, TABLE_Y),
        (0.0, 0.0),
        (ProgramMove((0.3, 0.1), "synchronized", 0.2), ProgramMove((0.1, 0.0), "straight_line")),
    )
    result = solve_program(program)
    for move in result.moves:
        assert move.varying is not None and move.varying.converged, move.varying
        assert move.varying.residual <= 1e-11
        assert move.design.axes[1].effective
        assert move.axes[1].stop_residual_fraction is not None and move.axes[1].stop_residual_fraction < 1e-10
    assert result.axes[1].method == "varying"
    for move in result.moves:  # settled on the true plant at the command's end (within a sample of the cycle's
        # grid); the same command on the plant at the stop, time-invariant, would ring for seconds (the metrics')
        true = move.axes[1].settling_time_s
        assert true is not None and move.settling_time_s is not None and move.settling_time_s >= true
        assert true <= move.design.duration_s + result.axes[1].period_s
        assert move.axes[1].metrics is not None and move.axes[1].metrics.metrics.settling.time_s > 3.0
    from optim.programs.moves import design_move
    from optim.programs.varying import residuals

    band = design_move(program, 0)  # the plant at the stop, robust over the band it passes through
    assert band.axes[1].band_hz is not None
    assert np.max(np.abs(residuals(program, 0, band, [1]))) > 1e-4


def test_a_stretched_axis_s_halves_may_be_designed_for_modes_of_their_own() -> None:
    """design_move with two effective modes for Y (stretched, the faster axis): (p(t) + q(t - delta)) / 2 with p and
    q Y's designs for each mode made apart, q's delay ending it with X; still within Y's limits."""
    from optim.programs.moves import design_move

    program = Program((X, TABLE_Y), (0.0, 0.0), (ProgramMove((0.3, 0.1), "synchronized"),))
    w1, w2 = 2 * math.pi * 7.2, 2 * math.pi * 7.9
    move = design_move(program, 0, {1: (w1, 0.02, w2, 0.02)})
    p, q = (_design(ModePlant(w / (2 * math.pi), 0.02), 0.1, Y.limits) for w in (w1, w2))
    y = move.design.axes[1] if hasattr(move, "design") else move.axes[1]
    assert y.second is not None and y.command is not None
    end = move.duration_s
    assert end == pytest.approx(float(_design(X.plant, 0.3, X.limits).time_s[-1]), rel=1e-12)
    delta = end - float(q.time_s[-1])
    t = np.linspace(0.0, end, 1201)
    want = 0.5 * (p.evaluate(0, t) + q.evaluate(0, t - delta))
    assert np.max(np.abs(y.command.evaluate(0, t) - want)) <= 1e-12
    assert y.command.max_abs(1) <= 0.8 * (1 + 1e-9) and y.command.max_abs(2) <= 3.0 * (1 + 1e-9)


def test_where_no_effective_mode_is_found_the_band_design_and_its_residual_are_reported(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Where Newton does not converge (here: no step allowed), the answer is the band design, a warning says so,
    and the residual the cycle reports is its true one."""
    import optim.programs.varying as varying

    monkeypatch.setattr(varying, "MAX_ITERATIONS", 0)
    program = Program((X, TABLE_Y), (0.0, 0.0), (ProgramMove((0.3, 0.1), "independent"),))
    result = solve_program(program)
    move = result.moves[0]
    assert move.varying is not None and not move.varying.converged
    assert move.design.axes[1].band_hz is not None and not move.design.axes[1].effective
    assert any("no effective mode left it still" in w for w in result.warnings)
    assert move.axes[1].stop_residual_fraction is not None and move.axes[1].stop_residual_fraction > 1e-6


def test_a_dwell_is_carried_in_closed_form_as_the_integration_would() -> None:
    """models.varying_mode.free_states over a still interval against DOP853 through it: 1e-10 of the deflection."""
    command = _design(ModePlant(7.0, 0.02), 0.2, Limits(0.8, 3.0, 60.0))
    end = float(command.time_s[-1])
    t = np.linspace(0.0, end + 1.0, 401)
    varying = lambda time: (2 * math.pi * (7.0 + 0.5 * min(time, 0.3)), 0.02)  # noqa: E731 (changes while moving)
    integrated = deflection(command, varying, t, np.array([]))
    carried = deflection(command, varying, t, np.array([]), ((end, end + 1.0),))
    scale = float(np.max(np.abs(integrated.deflection)))
    assert np.max(np.abs(carried.deflection - integrated.deflection)) <= 1e-10 * scale
    assert carried.evaluations < integrated.evaluations


def test_the_true_plant_s_simulation_is_bounded_in_periods(monkeypatch: pytest.MonkeyPatch) -> None:
    import optim.programs.cycle as cycle

    monkeypatch.setattr(cycle, "MAX_VARYING_PERIODS", 3)
    program = Program((X, TABLE_Y), (0.0, 0.0), (ProgramMove((0.3, 0.1), "synchronized"),))
    with pytest.raises(InvalidParameter) as caught:
        solve_program(program)
    assert caught.value.field == "moves" and "periods" in caught.value.rule


PAYLOAD = PlantTable(
    "payload_kg", (TablePoint(0.0, ModePlant(7.0, 0.02)), TablePoint(2.0, ModePlant(5.0, 0.02)))
)  # the heavier the payload, the lower Y's mode


def test_a_plant_over_a_payload_changes_at_the_stops_where_it_is_picked_and_placed() -> None:
    """The payload is picked at stop 0 (move 1 carries 1.5 kg) and placed at stop 1: each move is designed for the
    plant of its payload (the table's interpolation: 7 - 1.5 Hz), its axis's command is that plant's single-axis
    design (made apart here), and every stop is still on the true plant (the payload constant over each move)."""
    y = replace(Y, plant=ModePlant(7.0, 0.02), table=PAYLOAD)
    program = Program(
        (X, y),
        (0.0, 0.0),
        (
            ProgramMove((0.3, 0.1), "independent"),
            ProgramMove((0.1, 0.0), "independent", parameters=(("payload_kg", 1.5),)),
            ProgramMove((0.2, 0.1), "independent", parameters=(("payload_kg", 0.0),)),
        ),
        parameters=(("payload_kg", 0.0),),
    )
    result = solve_program(program)
    loaded = _design(ModePlant(7.0 - 1.5, 0.02), -0.1, Y.limits)
    command = result.moves[1].design.axes[1].command
    assert command is not None and np.array_equal(command.time_s, loaded.time_s)
    assert np.max(np.abs(command.derivatives[1:] - loaded.derivatives[1:])) <= 1e-12
    assert result.moves[1].design.axes[1].plant.modes()[0].natural_frequency_hz == pytest.approx(5.5, rel=1e-12)
    assert all(m.varying is None for m in result.moves)  # a payload does not change during a move
    for move in result.moves:
        assert move.axes[1].stop_residual_fraction is not None and move.axes[1].stop_residual_fraction < 1e-11
    assert result.axes[1].method == "varying" and not result.warnings
    for move in result.moves:  # the plant constant over each move: the true settling is the metrics' (both checked
        # at their samples during the command: within the cycle's grid, the coarser)
        true, own = move.axes[1].settling_time_s, move.axes[1].metrics
        assert true is not None and own is not None and own.metrics.settling.time_s is not None
        assert true == pytest.approx(own.metrics.settling.time_s, abs=result.axes[1].period_s)


@pytest.mark.parametrize(
    ("parameters", "moves_parameters", "field"),
    [
        ((), (), "axes[1].plant_table.coordinate"),  # never given: the coordinate names nothing
        ((("payload_kg", 0.0),), (("payload_kg", 2.5),), "moves[0].parameters.payload_kg"),  # outside [0, 2]
        ((("x", 0.0),), (), "parameters"),  # an axis's name
    ],
)
def test_a_payload_s_values_are_checked_naming_where_they_were_given(
    parameters: tuple[tuple[str, float], ...], moves_parameters: tuple[tuple[str, float], ...], field: str
) -> None:
    y = replace(Y, table=PAYLOAD)
    program = Program(
        (X, y), (0.0, 0.0), (ProgramMove((0.3, 0.1), parameters=moves_parameters),), parameters=parameters
    )
    with pytest.raises(InvalidParameter) as caught:
        solve_program(program)
    assert caught.value.field == field, caught.value


def test_a_payload_given_only_later_is_missing_at_the_start() -> None:
    y = replace(Y, table=PAYLOAD)
    moves = (ProgramMove((0.3, 0.1)), ProgramMove((0.0, 0.0), parameters=(("payload_kg", 1.0),)))
    with pytest.raises(InvalidParameter) as caught:
        solve_program(Program((X, y), (0.0, 0.0), moves))
    assert caught.value.field == "parameters.payload_kg" and "from the first move on" in caught.value.rule


def test_the_pool_starts_the_designs_that_cancel_the_most_modes_first() -> None:
    """X and Y have a mode each: the straight line moving both cancels two in one design and is started first; the
    others (one mode a design: one axis moving, or each axis its own design) keep their program order."""
    program = _program(
        ProgramMove((0.3, 0.0), "synchronized"),  # x alone: one mode
        ProgramMove((0.0, 0.1), "independent"),  # both, one design each: one mode a design
        ProgramMove((0.2, 0.2), "straight_line"),  # both on one path: two modes
        ProgramMove((0.2, 0.3), "straight_line"),  # y alone: one mode
    )
    assert heaviest_first(program) == [2, 0, 1, 3]


def test_the_metrics_made_beside_each_design_are_the_ones_assemble_would_make() -> None:
    """design_one simulates each moving axis's metrics where the move is designed (a worker); the cycle assembled
    from the designs without them (assemble simulating them itself) reports the same metrics, field for field."""
    program = _program(ProgramMove((0.3, 0.05), "synchronized", 0.1), ProgramMove((0.0, 0.0), "straight_line"))
    designed = design_moves(program)
    assert all(d.metrics is not None and len(d.metrics) == 2 for d, _ in designed)
    with_them = assemble(program, designed)
    without = assemble(program, [(replace(d, metrics=None), fit) for d, fit in designed])
    for ours, theirs in zip(with_them.moves, without.moves, strict=True):
        assert [a.metrics for a in ours.axes] == [a.metrics for a in theirs.axes]
        assert all(a.metrics is not None for a in ours.axes)
