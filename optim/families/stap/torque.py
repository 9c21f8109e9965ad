"""The motor torque limit held for the real torque J_M a_M + J_L a_L (beyond Cusimano 2022, eqs. 19, 57-59).

Eq. (19) bounds the rigid part (J_M + J_L) a_M; eqs. (57)-(59) add the undamped oscillation of one
ramp with a long t_c. Damping, a short t_c and the deceleration ramp of a rest-to-rest move meeting
the first ramp's oscillation can still push the real torque past M (an audit found 71.6956 N m for
M = 71.6677 N m). So every design is checked on its exact peak (``models.stap_torque.peak_motor_torque_nm``)
and, where it breaks the limit, the closed form is redesigned with a lower acceleration cap found
by a 1-D search on that exact peak.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

from models.commands import PiecewiseCommand
from models.errors import Infeasible, InvalidParameter
from models.plants import Plant
from models.stap import RestToRest, Stap
from models.stap_torque import peak_motor_torque_nm
from optim.families.stap.types import StapDesign, StapRequest

TORQUE_RTOL = 1e-12  # round-off allowed above M (a design touching eq. 19 exactly); the pipeline refuses 1e-9
SEARCH_RTOL = 1e-7  # the acceleration cap is found to this fraction
MAX_SEARCH_STEPS = 40


def command_of(stap: Stap, move: RestToRest | None) -> PiecewiseCommand:
    """The exact command of a ramp (rest-to-velocity) or of its move."""
    return stap.command() if move is None else move.command()


def fits_torque(plant: Plant, command: PiecewiseCommand, max_torque_nm: float) -> tuple[bool, float]:
    """(exact peak <= M (1 + 1e-12), exact peak in N m)."""
    peak = peak_motor_torque_nm(plant, command)
    return peak <= max_torque_nm * (1.0 + TORQUE_RTOL), peak


def lower_acceleration(
    request: StapRequest, closed: StapDesign, redesign: Callable[[StapRequest], StapDesign]
) -> StapDesign:
    """``closed`` if its exact torque peak fits max_torque_nm, else ``redesign`` with the largest
    acceleration cap (to 1e-7) whose design fits: a cap a fits or not by its exact peak; the search
    brackets it from a0 M / peak down (a0 the design's peak acceleration), then bisects."""
    limit = request.max_torque_nm
    if limit is None:
        return closed
    ok, peak = fits_torque(request.plant, command_of(closed.stap, closed.move), limit)
    if ok:
        return replace(closed, peak_torque_nm=peak)
    first_peak, a0 = peak, abs(closed.stap.peak_acceleration)

    def attempt(cap: float) -> tuple[StapDesign | None, float]:
        try:
            design = redesign(replace(request, max_acceleration=min(cap, request.max_acceleration or cap)))
        except (Infeasible, InvalidParameter):
            return None, float("inf")
        fits, p = fits_torque(request.plant, command_of(design.stap, design.move), limit)
        return (design if fits else None), p

    hi, lo, best = a0, 0.0, None
    cap = a0 * limit / peak
    for _ in range(MAX_SEARCH_STEPS):  # bracket: lower the cap until a design fits
        best, peak = attempt(cap)
        if best is not None:
            lo = cap
            break
        hi = cap
        cap *= min(limit / peak, 1.0 - 1e-3) if peak < float("inf") else 0.5
    if best is None:
        raise Infeasible(
            f"no STAP keeps the motor torque J_M a_M + J_L a_L within max_torque_nm = {limit:.9g} N m: the closed form "
            f"peaks at {first_peak:.9g} N m and lowering the acceleration by a factor {cap / a0:.3g} did not fit",
            field="max_torque_nm",
        )
    best_peak = peak
    for _ in range(MAX_SEARCH_STEPS):  # bisect between the fitting cap lo and the failing one hi
        if hi - lo <= SEARCH_RTOL * hi:
            break
        mid = 0.5 * (lo + hi)
        design, p = attempt(mid)
        if design is None:
            hi = mid
        else:
            lo, best, best_peak = mid, design, p
    note = (
        f"the real motor torque J_M a_M + J_L a_L of the eq. (19)/(57)-(59) design peaks at {first_peak:.9g} N m > "
        f"max_torque_nm = {limit:.9g} (damping, t_c or the other ramp's oscillation): the acceleration is lowered "
        f"to {abs(best.stap.peak_acceleration):.9g} (from {a0:.9g}), where the exact peak is {best_peak:.9g} N m"
    )
    return replace(
        best,
        peak_torque_nm=best_peak,
        torque_lowered_acceleration=lo,
        notes=(*best.notes, note),
    )
