"""POST /v1/profiles/time-optimal: the minimum-time command without residual vibration, nominal or robust."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body, Depends, Response

from app import problems
from app.deps import PoolDep, SettingsDep, ThreadsDep
from app.examples.time_optimal import EXAMPLES
from app.family_names import slug_of
from app.json_bodies import JSONRoute
from app.responses import CSV_RESPONSE_DOC, Output, ProfileOutput, respond
from app.schemas.time_optimal import FAMILY, TimeOptimalIn, TimeOptimalOut
from app.services import profile as profiles

router = APIRouter(prefix="/v1", tags=["time-optimal"], route_class=JSONRoute)


@router.post(
    f"/profiles/{slug_of(FAMILY.name)}",
    summary="Minimum-time command without residual vibration, nominal or robust over a frequency band",
    response_model=TimeOptimalOut,
    responses={**CSV_RESPONSE_DOC, **problems.responses(413, 422, 503, 504)},
)
async def time_optimal_profile(
    body: Annotated[TimeOptimalIn, Body(openapi_examples=EXAMPLES)],
    settings: SettingsDep,
    pool: PoolDep,
    threads: ThreadsDep,
    output: Annotated[Output, Depends(ProfileOutput(TimeOptimalOut))],
) -> Response:
    """The shortest motor command within the limits that leaves the load without residual vibration at the
    plant's modes (exactly zero), or whose percentage vibration V stays <= robustness.max_percentage_vibration
    for every true natural frequency in a band (and damping ratio in a range), or with zero derivatives of the
    residual in frequency (derivative_order). The stop cancels what the start excited: shaping pays half a period
    (ZV) or a whole one (ZVD, EI) after each acceleration step, this command typically a fraction of a percent.

    Method (Singh and Vadali 1993; Pao and Singhose; the LP view of Dhanda, Vaughan and Singhose 2009): for a
    fixed duration on a grid with the acceleration (with max_jerk, the jerk) constant on each step, every
    constraint is linear: the end state, the velocity/acceleration bounds (exact at the nodes), the motor
    torque J_M a + J_L a_L of a two-inertia plant (five points a step), the residual of each mode
    (Re F = Im F = 0, F = int a(t) exp(lambda (T - t)) dt), each band point |F| <= c by an inscribed 16-gon, the
    points added as cutting planes until a dense check (at least 1500 frequencies per damping ratio, more for a
    wide band) passes. Feasibility is monotone in the number of steps, so bisection gives the grid's optimum
    (HiGHS). The answer is the shortest exact candidate, each kept only if every limit and the dense band check
    hold: the grid optimum's structure, the shaped rigid optimum (Ruckig's rigid time-optimal move, jerk
    included, convolved with ZV per mode, and for a band with ZVs spread over it: exactly feasible, so the
    answer is never longer than that recipe and a move it shows feasible is never refused), the symmetric
    three-switch structure and finer-grid probes, refined by SLSQP and a Newton polish. Before any LP, predicted
    arc structures (the rigid optimum with reversal pulses; with two modes or more, the lower modes' proven
    command with a reversal of the next) are solved by Newton, and one that Pontryagin's switching function proves
    minimum-time is the answer with no search; where only the lower modes' command is proven, it bounds the answer
    from below and a command within 1e-4 of that bound is the answer with no search. A band also keeps
    exactly zero residual at the nominal modes unless robustness.zero_residual_at_modes is false;
    lower_bound_s certifies the problem as asked.

    design: duration_s; method ("refined": exact switching times, the shortest command found, proven minimum-time
    where lower_bound_method says so, else lower_bound_s bounds the gap; "shaped_rigid": the shaped rigid optimum
    itself; "grid": the optimum of a 4x finer search grid, with a band or a torque limit); rigid_duration_s
    (Ruckig's rigid minimum within every limit, jerk included); lower_bound_s (a certificate, lower_bound_method
    says which: the switching function's (the duration itself: proven minimum-time), the proven minimum of the
    lower modes alone (a relaxation), HiGHS proving infeasible a relaxation that every command of that duration
    satisfies, by its step averages, or the motor's rigid minimum; no command at all, on any grid, is shorter);
    arcs (start, duration, level, bang/coast/partial); robustness (requested, achieved band and the worst V inside
    the request, by an independent dense check with models.sensitivity on the exact command); modes cancelled;
    the grid (null when the grid search found nothing and the shaped rigid optimum answers), the refinement and
    the search's LP counts. tradeoff: one row per half-width.
    solver: status, the design's method; solves, iterations and time count every LP of the design, its
    tightenings and its trade-off rows.
    Infeasible within max_duration_s is a 422 /problems/infeasible only where proven; a search that found
    nothing without a proof is /problems/solver-failed; over the time limit, 504."""
    answer, result = await profiles.design(FAMILY, body, settings, pool, threads)
    return await respond(output, answer, result, body, "time-optimal profile")
