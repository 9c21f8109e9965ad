"""The minimum-time answer: the shortest exact candidate, never longer than the shaped rigid optimum.

Candidates, each refined to exact switching times (optim.families.time_optimal.refine) and kept only if it meets
the limits exactly (the caller's check) and the bands on the dense check (optim.families.time_optimal.check):

- first the predicted structures (optim.families.time_optimal.structures), by damped Newton: one that its
  certificate proves minimum-time (optim.families.time_optimal.certify) is the answer, with nothing else computed
  (a proven minimum is never longer than the shaped rigid optimum); the others are offered after the search;
- the shaped rigid optimum (optim.families.time_optimal.shaped), as it is and refined: the recipe's answer,
  feasible by construction, so that no answer is longer and no move it shows feasible is refused;
- the grid optimum's structure (optim.families.time_optimal.search), or its early-acting vertex's;
- known structures: the symmetric three-switch bang-bang of Singh and Vadali (1993) for a held acceleration;
- probes: the early-acting vertex of a grid PROBE_FINER times finer at the best duration found, refined.

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

import numpy as np
from numpy.typing import NDArray

from models.errors import SolverFailed, SolverTimedOut
from models.rigid_motion import RigidMove
from optim.families.time_optimal.arcs import arcs_of
from optim.families.time_optimal.candidates import Best, Found, LimitCheck, duration_s
from optim.families.time_optimal.search import GridSearch, clip, project
from optim.families.time_optimal.shaped import as_start, rigid_of, shaped_arcs, shapers
from optim.families.time_optimal.structures import reversal_starts, three_switch_starts
from optim.families.time_optimal.types import GridSolution, Solution, Spec

Array = NDArray[np.float64]
FALLBACK_FINER = 4  # without an exact candidate, the grid optimum is sought again on steps this much shorter
UNREFINED_FINER = 8  # ... and then this much too where every refined candidate is longer than the coarse grid's command
PROBES = 3
PROBE_FINER = 4  # the probe's grid is this much finer than the search's
GUESS_MARGIN = 0.05  # the grid search starts this much above the shaped rigid optimum's duration
CERTIFIED_GAP = 1e-9  # a certified answer's lower bound: its duration less this (the switching times' precision)


def shaped_rigid(best: Best) -> Found | None:
    """The first shaped rigid optimum that checks out (the shapers of ``shapers``), offered to ``best``."""
    for shaper in shapers(best.spec):
        rigid = rigid_of(best.spec, shaper)
        if rigid is None:
            continue
        arcs = shaped_arcs(best.spec, rigid, shaper)
        note = (
            f"the rigid time-optimal move (Ruckig) shaped by {shaper.count} positive impulses "
            "(no shorter command found)"
        )
        if best.offer(arcs, "shaped_rigid", note):
            return best.found
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
    """Every exact candidate offered to ``best``: the grid's structures, the shaped rigid optimum's, the known
    structures, then the probes."""
    spec = best.spec
    shaped = best.found
    if grid is not None:
        values = clip(spec, project(spec, grid))
        if not best.refine_grid(values, grid.step_s):
            late = search.late_vertex(grid.steps, grid.step_s)
            if late is not None:
                best.refine_grid(clip(spec, late), grid.step_s)
    if best.proof is not None:
        return
    if shaped is not None:
        best.refine_from(as_start(spec, shaped.arcs), " (from the shaped rigid optimum)")
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


def _grid_answer(best: Best, search: GridSearch, grid: GridSolution) -> GridSolution:
    """The grid optimum on a grid FALLBACK_FINER times finer (``_finer``). Searched where no structure was refined,
    where the refined one is longer than the coarse grid's own command (a local optimum: 509.9 ms against the
    finer grid's 504.2 on bench/time_optimal.py's two-mode case), or with a held jerk (whose refined structures are
    often local optima); the grid it used. Where the refined candidates are all longer than the coarse grid's command
    (no band: there none is refined), then also on a grid UNREFINED_FINER times finer (the 25 Hz held-jerk move of
    docs/benchmarks.md's nested bands: 657.79 ms from the 4x grid, 0.23 % above the 800-step LP's 656.27; 656.53 from
    the 8x grid's structure, with one BLAS thread as the service's workers run)."""
    spec, found = best.spec, best.found
    coarse_s = grid.steps * grid.step_s
    if found is not None and found.method == "refined" and spec.order == 2 and found.duration_s <= coarse_s:
        return grid  # a refined held acceleration shorter than the grid's own command: the finer grid cost 2.5x
    struggling = found is not None and found.method == "refined" and found.duration_s > coarse_s and not spec.bands
    fine = _finer(best, search, grid, FALLBACK_FINER)
    return _finer(best, search, grid, UNREFINED_FINER) if struggling else fine


def _finer(best: Best, search: GridSearch, grid: GridSolution, finer: int) -> GridSolution:
    """The grid optimum on steps ``finer`` times shorter: its structures refined in turn (another local optimum than
    the coarse grid's: 1028.8 ms instead of 1032.4 on bench/time_optimal.py's 5 Hz cruise with a jerk limit), and
    itself the answer where nothing exact checks out or it is shorter; the grid it used."""
    spec = best.spec
    fine = search.bisect(grid.step_s / finer, finer * grid.infeasible_steps, finer * grid.steps)
    if fine is None:
        fine = grid
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


def solve(spec: Spec, check_limits: LimitCheck | None = None, bound_spec: Spec | None = None) -> Solution:
    """The minimum-time command of ``spec`` (see the module's docstring). ``check_limits(arcs) -> bool`` tells
    whether a command meets the limits exactly (the caller's independent check); ``bound_spec`` is the problem
    lower_bound_s certifies (default ``spec``)."""
    began = time.perf_counter()  # for solve_time_s only: the search's caps are counts (optim.families.time_optimal.lp)
    search = GridSearch(spec)
    best = Best(spec, search, check_limits)
    rigid = rigid_of(spec)
    exact = spec.torque is None and not spec.bands  # a torque limit or a band: the grid optimum (or the shaped one)
    note = "Newton on the switching times of the rigid optimum with reversal pulses"
    held = best.predicted(reversal_starts(spec, rigid), note) if exact else []  # no LP where one is proven
    shaped = None if best.proof is not None else shaped_rigid(best)  # a proven answer is never longer than it
    grid = None if best.proof is not None else _grid(search, shaped)
    if exact and best.proof is None:
        _refined(best, search, grid, rigid)
    if grid is not None and best.proof is None:
        grid = _grid_answer(best, search, grid)
    for arcs in held if best.proof is None else []:
        best.offer(arcs, "refined", note)
    if held and best.proof is None:  # SLSQP from the shortest: its structure's optimum is often the certified one
        shortest = min(held, key=duration_s)
        best.refine_from(as_start(spec, shortest), " (from a predicted structure)")
    best.offer_repaired()
    if best.proof is None:
        best.with_dips()
    best.last_repairs()
    found = best.found
    assert found is not None  # the shaped rigid optimum, or the grid's
    if best.proof is not None and (bound_spec is None or bound_spec is spec):
        found = Found(found.arcs, found.method, f"{found.note}; {best.proof.describe()}")
        bound = found.duration_s * (1 - CERTIFIED_GAP)
        method = "the switching function's certificate (Pontryagin, optim.families.time_optimal.certify)"
    else:
        bound, method = search.lower_bound(found.duration_s, bound_spec)
    return Solution(
        arcs=found.arcs,
        order=spec.order,
        duration_s=found.duration_s,
        lower_bound_s=min(bound, found.duration_s),
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
