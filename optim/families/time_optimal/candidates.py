"""The shortest candidate that checks out so far, and the repairs that turn a candidate into a proven one.

A candidate is kept only if it meets every limit exactly (the caller's check) and the bands on the dense check
(optim.families.time_optimal.check), and is shorter than the best so far; the certificate
(optim.families.time_optimal.certify) proves it the minimum-time command, or its off-limit arcs and the places where
the multipliers contradict it are repaired (optim.families.time_optimal.repair) and refined
(optim.families.time_optimal.refine). The predicted structures (optim.families.time_optimal.structures) are solved
here by damped Newton, and repaired in chains before any LP.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from optim.families.time_optimal.arcs import merged, same_command, structure
from optim.families.time_optimal.certify import Certificate, certificate, certificate_applies
from optim.families.time_optimal.refine import Refined, newton, refine
from optim.families.time_optimal.repair import NOTCH_SHARE, Where, bang_start, coast_dips, next_repair, notched
from optim.families.time_optimal.search import GridSearch
from optim.families.time_optimal.shaped import as_start
from optim.families.time_optimal.shooting import shoot
from optim.families.time_optimal.stationary import stationary
from optim.families.time_optimal.structures import Start
from optim.families.time_optimal.types import Arc, Spec

Array = NDArray[np.float64]
LimitCheck = Callable[[tuple[Arc, ...]], bool]
MAX_ARCS = 24  # a start with more arcs is not refined (a chattering grid vertex: another start is tried)
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


def duration_s(arcs: tuple[Arc, ...]) -> float:
    return sum(a.duration_s for a in arcs)


def _stuck(result: Refined | None, arcs: tuple[Arc, ...]) -> bool:
    """A repair of ``arcs`` that SLSQP failed from, or brought back shorter by less than PROGRESS."""
    return result is None or duration_s(result.arcs) > duration_s(arcs) * (1 - PROGRESS)


@dataclass(frozen=True)
class Found:
    arcs: tuple[Arc, ...]
    method: str
    note: str

    @property
    def duration_s(self) -> float:
        return duration_s(self.arcs)


class Best:
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
        total = duration_s(arcs)
        if self.found is not None and total >= self.found.duration_s * (1 - SHORTER):
            return False
        if total > self.spec.max_duration_s or not self.accepts(arcs):
            return False
        self.found = Found(merged(arcs), method, note)
        self.proof = proof or certificate(self.spec, self.found.arcs) or self.made_stationary()
        if self.proof is None:
            self.repair(self.found.arcs)
        return True

    def made_stationary(self) -> Certificate | None:
        """The found command's switching times made stationary (optim.families.time_optimal.stationary) where its
        certificate fails: kept, proven, where the certificate proves them (the proven minimum is never longer)."""
        found = self.found
        if found is None or found.method != "refined" or not certificate_applies(self.spec):
            return None
        exact = stationary(self.spec, found.arcs)
        if exact is None or not self.accepts(exact):
            return None
        proof = certificate(self.spec, merged(exact))
        if proof is not None:
            self.found = Found(merged(exact), found.method, f"{found.note}; its switching times made stationary")
        return proof

    def repair(self, arcs: tuple[Arc, ...]) -> None:
        """``arcs`` with their off-limit arcs made bang, or else a notch where sigma contradicts a bang arc
        (optim.families.time_optimal.repair), refined with every level fixed: offered at once where the certificate
        proves it (the search ends), else kept for the end (offered then, so that it does not steer the search: a
        shorter best earlier stopped the probes that found shorter)."""
        if self.repairs >= REPAIRS or not certificate_applies(self.spec):  # (no structure it could prove)
            return
        start, where = next_repair(self.spec, arcs, self.notching)
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
        return any(self.chain(arcs, note, held, budget) for arcs in sorted(held, key=duration_s)[:CHAINS])

    def chain(self, arcs: tuple[Arc, ...], note: str, held: list[tuple[Arc, ...]], budget: list[int]) -> bool:
        """``arcs`` repaired again and again (off-limit arcs made bang, else a notch where the multipliers
        contradict them: optim.families.time_optimal.repair), each refined with fixed levels, until the certificate
        proves one (offered: True) or a step fails, shortens by less than PROGRESS or ``budget[0]`` refines are
        spent; each command found is added to ``held``. Before any LP: a predicted structure one or two reversals
        short of the optimum's gets them where the switching function says (7 of 20 held-jerk moves of
        bench/time_optimal_speed.py certified in 30-190 ms instead of after the search)."""
        for _ in range(budget[0]):
            start, where = next_repair(self.spec, arcs, notching=True)
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
