"""The minimum-time answer: the shortest exact candidate, never longer than the shaped rigid optimum.

Candidates, each refined to exact switching times (optim.families.time_optimal.refine) and kept only if it meets
the limits exactly (the caller's check) and the bands on the dense check (optim.families.time_optimal.check):

- with ``sufficient_duration_s`` (a program's synchronized axis that another axis sets the pace of): the shaped
  rigid optimum where it is no longer, first and alone (``sufficient``: not proven minimum-time, not needed to be);
- with two modes or more, first mode by mode (optim.families.time_optimal.by_modes): the lower modes' proven
  command with a reversal of the next, by Newton; a proven one is the answer. Else the lower modes' proven minimum
  bounds the answer from below, and where a command within NEAR of that bound is found (it shaped by ZV at the
  modes above, Newton's shorter commands on the way, their refinement), that command is the answer with no search;
- the predicted structures (optim.families.time_optimal.structures), by damped Newton: one that its
  certificate proves minimum-time (optim.families.time_optimal.certify) is the answer, with nothing else computed
  (a proven minimum is never longer than the shaped rigid optimum); the others are offered after the search;
- with a held jerk and one mode, a move that cruises: the cruise structures (structures.cruise_starts: the velocity
  touching its limit and dipping as the cruise begins, a notch in the deceleration's hold; then
  structures.two_dip_starts: a second dip in mid-cruise), refined by SLSQP (the first repaired) apart from the
  search, the answer where the certificate proves one;
- the shaped rigid optimum (optim.families.time_optimal.shaped), as it is and refined: the recipe's answer,
  feasible by construction, so that no answer is longer and no move it shows feasible is refused;
- the grid optimum's structure (optim.families.time_optimal.search), or its early-acting vertex's;
- known structures: the symmetric three-switch bang-bang of Singh and Vadali (1993) for a held acceleration;
- probes: the early-acting vertex of a grid PROBE_FINER times finer at the best duration found, refined;
- the lower modes' shaped command (by_modes.Relaxed), offered after the search (earlier, a shorter best steers the
  search away from shorter commands).

``method`` of the answer: "refined" (exact switching times of a structure), "shaped_rigid" (the shaped rigid
optimum itself: nothing shorter was found) or "grid" (the optimum of a grid FALLBACK_FINER times finer, where no
exact candidate checks out or applies, or where it is shorter than all of them and meets every limit exactly: the
refinement found a worse local optimum, 1032.4 against the grid's 1028.8 ms on bench/time_optimal.py's 5 Hz cruise
with a jerk limit). With a torque limit or a band no structure is refined (SLSQP
on the band's cut points took seconds and rarely passed the dense check): the grid optimum, or the shaped rigid
optimum where it is shorter.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from functools import partial

import numpy as np
from numpy.typing import NDArray

from models.errors import SolverFailed, SolverTimedOut
from models.rigid_motion import RigidMove
from optim.families.time_optimal.arcs import arcs_of, structure
from optim.families.time_optimal.by_modes import Proven, Relaxed, mode_by_mode
from optim.families.time_optimal.candidates import Best, Found, LimitCheck, duration_s
from optim.families.time_optimal.repair import switched
from optim.families.time_optimal.search import KINEMATIC, GridSearch, clip, project, without_chatter
from optim.families.time_optimal.shaped import as_start, rigid_of, shaped_arcs, shapers
from optim.families.time_optimal.structures import cruise_starts, reversal_starts, three_switch_starts, two_dip_starts
from optim.families.time_optimal.types import Arc, GridSolution, Solution, Spec

Array = NDArray[np.float64]
FALLBACK_FINER = 4  # without an exact candidate, the grid optimum is sought again on steps this much shorter
UNREFINED_FINER = 8  # ... and then this much too where every refined candidate is longer than the coarse grid's command
PROBES = 3
PROBE_FINER = 4  # the probe's grid is this much finer than the search's
GUESS_MARGIN = 0.05  # the grid search starts this much above the shaped rigid optimum's duration
CERTIFIED_GAP = 1e-9  # a certified answer's lower bound: its duration less this (the switching times' precision)
BY_MODES = 2  # with this many modes or more, the proven command is also sought mode by mode before any LP
NEAR = 1e-4  # no search where the answer is proven within this (relative) of the minimum (by_modes.Relaxed)
TRY_NEAR = 1e-3  # ... tried where the relaxation's command is within this of it (SLSQP and a repair, 10-70 ms)


def _predicted(rigid: RigidMove | None, check_limits: LimitCheck | None, spec: Spec) -> Proven | None:
    """The proven command of ``spec`` from its predicted structures (``Best.predicted``), or None."""
    best = Best(spec, GridSearch(spec), check_limits)
    best.predicted(reversal_starts(spec, rigid), "")
    return None if best.found is None or best.proof is None else (best.found.arcs, best.proof)


def _shaped_commands(spec: Spec) -> Iterator[tuple[tuple[Arc, ...], str]]:
    """Each shaped rigid optimum (the shapers of ``shapers``, shortest first) and its description."""
    for shaper in shapers(spec):
        rigid = rigid_of(spec, shaper)
        if rigid is not None:
            yield (
                shaped_arcs(rigid, shaper),
                f"the rigid time-optimal move (Ruckig) shaped by {shaper.count} positive impulses",
            )


def shaped_rigid(best: Best) -> Found | None:
    """The first shaped rigid optimum that checks out (``_shaped_commands``), offered to ``best``."""
    for arcs, what in _shaped_commands(best.spec):
        if best.offer(arcs, "shaped_rigid", f"{what} (no shorter command found)"):
            return best.found
    return None


def sufficient(best: Best) -> Found | None:
    """The first shaped rigid optimum (``_shaped_commands``) no longer than spec.sufficient_s that meets the limits
    exactly, taken as it is (no repair, no certificate: no search follows), or None."""
    spec = best.spec
    limit_s = spec.sufficient_s
    if limit_s is None or spec.torque is not None:
        return None
    for arcs, what in _shaped_commands(spec):
        if duration_s(arcs) <= limit_s and best.accepts(arcs):
            note = (
                f"{what}: no longer than the {limit_s:.6g} s asked (sufficient_duration_s), so not searched further "
                "(not proven minimum-time)"
            )
            return Found(arcs, "shaped_rigid", note)
    return None


def _grid(search: GridSearch, shaped: Found | None) -> GridSolution | None:
    """The grid optimum, searched from the spec's upper guess or just above the shaped rigid optimum where that is
    shorter; None if the search finds no command within its caps (counts of work) where the shaped rigid optimum
    exists (it is then the answer)."""
    try:
        guess = search.spec.upper_guess_s
        if shaped is None or search.spec.bands:  # a band's grids from the first guess (its answers were tuned so)
            return search.grid_optimum(guess)
        return search.grid_optimum(min(guess, shaped.duration_s * (1 + GUESS_MARGIN)))
    except SolverTimedOut:  # the wall-clock last resort: a time-out, never an answer that depends on the load
        raise
    except SolverFailed:
        if shaped is None:
            raise
        return None


def _refined(best: Best, search: GridSearch, grid: GridSolution | None, rigid: RigidMove | None) -> None:
    """Every exact candidate offered to ``best``, until one is proven: the grid's structures, the known structures,
    the probes, then the shaped rigid optimum's (after the probes: on bench/programs.py's 144 designs its
    refinement proved none of the 27 it ran on, the probes 17; 3 % of their time saved, every answer the same)."""
    spec = best.spec
    shaped = best.found
    if grid is not None:
        values = clip(spec, project(spec, grid))
        if not best.refine_grid(values, grid.step_s):
            late = search.late_vertex(grid.steps, grid.step_s)
            if late is not None:
                best.refine_grid(clip(spec, late), grid.step_s)
    for start in three_switch_starts(spec, rigid):
        if best.proof is None:
            best.refine_from(start, " (from the symmetric three-switch structure)")
    for _ in range(PROBES if grid is not None and best.found is not None and best.proof is None else 0):
        assert best.found is not None and grid is not None
        steps = PROBE_FINER * grid.steps
        dt = best.found.duration_s / steps
        probe = search.late_vertex(steps, dt)
        if probe is None or not best.refine_grid(np.clip(probe, -1, 1), dt, " (from a finer grid's vertex)"):
            break
        if best.proof is not None:
            break
    if shaped is not None and best.proof is None:
        best.refine_from(as_start(spec, shaped.arcs), " (from the shaped rigid optimum)")


def _grid_answer(best: Best, search: GridSearch, grid: GridSolution) -> GridSolution:
    """The grid optimum on a grid FALLBACK_FINER times finer (``_finer``; where the refined candidates are all
    longer than the coarse grid's command, its command at its least duration first: ``_least``, proven, no more
    search). Searched where no structure was refined, where the refined one is longer than the coarse grid's own
    command (a local optimum: 509.9 ms against the finer grid's 504.2 on bench/time_optimal.py's two-mode case), or
    with a held jerk (whose refined structures are often local optima); the grid it used. Where the refined
    candidates are all longer than the coarse grid's command (no band: there none is refined), then also on a grid
    UNREFINED_FINER times finer (the 25 Hz held-jerk move of docs/benchmarks.md's nested bands: 657.79 ms from the 4x
    grid, 0.23 % above the 800-step LP's 656.27; 656.53 from the 8x grid's structure, with one BLAS thread as the
    service's workers run)."""
    spec, found = best.spec, best.found
    coarse_s = grid.steps * grid.step_s
    if found is not None and found.method == "refined" and spec.order == 2 and found.duration_s <= coarse_s:
        return grid  # a refined held acceleration shorter than the grid's own command: the finer grid cost 2.5x
    struggling = found is not None and found.method == "refined" and found.duration_s > coarse_s and not spec.bands
    fine = _finer(best, search, grid, FALLBACK_FINER, least=struggling)
    return _finer(best, search, grid, UNREFINED_FINER, fine) if struggling and best.proof is None else fine


def _steps_of(known: GridSolution, dt: float, lo: int) -> int | None:
    """``known``'s duration in steps of ``dt``, where its step is a whole number of them (exactly: the 4x grid's is
    twice the 8x grid's) and that count is above ``lo``; else None."""
    ratio = round(known.step_s / dt)
    count = ratio * known.steps
    return count if ratio >= 1 and known.step_s == ratio * dt and count > lo else None


def _least(best: Best, search: GridSearch, fine: GridSolution) -> bool:
    """With a held jerk: ``fine``'s command at its least duration on as many steps (GridSearch.least_duration), its
    cruise's chatter removed (search.without_chatter), its structure's switches inside a step split
    (repair.switched), refined; True where the certificate proves it."""
    if best.spec.order != 3:
        return False
    least = search.least_duration(fine)
    values = without_chatter(best.spec, clip(best.spec, project(best.spec, least)), least.step_s)
    start = switched(*structure(values, least.step_s))
    best.refine_from(start, " (from the finer grid's vertex at its least duration, without chatter)")
    return best.proof is not None


def _finer(
    best: Best,
    search: GridSearch,
    grid: GridSolution,
    finer: int,
    known: GridSolution | None = None,
    least: bool = False,
) -> GridSolution:
    """The grid optimum on steps ``finer`` times shorter: its structures refined in turn (another local optimum than
    the coarse grid's: 1028.8 ms instead of 1032.4 on bench/time_optimal.py's 5 Hz cruise with a jerk limit), and
    itself the answer where nothing exact checks out or it is shorter; the grid it used. ``known``: a grid optimum on
    steps a whole number of these (the 4x grid's, for the 8x one): its duration is the bisection's upper count,
    solved only where no shorter count is feasible (GridSearch.bisect: one LP of the finest size saved, the same
    counts solved after it), and the full range again where that count is not feasible here."""
    spec = best.spec
    dt = grid.step_s / finer
    lo, top = finer * grid.infeasible_steps, finer * grid.steps
    hi = top if known is None or known is grid else min(top, _steps_of(known, dt, lo) or top)
    fine = search.bisect(dt, lo, hi)
    if fine is None and hi < top:
        fine = search.bisect(dt, lo, top)
    if fine is None:
        fine = grid
    if least and spec.torque is None and not spec.bands and _least(best, search, fine):
        return fine  # proven: the refined command is the answer
    values = clip(spec, project(spec, fine))
    if spec.torque is None and not spec.bands:
        note = " (from the finer grid's structure)"
        if not best.refine_grid(values, fine.step_s, note):
            late = search.late_vertex(fine.steps, fine.step_s)
            if late is not None:
                best.refine_grid(clip(spec, late), fine.step_s, note)
    arcs = arcs_of(spec.scale * values, fine.step_s)
    how = (
        "the grid optimum (no exact structure checks out, or none is shorter: its switching times are the grid's, "
        "within one step of that grid's optimum)"
    )
    if best.found is None:
        best.found = Found(arcs, "grid", how)  # the caller checks its limits between the nodes
    else:  # shorter than every exact candidate and within every limit exactly: the user's answer, labelled
        best.offer(arcs, "grid", how)
    return fine


def _search(
    best: Best,
    search: GridSearch,
    rigid: RigidMove | None,
    held: list[tuple[Arc, ...]],
    note: str,
    relaxed: Relaxed | None,
) -> GridSolution | None:
    """The search where nothing is proven yet: the shaped rigid optimum, the grid optimum and its refinements, the
    predicted commands ``held``, ``relaxed``'s command (offered late, with its own REPAIRS: a shorter best early
    steers the search away from shorter commands, 824.6 against 818.3 ms on a three-mode move), the repairs and the
    dips (see the module); the grid it used."""
    spec = best.spec
    shaped = shaped_rigid(best)
    grid = _grid(search, shaped)
    if spec.torque is None and not spec.bands and best.proof is None:
        _refined(best, search, grid, rigid)
    if grid is not None and best.proof is None:
        grid = _grid_answer(best, search, grid)
    for arcs in held if best.proof is None else []:
        best.offer(arcs, "refined", note)
    if held and best.proof is None:  # SLSQP from the shortest: its structure's optimum is often the certified one
        shortest = min(held, key=duration_s)
        best.refine_from(as_start(spec, shortest), " (from a predicted structure)")
    if relaxed is not None and best.proof is None:  # with REPAIRS of its own
        best.repairs = 0
        _offer_relaxed(best, relaxed)
    best.offer_repaired()
    if best.proof is None:
        best.with_dips()
    best.last_repairs()
    return grid


def _by_modes(best: Best, rigid: RigidMove | None, check_limits: LimitCheck | None) -> Relaxed | None:
    """With BY_MODES modes or more, the proven command sought mode by mode (optim.families.time_optimal.by_modes) and
    offered; else the deepest proven lower modes' command shaped at the others (not offered yet)."""
    if best.spec.torque is not None or best.spec.bands or len(best.spec.zero_poles) < BY_MODES:
        return None
    outcome = mode_by_mode(best.spec, rigid, best.accepts, partial(_predicted, rigid, check_limits))
    if outcome.proven is not None:
        arcs, proof = outcome.proven
        best.offer(arcs, "refined", "found mode by mode (optim.families.time_optimal.by_modes)", proof)
    return outcome.relaxed


def _offer_relaxed(best: Best, relaxed: Relaxed) -> None:
    """``relaxed``'s command offered as it is (and repaired), then, where it is kept (the shortest so far), refined
    with its levels free (bench/time_optimal.py's two-mode move: 40 ms more for nothing when it was always)."""
    if best.offer(relaxed.arcs, "refined", relaxed.note()):
        best.refine_from(as_start(best.spec, relaxed.arcs), f" (from {relaxed.note()})")


def _near(best: Best, relaxed: Relaxed) -> bool:
    """Whether an answer within NEAR of ``relaxed``'s bound is found (offered; no search is needed then):
    ``relaxed``'s command itself, or where it is within TRY_NEAR, it refined with its levels free, then repaired
    (tried apart from ``best``: a shorter best early steers the search)."""
    if duration_s(relaxed.arcs) * (1 - NEAR) <= relaxed.bound_s:
        return best.offer(relaxed.arcs, "refined", relaxed.note())
    if duration_s(relaxed.arcs) * (1 - TRY_NEAR) > relaxed.bound_s:
        return False
    trial = Best(best.spec, best.search, best.check_limits)

    def near_found() -> bool:
        found = trial.found
        return found is not None and found.duration_s * (1 - NEAR) <= relaxed.bound_s

    trial.refine_from(as_start(best.spec, relaxed.arcs), f" (from {relaxed.note()})")
    if not near_found():
        trial.offer(relaxed.arcs, "refined", relaxed.note())  # (and repaired)
    if not near_found():
        return False
    found = trial.found
    assert found is not None
    return best.offer(found.arcs, found.method, found.note)


def _cruise(best: Best, rigid: RigidMove | None) -> bool:
    """The cruise structures refined apart from ``best`` (an unproven shorter best early steers the search) and
    offered where the certificate proves one (True: no search is needed): one dip (structures.cruise_starts), each
    answer repaired (REPAIRS: four of 144 program designs certified only so), then two (structures.two_dip_starts:
    their repairs certified none of those and cost 0.2 s on each seed's 48)."""
    one = [(start, True, "a touch and a dip") for start in cruise_starts(best.spec, rigid)]
    two = [(start, False, "two dips") for start in two_dip_starts(best.spec, rigid)]
    for start, repaired, what in one + two:
        trial = Best(best.spec, best.search, best.check_limits)
        trial.refine_from(start, f" (from a cruise's structure: {what} of the velocity, a notch)")
        if repaired:
            trial.last_repairs()
        found = trial.found
        if trial.proof is not None and found is not None:
            return best.offer(found.arcs, found.method, found.note, trial.proof)
    return False


def solve(spec: Spec, check_limits: LimitCheck | None = None, bound_spec: Spec | None = None) -> Solution:
    """The minimum-time command of ``spec`` (see the module's docstring). ``check_limits(arcs) -> bool`` tells
    whether a command meets the limits exactly (the caller's independent check); ``bound_spec`` is the problem
    lower_bound_s certifies (default ``spec``)."""
    began = time.perf_counter()  # for solve_time_s only: the search's caps are counts (optim.families.time_optimal.lp)
    search = GridSearch(spec)
    best = Best(spec, search, check_limits)
    rigid = rigid_of(spec)
    exact = spec.torque is None and not spec.bands  # a torque limit or a band: the grid optimum (or the shaped one)
    certifies = bound_spec is None or bound_spec is spec  # (a tightened limit's answers bound nothing of the problem)
    best.found = sufficient(best)
    if best.found is not None:
        return _solution(spec, best.found, spec.floor_s, KINEMATIC, search, None, began)
    relaxed = _by_modes(best, rigid, check_limits)  # first: all modes' predicted structures rarely converge
    near = certifies and best.proof is None and relaxed is not None and _near(best, relaxed)
    note = "Newton on the switching times of the rigid optimum with reversal pulses"
    held = best.predicted(reversal_starts(spec, rigid), note) if exact and best.proof is None and not near else []
    if exact and certifies and best.proof is None and not near:
        _cruise(best, rigid)
    grid = None if best.proof is not None or near else _search(best, search, rigid, held, note, relaxed)
    relaxed = relaxed if certifies else None
    found = best.found
    assert found is not None  # the shaped rigid optimum, or the grid's
    if best.proof is not None and certifies:
        found = Found(found.arcs, found.method, f"{found.note}; {best.proof.describe()}")
        bound = found.duration_s * (1 - CERTIFIED_GAP)
        method = "the switching function's certificate (Pontryagin, optim.families.time_optimal.certify)"
    elif near:
        assert relaxed is not None
        bound, method = relaxed.bound_s, relaxed.describe()
    else:
        bound, method = search.lower_bound(found.duration_s, bound_spec)
        if relaxed is not None and relaxed.bound_s > bound:
            bound, method = relaxed.bound_s, relaxed.describe()
    return _solution(spec, found, bound, method, search, grid, began)


def _solution(
    spec: Spec, found: Found, bound_s: float, method: str, search: GridSearch, grid: GridSolution | None, began: float
) -> Solution:
    return Solution(
        arcs=found.arcs,
        order=spec.order,
        duration_s=found.duration_s,
        lower_bound_s=min(bound_s, found.duration_s),
        lower_bound_method=method,
        grid=grid,
        method=found.method,
        refinement=found.note,
        lp_solves=search.counter.solves,
        lp_iterations=search.counter.iterations,
        solve_time_s=time.perf_counter() - began,
        cut_frequencies=len(search.cuts),
        max_lp_iterations=search.counter.max_iterations,
        max_lp_solves=search.counter.max_solves,
        capped_runs=search.counter.capped_runs,
        capped_lps=search.counter.capped_lps,
    )
