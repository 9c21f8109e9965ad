"""The optimised STAP: multistart over the CasADi problem and selection (Cusimano 2022, eqs. 61-72).

Objectives: ``residual`` at fixed t_a (the caller's or the closed-form one); ``worst_case`` over a
grid of f_n / f_n,e in [1 - u, 1 + u] and damping ratios, at fixed t_a; ``residual_and_time``:
the shortest t_a in [1 / f_n,e (eq. 72), 4 x the closed-form t_a] with residual / move <= tol on
that grid (at the nominal plant when u = 0). a_Max comes from max_acceleration only: the torque is
constrained directly, at the nominal plant and (worst_case, residual_and_time) at five frequencies
spread over the band (its ends and quartiles), with the plant's damping.

Starts are the closed-form design and the other zero-vibration jerk times at its t_a (or the
eq. 61/66 designs for k_j = 1..3 when t_a is free). The closed-form design (whose real torque fits,
``optim.families.stap.torque``) competes with every converged solve: a solve is kept only where it meets the
limits (the acceleration projected onto its constraint exactly, the real torque J_M a_M + J_L a_L
checked on its exact peak, the sampled torque rows tightened by the excess and solved again where
it slipped through) and beats the closed form (lower objective, then shorter). Otherwise the closed
form is returned with selection ``closed_form_kept`` and a note saying why: a solve that fails or
reports Infeasible_Problem_Detected (a local verdict) is never a design, and never a proof that the
problem is infeasible while the closed form meets the limits.

The work is capped in counts: at most MAX_STARTS starts, each solved at most 1 + TORQUE_RESOLVES
times within IPOPT's max_iter, so the design is the same on any machine under any load. IPOPT's
max_wall_time is only a last resort: a solve that reaches it raises SolverTimedOut (never the
closed form in its place, which would make the answer depend on the load).
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from models.errors import Infeasible, InvalidParameter, SolverTimedOut
from models.stap import FloatArray, RestToRest, Stap
from models.stap_design import max_jerk_time
from optim.families.stap.limits import estimated_mode, has_no_acceleration_limit, torque_plant
from optim.families.stap.moves import check_request
from optim.families.stap.problem import (
    ResidualPoints,
    amplitudes,
    band_poles,
    compiled_problem,
    mode_form,
    oscillatory_modes,
    residual_points,
    torque_grid_size,
)
from optim.families.stap.ramp import periods_rule, zero_vibration_candidates
from optim.families.stap.torque import command_of, fits_torque
from optim.families.stap.types import OptimizedDesign, StapDesign, StapRequest
from optim.solver import SolverReport, report_of

TORQUE_BAND_POINTS = 5  # band frequencies where the torque is constrained (ends and quartiles)
JERK_PERIODS_FLOOR = 1e-3  # the optimiser keeps t_j >= 0.001 / f_n,e
TIME_RANGE = 4.0  # residual_and_time searches t_a up to this times the closed-form t_a
MAX_STARTS = 8  # starts of the multistart (the closed form first); each solved at most 1 + TORQUE_RESOLVES times
FEASIBLE = 1e-6  # largest constraint breach accepted from IPOPT (scaled constraints)
TORQUE_RESOLVES = 3  # solves again with the torque rows tightened where the real torque broke the limit


ZERO_RESIDUAL = 1e-12  # a nominal residual (fraction of the load's move) at round-off level


def optimize(request: StapRequest, start: StapDesign) -> OptimizedDesign:
    """The optimised STAP (runs in a worker process); ``start`` is the closed-form design."""
    request = check_request(request)
    plant = request.plant
    mode = estimated_mode(plant)
    f_e = mode.natural_frequency_hz
    s0 = start.stap
    speed = abs(s0.velocity)
    distance = None if start.move is None else abs(start.move.displacement)
    t_a0 = s0.acceleration_time_s

    modal = oscillatory_modes(plant)
    nominal = residual_points(modal.poles, modal.residues, speed, distance, plant.load_move(1.0))
    band = band_poles(request, mode)
    grid = None if band is None else residual_points(band[0], band[1], speed, distance)
    kind = {"residual": "sum", "worst_case": "max", "residual_and_time": "time"}[request.objective]
    used = nominal if kind == "sum" or grid is None else grid

    if kind == "time":
        ta_lo = 1.0 / f_e  # eq. (72)
        ta_hi = TIME_RANGE * t_a0
        if distance is not None:
            ta_hi = min(ta_hi, distance / speed)  # the ramps must fit the displacement
        ta_lo = min(ta_lo, t_a0)
    else:
        ta_lo = ta_hi = t_a0
    t_hat_lo = JERK_PERIODS_FLOOR / (f_e * ta_hi)
    if kind == "sum" and float(np.sum(amplitudes(nominal, speed, t_a0, s0.jerk_time_s))) <= ZERO_RESIDUAL:
        return _closed_form_kept(  # the objective is already at its floor: no solve can lower it
            request,
            start,
            [],
            0,
            0,
            0.0,
            (ta_lo, ta_hi),
            t_hat_lo * ta_lo,
            nominal,
            grid,
            "the closed form leaves no residual at the nominal mode, the objective's minimum: no solve was run",
        )

    torque_modes: list[tuple[complex, complex]] = []
    jj = np.zeros(3)
    if request.max_torque_nm is not None:
        two = torque_plant(request)
        torque_modes = [(p, r) for p, r in zip(modal.poles, modal.residues, strict=True)]
        if band is not None and kind != "sum" and request.frequency_uncertainty > 0.0:
            own = np.full(TORQUE_BAND_POINTS, mode.damping_ratio)
            ratios = np.linspace(
                1.0 - request.frequency_uncertainty, 1.0 + request.frequency_uncertainty, TORQUE_BAND_POINTS
            )
            poles_b, res_b = mode_form(mode.natural_frequency_rad_s * ratios, own)
            torque_modes += list(zip(poles_b, res_b, strict=True))
        jj = np.array(
            [two.motor_inertia_kgm2 + two.load_inertia_kgm2, two.load_inertia_kgm2, 1.0 / request.max_torque_nm]
        )
    top_hz = max((abs(p) / (2 * math.pi) for p, _ in torque_modes), default=0.0)
    try:
        torque_grid = torque_grid_size(top_hz * ta_hi) if torque_modes else 0
    except InvalidParameter as exc:  # too many periods to sample the torque: the closed form meets the limits
        return _closed_form_kept(
            request, start, [], 0, 0, 0.0, (ta_lo, ta_hi), t_hat_lo * ta_lo, nominal, grid, exc.rule
        )
    compiled = compiled_problem(kind, used.poles.size, len(torque_modes), torque_grid, request.caps)

    lay = compiled.layout
    p = np.zeros(compiled.parameter_count)
    p[lay["ta0"]] = t_a0
    p[lay["v"]] = speed
    p[lay["inv_a"]] = 0.0 if request.max_acceleration is None else 1.0 / request.max_acceleration
    pre = (used.factor / np.abs(used.poles) ** 4) ** 2  # pre j^2 |..|^2 |..|^2 = (residual / move)^2
    base = np.column_stack([pre, used.poles.real, used.poles.imag])
    if torque_modes:
        tq = np.array(
            [[pole.real, pole.imag, (2 * r / pole**2).real, (2 * r / pole**2).imag] for pole, r in torque_modes]
        )
        p[lay["tq"]] = tq.ravel()
        p[lay["jj"]] = jj

    def x_of(t_a: float, t_j: float, z: float = 1.0) -> FloatArray:
        head = [t_a / t_a0, min(max(t_j / t_a, t_hat_lo), 0.5)]
        return np.array(head + ([z] if compiled.variables == 3 else []))

    # Normalise the squares: by the start's value (floor 1e-14, a residual of 1e-7) for the
    # residual objectives, by the tolerance squared for residual_and_time.
    p[lay["pts"]] = base.ravel()
    _, _, sq0 = (np.asarray(a).ravel() for a in compiled.evaluate(x_of(t_a0, s0.jerk_time_s), p))
    if kind == "time":
        norm = request.residual_tolerance**2
    else:
        norm = max(float(np.sum(sq0) if kind == "sum" else np.max(sq0)), 1e-14)
    scaled = base.copy()
    scaled[:, 0] /= norm
    p[lay["pts"]] = scaled.ravel()

    lbx = np.array([ta_lo / t_a0, t_hat_lo] + ([0.0] if compiled.variables == 3 else []))
    ubx = np.array([ta_hi / t_a0, 0.5] + ([np.inf] if compiled.variables == 3 else []))
    starts = _starts(request, start, f_e, ta_lo, ta_hi)

    def breach(xs: FloatArray) -> tuple[float, float]:
        fx, gx, _ = (np.asarray(a).ravel() for a in compiled.evaluate(xs, p))
        return float(fx[0]), float(np.max(np.concatenate([compiled.lbg - gx, gx - compiled.ubg])))

    def projected(xs: FloatArray) -> tuple[Stap, RestToRest | None]:
        """The design of a solution, projected onto v <= a_Max (t_a - t_j) exactly (IPOPT meets it to ~1e-8)."""
        t_a, t_hat = float(xs[0] * t_a0), float(xs[1])
        if request.max_acceleration is not None:
            if ta_lo == ta_hi:
                t_hat = max(min(t_hat, 1.0 - speed / (request.max_acceleration * t_a)), 0.0)
            else:
                t_a = max(t_a, speed / (request.max_acceleration * (1.0 - t_hat)))
        stap = Stap(math.copysign(speed, s0.velocity), t_a, t_hat * t_a)
        return stap, None if distance is None else RestToRest(stap, max(0.0, distance / speed - t_a))

    # The closed-form design competes (it meets the limits, its torque by the exact peak): a solve is
    # kept only where it meets the limits too (the real torque checked on its exact peak, the torque
    # rows tightened and re-solved where the sampled constraint let it through) and beats it.
    x_start = x_of(t_a0, s0.jerk_time_s)
    if compiled.variables == 3:
        x_start[2] = float(np.max(np.asarray(compiled.evaluate(x_start, p)[2]).ravel()))
    f_start, _ = breach(x_start)
    meets_start = kind != "time" or float(np.max(sq0)) <= norm * (1.0 + 1e-9)  # within the tolerance
    best: tuple[tuple[bool, float, float], FloatArray] | None = None
    key_start = (not meets_start, f_start, _duration(s0, start.move))
    iterations, elapsed, solves = 0, 0.0, 0  # elapsed: reported only, never a reason to stop
    statuses: list[str] = []
    converged_status = ""
    for k, (t_a_s, t_j_s) in enumerate(starts, 1):  # at most MAX_STARTS
        x0 = x_of(t_a_s, t_j_s)
        if compiled.variables == 3:
            _, _, sq = (np.asarray(a).ravel() for a in compiled.evaluate(x0, p))
            x0[2] = float(np.max(sq))
        lbg, ubg = compiled.lbg.copy(), compiled.ubg.copy()
        for _ in range(TORQUE_RESOLVES + 1):  # the solve, then a few with the torque rows tightened
            started = time.perf_counter()
            solution = compiled.solver(x0=np.clip(x0, lbx, ubx), p=p, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
            report = report_of(compiled.solver, time.perf_counter() - started)
            iterations, elapsed, solves = iterations + report.iterations, elapsed + report.solve_time_s, solves + 1
            statuses.append(report.status)
            if report.timed_out:  # the last resort: no design rather than one that depends on the load
                raise SolverTimedOut(
                    SolverReport(report.status, iterations, elapsed),
                    f"IPOPT reached its wall-clock last resort ({request.caps.max_wall_time_s:g} s) on start "
                    f"{k} of {len(starts)}: no design is returned",
                )
            if not report.converged:
                break
            xs = np.clip(np.asarray(solution["x"]).ravel(), lbx, ubx)
            if breach(xs)[1] > FEASIBLE:
                break
            stap, move = projected(xs)
            xs = x_of(stap.acceleration_time_s, stap.jerk_time_s, *xs[2:])  # the design as returned
            fx = breach(xs)[0]
            if request.max_torque_nm is not None:
                fits, peak = fits_torque(plant, command_of(stap, move), request.max_torque_nm)
                if not fits:  # tighten the torque rows by the measured excess and solve again
                    scale = request.max_torque_nm / peak * (1.0 - 1e-6)
                    rows = compiled.torque_rows
                    lbg[rows], ubg[rows] = lbg[rows] * scale, ubg[rows] * scale
                    lbg[compiled.envelope_rows] *= scale * scale
                    ubg[compiled.envelope_rows] *= scale * scale
                    x0 = xs
                    continue
            converged_status = report.status
            key = (False, fx, _duration(stap, move))
            if _beats(key, key_start) and (best is None or _beats(key, best[0])):
                best = (key, xs)
            break
    if best is None:
        none = None if starts else f"no start: no design with t_j > 0 fits t_a in [{ta_lo:.6g}, {ta_hi:.6g}] s"
        return _closed_form_kept(
            request,
            start,
            statuses,
            solves,
            iterations,
            elapsed,
            (ta_lo, ta_hi),
            t_hat_lo * ta_lo,
            nominal,
            grid,
            none,
        )
    stap, move = projected(best[1])
    t_a = stap.acceleration_time_s
    return OptimizedDesign(
        stap=stap,
        objective=request.objective,
        start=s0,
        nominal_residual=float(np.sum(amplitudes(nominal, speed, t_a, stap.jerk_time_s))),
        start_nominal_residual=float(np.sum(amplitudes(nominal, speed, t_a0, s0.jerk_time_s))),
        grid_worst_residual=None if grid is None else float(np.max(amplitudes(grid, speed, t_a, stap.jerk_time_s))),
        start_grid_worst_residual=None
        if grid is None
        else float(np.max(amplitudes(grid, speed, t_a0, s0.jerk_time_s))),
        solver=SolverReport(converged_status, iterations, elapsed),
        solves=solves,
        selection="optimized",
        acceleration_time_bounds_s=(ta_lo, ta_hi),
        jerk_time_floor_s=t_hat_lo * ta_lo,
        move=move,
    )


IMPROVEMENT = 1e-6  # a solve must lower the objective by this fraction (or tie and be shorter) to replace


def _beats(key: tuple[bool, float, float], other: tuple[bool, float, float]) -> bool:
    """Whether a design ranked (misses the tolerance, objective, duration) is better than ``other``: it
    meets the tolerance where the other does not, or lowers the objective by more than 1e-6 of it, or
    ties on the objective and is shorter; round-off differences do not count."""
    if key[0] != other[0]:
        return not key[0]
    scale = max(abs(other[1]), 1e-300)
    if key[1] < other[1] - IMPROVEMENT * scale:
        return True
    return key[1] <= other[1] + 1e-12 * scale and key[2] < other[2] * (1.0 - 1e-9)


def _duration(stap: Stap, move: RestToRest | None) -> float:
    """How long the command changes: t_a (rest-to-velocity) or the move's 2 t_a + t_cruise."""
    return stap.acceleration_time_s if move is None else move.total_time_s


def _closed_form_kept(
    request: StapRequest,
    start: StapDesign,
    statuses: list[str],
    solves: int,
    iterations: int,
    elapsed: float,
    bounds: tuple[float, float],
    jerk_floor_s: float,
    nominal: ResidualPoints,
    grid: ResidualPoints | None,
    reason: str | None = None,
) -> OptimizedDesign:
    """The closed-form design, returned when no solve met the limits and beat it (IPOPT's
    Infeasible_Problem_Detected is a local verdict, and a start with zero residual leaves it no
    descent direction: neither makes the problem infeasible, the closed form meets the limits)."""
    s0 = start.stap
    speed = abs(s0.velocity)
    what = reason or "IPOPT: " + (", ".join(dict.fromkeys(statuses)) or "no solve")
    note = (
        f"the optimization did not improve on the closed-form design ({what}); the closed form, which meets "
        "the limits, is returned"
    )
    if request.objective == "residual_and_time" and grid is not None:
        worst = float(np.max(amplitudes(grid, speed, s0.acceleration_time_s, s0.jerk_time_s)))
        if worst > request.residual_tolerance:
            note += f" (its residual over the band, {worst:.3g}, is above residual_tolerance)"
    nominal_residual = float(np.sum(amplitudes(nominal, speed, s0.acceleration_time_s, s0.jerk_time_s)))
    worst_grid = (
        None if grid is None else float(np.max(amplitudes(grid, speed, s0.acceleration_time_s, s0.jerk_time_s)))
    )
    return OptimizedDesign(
        stap=s0,
        objective=request.objective,
        start=s0,
        nominal_residual=nominal_residual,
        start_nominal_residual=nominal_residual,
        grid_worst_residual=worst_grid,
        start_grid_worst_residual=worst_grid,
        solver=SolverReport(statuses[-1] if statuses else "not_solved", iterations, elapsed),
        solves=solves,
        selection="closed_form_kept",
        acceleration_time_bounds_s=bounds,
        jerk_time_floor_s=jerk_floor_s,
        move=start.move,
        notes=(note,),
    )


def _starts(
    request: StapRequest, start: StapDesign, f_e: float, ta_lo: float, ta_hi: float
) -> list[tuple[float, float]]:
    """The closed-form design first, then the other zero-vibration jerk times at its t_a (fixed t_a),
    or the eq. (61)/(66) designs for k_j = 1..3 within [ta_lo, ta_hi] (residual_and_time)."""
    s0 = start.stap
    out = [(s0.acceleration_time_s, s0.jerk_time_s)]
    if ta_lo == ta_hi:
        candidates = start.candidates
        if not candidates:
            probe = replace(request, acceleration_time_s=s0.acceleration_time_s, jerk_periods=None, delta=0)
            try:
                candidates = tuple(zero_vibration_candidates(probe, abs(s0.velocity), f_e, s0.acceleration_time_s)[0])
            except (Infeasible, InvalidParameter):
                candidates = ()
        out += [(s0.acceleration_time_s, c.jerk_time_s) for c in candidates]
        # The largest jerk time the acceleration limit allows at this t_a.
        out.append(
            (s0.acceleration_time_s, max_jerk_time(s0.acceleration_time_s, s0.velocity, request.max_acceleration))
        )
    else:
        for k in (1, 2, 3):
            try:
                d = (
                    periods_rule(replace(request, jerk_periods=k), abs(s0.velocity), f_e, k)
                    if not has_no_acceleration_limit(request)
                    else None
                )
            except (Infeasible, InvalidParameter):
                d = None
            if d is not None and ta_lo <= d.stap.acceleration_time_s <= ta_hi:
                out.append((d.stap.acceleration_time_s, d.stap.jerk_time_s))
    seen: list[tuple[float, float]] = []
    for t_a, t_j in out:
        if t_j > 0.0 and all(abs(t_a - a) > 1e-12 * t_a or abs(t_j - b) > 1e-9 * t_a for a, b in seen):
            seen.append((t_a, t_j))
    return seen[:MAX_STARTS]
