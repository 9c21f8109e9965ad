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

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from models.errors import SolverFailed, SolverTimedOut
from models.rigid_motion import RigidMove
from optim.families.time_optimal.arcs import arcs_of, merged, same_command, structure
from optim.families.time_optimal.certify import Certificate, certificate, certificate_applies, wrong_sign
from optim.families.time_optimal.refine import Refined, newton, refine
from optim.families.time_optimal.repair import NOTCH_SHARE, bang_start, coast_dips, notched
from optim.families.time_optimal.search import GridSearch, clip, project
from optim.families.time_optimal.shaped import as_start, rigid_of, shaped_arcs, shapers
from optim.families.time_optimal.shooting import shoot
from optim.families.time_optimal.structures import Start, reversal_starts, three_switch_starts
from optim.families.time_optimal.types import Arc, GridSolution, Solution, Spec

Array = NDArray[np.float64]
LimitCheck = Callable[[tuple[Arc, ...]], bool]
Where = tuple[int, float, float]  # certify.wrong_sign's answer: the arc, the first and the last time of its run
FALLBACK_FINER = 4  # without an exact candidate, the grid optimum is sought again on steps this much shorter
UNREFINED_FINER = 8  # ... and then this much too where every refined candidate is longer than the coarse grid's command
PROBES = 3
PROBE_FINER = 4  # the probe's grid is this much finer than the search's
MAX_ARCS = 24  # a start with more arcs is not refined (a chattering grid vertex: another start is tried)
GUESS_MARGIN = 0.05  # the grid search starts this much above the shaped rigid optimum's duration
CERTIFIED_GAP = 1e-9  # a certified answer's lower bound: its duration less this (the switching times' precision)
SHORTER = 1e-12  # a candidate replaces the best only if shorter by more than this (relative)
MAX_DIPS = 4  # coast_dips tried with 1 to this many dips (each an SLSQP run of 10-40 ms) where nothing is proven
DIP_PASSES = 2  # from the command found, then from the shorter one the dips gave
CHAINS = 2  # the shortest predicted commands not certified are repaired in a chain (_Best.chain) ...
CHAIN_REFINES = 4  # ... of this many refines at most in all (each an SLSQP run of 5-60 ms)
WIDER = 3.0  # a chain's notch SLSQP fails from is tried again this many times wider
CHAIN_AFTER = 4  # the chains start once this many predicted commands converged uncertified (or after all starts)
PROGRESS = 1e-6  # a chain's step that shortens the command by less than this (relative) ends it (no new structure)
SAME_RTOL = 1e-12  # Newton's commands from two starts whose arcs differ by less than this (of the duration) are one
REPAIRS = 4  # off-limit arcs made bang at most this often a design (each an SLSQP run of a few milliseconds)


def _duration_s(arcs: tuple[Arc, ...]) -> float:
    return sum(a.duration_s for a in arcs)


def _next_repair(spec: Spec, arcs: tuple[Arc, ...], notching: bool) -> tuple[Start | None, Where | None]:
    """The start of the next repair of ``arcs`` (optim.families.time_optimal.repair): their off-limit arcs made bang;
    else, with ``notching``, a notch where the multipliers contradict them, and that place (certify.wrong_sign:
    None for the former); (None, None) where neither applies."""
    durations, levels, _ = as_start(spec, arcs)
    start = bang_start(spec, durations, levels)
    if start is not None or not notching:
        return start, None
    where = wrong_sign(spec, arcs)
    return (None if where is None else notched(spec, durations, levels, *where)), where


def _stuck(result: Refined | None, arcs: tuple[Arc, ...]) -> bool:
    """A repair of ``arcs`` that SLSQP failed from, or brought back shorter by less than PROGRESS."""
    return result is None or _duration_s(result.arcs) > _duration_s(arcs) * (1 - PROGRESS)


@dataclass(frozen=True)
class Found:
    arcs: tuple[Arc, ...]
    method: str
    note: str

    @property
    def duration_s(self) -> float:
        return _duration_s(self.arcs)


class _Best:
    """The shortest candidate that checks out so far."""

    def __init__(self, spec: Spec, search: GridSearch, check_limits: LimitCheck | None) -> None:
        self.spec, self.search, self.check_limits = spec, search, check_limits
        self.found: Found | None = None
        self.proof: Certificate | None = None  # the found command is proven the minimum-time one: search no more
        self.repairs = 0
        self.notching = False  # repairs also notch where sigma contradicts a bang arc (last_repairs)
        self.repaired: list[tuple[tuple[Arc, ...], str]] = []  # repaired commands not proven: offered at the end
        self.accepted: dict[tuple[Arc, ...], bool] = {}  # accepts' answers

    def accepts(self, arcs: tuple[Arc, ...]) -> bool:
        """``arcs`` meet every limit exactly and the bands on the dense check (remembered: a chain's command is
        checked before its certificate, and again when offered)."""
        known = self.accepted.get(arcs)
        if known is None:
            known = (self.check_limits is None or self.check_limits(arcs)) and self.search.verified(arcs)
            self.accepted[arcs] = known
        return known

    def offer(self, arcs: tuple[Arc, ...], method: str, note: str, proof: Certificate | None = None) -> bool:
        """Keep ``arcs`` if shorter and they check out; ``proof``: their certificate, if already found."""
        total = _duration_s(arcs)
        if self.found is not None and total >= self.found.duration_s * (1 - SHORTER):
            return False
        if total > self.spec.max_duration_s or not self.accepts(arcs):
            return False
        self.found = Found(merged(arcs), method, note)
        self.proof = proof or certificate(self.spec, self.found.arcs)
        if self.proof is None:
            self.repair(self.found.arcs)
        return True

    def repair(self, arcs: tuple[Arc, ...]) -> None:
        """``arcs`` with their off-limit arcs made bang, or else a notch where sigma contradicts a bang arc
        (optim.families.time_optimal.repair), refined with every level fixed: offered at once where the certificate
        proves it (the search ends), else kept for the end (offered then, so that it does not steer the search: a
        shorter best earlier stopped the probes that found shorter)."""
        if self.repairs >= REPAIRS or not certificate_applies(self.spec):  # (no structure it could prove)
            return
        start, where = _next_repair(self.spec, arcs, self.notching)
        how = " (its off-limit arcs made bang)" if where is None else " (notched where the multipliers say)"
        if start is None or len(start[0]) > MAX_ARCS:
            return
        self.repairs += 1
        result = refine(self.spec, *start, self.search.cuts)
        if _stuck(result, arcs) and where is not None and self.repairs < REPAIRS:  # (as a chain's notch)
            self.repairs += 1
            result = self.wider_notch(arcs, where) or result
        if result is None:
            return
        note = result.status + how
        proof = certificate(self.spec, merged(result.arcs))
        if proof is None or not self.offer(result.arcs, "refined", note, proof):
            self.repaired.append((result.arcs, note))

    def with_dips(self) -> None:
        """With one cancelled mode and a held acceleration: the found command with 1 to MAX_DIPS dips at its coast's
        end (optim.families.time_optimal.repair.coast_dips), each refined with fixed levels and offered; again from
        the shorter command found, DIP_PASSES times at most (a train grows from the dips already there)."""
        if len(self.spec.zero_poles) != 1 or not certificate_applies(self.spec):
            return
        pole = self.spec.zero_poles[0]
        if pole.imag == 0.0:
            return
        period_s = 2.0 * math.pi / abs(pole.imag)
        for _ in range(DIP_PASSES):
            assert self.found is not None
            durations, levels, _ = as_start(self.spec, self.found.arcs)
            shorter = False
            for count in range(1, MAX_DIPS + 1):
                start = coast_dips(self.spec, durations, levels, period_s, count)
                if start is None or self.proof is not None:
                    return
                shorter |= self.refine_from(start, f" ({count} dips at its coast's end)")
            if not shorter:
                return

    def offer_repaired(self) -> None:
        """The repaired commands kept for the end (each offered may be repaired again, within REPAIRS)."""
        while self.repaired and self.proof is None:
            arcs, note = self.repaired.pop(0)
            self.offer(arcs, "refined", note)

    def last_repairs(self) -> None:
        """The best found repaired in a chain of REPAIRS more, now also notched where sigma contradicts a bang arc
        (the search's early, longer candidates spent the first REPAIRS; notches only here, so that the search and
        the dips run as before them)."""
        if self.found is None or self.proof is not None:
            return
        self.repairs, self.notching = 0, True
        self.repair(self.found.arcs)
        self.offer_repaired()

    def refine_from(self, start: Start, note: str = "") -> bool:
        if len(start[0]) > MAX_ARCS:
            return False
        result = refine(self.spec, *start, self.search.cuts)
        return result is not None and self.offer(result.arcs, "refined", result.status + note)

    def predicted(self, starts: list[Start], note: str) -> list[tuple[Arc, ...]]:
        """Newton on each predicted structure (optim.families.time_optimal.structures) until one is certified
        (offered: the answer); once CHAIN_AFTER converged uncertified (or after the last start, if fewer did), the
        shortest CHAINS of them repaired in chains (``chains``: the remaining starts cost as much as a chain); the
        commands not certified, to offer after the search (as the search did without them)."""
        held: list[tuple[Arc, ...]] = []
        budget = [CHAIN_REFINES]
        seen: list[tuple[tuple[Arc, ...], bool]] = []  # each command Newton converged to, and whether it was held
        for durations, levels, _ in starts:
            result = newton(self.spec, durations, levels)
            if result is None:
                continue
            # another start's command to round-off (9 of 36 on the held-jerk bench) is kept or not as it was, without
            # its certificate and limit check again (0.3 ms)
            keep = next((kept for arcs, kept in seen if same_command(arcs, result.arcs, SAME_RTOL)), None)
            if keep is None:
                proof = certificate(self.spec, merged(result.arcs))
                if proof is not None and self.offer(result.arcs, "refined", note, proof):
                    return []
                keep = proof is not None or self.accepts(result.arcs)
                seen.append((result.arcs, keep))
            if not keep:
                continue  # it breaks a limit: no chain from it (its repairs keep the breach), nothing to offer
            held.append(result.arcs)
            if len(held) == CHAIN_AFTER and self.chains(held, note, budget):
                return []
        return [] if len(held) < CHAIN_AFTER and self.chains(held, note, budget) else held

    def chains(self, held: list[tuple[Arc, ...]], note: str, budget: list[int]) -> bool:
        """A chain from each of the CHAINS shortest commands ``held`` until one proves its answer (True)."""
        return any(self.chain(arcs, note, held, budget) for arcs in sorted(held, key=_duration_s)[:CHAINS])

    def chain(self, arcs: tuple[Arc, ...], note: str, held: list[tuple[Arc, ...]], budget: list[int]) -> bool:
        """``arcs`` repaired again and again (off-limit arcs made bang, else a notch where the multipliers
        contradict them: optim.families.time_optimal.repair), each refined with fixed levels, until the certificate
        proves one (offered: True) or a step fails, shortens by less than PROGRESS or ``budget[0]`` refines are
        spent; each command found is added to ``held``. Before any LP: a predicted structure one or two reversals
        short of the optimum's gets them where the switching function says (7 of 20 held-jerk moves of
        bench/time_optimal_speed.py certified in 30-190 ms instead of after the search)."""
        for _ in range(budget[0]):
            start, where = _next_repair(self.spec, arcs, notching=True)
            if start is None or len(start[0]) > MAX_ARCS:
                return False
            budget[0] -= 1
            if self.shot(start, f"{note}, repaired where the multipliers say"):
                return True
            result = refine(self.spec, *start, self.search.cuts)
            if _stuck(result, arcs) and where is not None and budget[0] > 0:  # (bench/time_optimal_speed.py's
                budget[0] -= 1  # held-jerk move 6)
                result = self.wider_notch(arcs, where)
            if result is None or not self.accepts(result.arcs):
                return False
            proof = certificate(self.spec, merged(result.arcs))
            how = f"{note}, repaired where the multipliers say: {result.status}"
            if proof is not None and self.offer(result.arcs, "refined", how, proof):
                return True
            if _stuck(result, arcs):
                return False
            held.append(result.arcs)
            arcs = merged(result.arcs)
        return False

    def shot(self, start: Start, note: str) -> bool:
        """A bang train's Newton on Pontryagin's conditions (optim.families.time_optimal.shooting), offered if the
        certificate proves it: held-jerk move 3's repaired +-+-+-+ in 0.5 ms, where SLSQP took 0.9."""
        arcs = None if any(start[2]) else shoot(self.spec, start[0], start[1])
        proof = None if arcs is None else certificate(self.spec, merged(arcs))
        how = f"{note}: Newton on the switching times and the multipliers (Pontryagin's conditions)"
        return arcs is not None and proof is not None and self.offer(arcs, "refined", how, proof)

    def wider_notch(self, arcs: tuple[Arc, ...], where: Where) -> Refined | None:
        """The notch at ``where`` in ``arcs`` WIDER times wider than repair's, refined: where SLSQP failed from the
        thin one or brought it back no shorter (``_stuck``)."""
        durations, levels, _ = as_start(self.spec, arcs)
        wider = notched(self.spec, durations, levels, *where, share=WIDER * NOTCH_SHARE)
        return refine(self.spec, *wider, self.search.cuts)

    def refine_grid(self, values: Array, step_s: float, note: str = "") -> bool:
        """The grid command's structure refined (its fractional levels free), then with them made bang (repair's
        rules, every level fixed: another local optimum than SLSQP's on the free levels, which often stops at its
        cap); True if either is kept."""
        durations, levels, free = structure(values, step_s)
        kept = self.refine_from((durations, levels, free), note)
        if self.proof is None and any(free):
            bang = bang_start(self.spec, durations, levels)
            if bang is not None:
                kept |= self.refine_from(bang, f"{note} (its fractional levels made bang)")
        return kept


def shaped_rigid(best: _Best) -> Found | None:
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


def _refined(best: _Best, search: GridSearch, grid: GridSolution | None, rigid: RigidMove | None) -> None:
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


def _grid_answer(best: _Best, search: GridSearch, grid: GridSolution) -> GridSolution:
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


def _finer(best: _Best, search: GridSearch, grid: GridSolution, finer: int) -> GridSolution:
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
    best = _Best(spec, search, check_limits)
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
        shortest = min(held, key=_duration_s)
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
