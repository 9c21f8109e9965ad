"""STAP design (Cusimano 2022): the closed-form rules and a CasADi/IPOPT formulation over (t_a, t_j).

Closed form (in-process, no solver). f_n,e is the plant's first vibration mode; v the target
velocity; a_Max the acceleration limit: ``max_acceleration`` and, for a two_inertia plant with
``max_torque_nm``, M/(J_M + J_L) (eq. 19) lowered for the torque oscillation (below), the smaller.

- t_a,min = v / a_Max (eq. 21); t_j = k_j / f_n,e (eq. 50 for k_j = 1, eq. 48 for multiples).
- k_j / f_n,e <= t_a,min (eq. 60): t_a = t_a,min + k_j / f_n,e (eq. 61), reaching a_Max;
  otherwise (eq. 65) the triangle t_a = 2 k_j / f_n,e (eq. 66), peaking at 2 v / t_a (eq. 31).
  No STAP has zero residual with t_a < 1 / f_n,e (eq. 72).
- A caller-fixed t_a: the zero-vibration jerk times t_j,0 = (k_j + delta dec(f_n,e t_a)) / f_n,e
  (eqs. 44, 49) that fit t_j <= t_j,max = min(t_a/2, t_a - t_a,min) (eqs. 9, 27, 28), each marked:
  fundamental (k_j = 1, delta = 0), multiple (eq. 48), side band (delta = 1: zero residual at
  f_n,e but a poor SC, Sec. 3 and Fig. 17), and the one below the fundamental value ((0, 1),
  Appendix C, eq. A13, with its conditions A18/A21 when it reaches a_Max). The list is found by
  direct enumeration; eqs. (45)-(46) are reported too (``paper_k_j_max``, ``paper_delta_f``): they
  agree with it at t^_j,max = 1/2 (r = 6.7 gives 3 and 0), but eq. (46) rounds at 1/2 where the
  side band needs dec(r), so it can name a zero beyond t_j,max (r = 9.8, f t_j,max = 2.7 gives
  delta_f = 1, i.e. t_j = 2.8/f_n,e), and eq. (45) uses int(r) where r is meant (t^_j,max = 0.4,
  r = 7.6 gives 2 though 3/f_n,e fits). The enumeration is what the design uses.
- ``auto`` (the Fig. 25 flowchart, Sec. 4 items 1-2, with the paper's "a few hundredths" made a
  tolerance): u = ``frequency_uncertainty``, tol = ``residual_tolerance``; a design "meets" when
  its undamped SC (Appendix B) stays <= tol for f_n / f_n,e in [1 - u, 1 + u].
    Without acceleration_time_s: k_j = 1 first (the fundamental value). If f_n,e t_a,min >= 1
    (eq. 74) it is the trapezoid of eq. (61); if it does not meet and k_j = 2 still reaches a_Max
    (int(f_n,e t_a,min) >= 2, eqs. 63 and 75), k_j = 2 is tried. If f_n,e t_a,min < 1 (eq. 76)
    it is the triangle t_a = 2 / f_n,e; if it does not meet, t_a is lengthened to n / f_n,e,
    n = 3, ..., 10 (k_j = 1; whole f_n,e t_a keeps the SC's horizontal tangent at 1; Figs. 11-13).
    The first design that meets is taken; if none does, the one with the lowest worst-case SC,
    with a warning.
    With acceleration_time_s: the delta = 0 zero with the lowest worst-case SC over the band (the
    smallest k_j on ties); if none fits, the side band (0, 1) with a warning; else infeasible.
- Torque limit (two_inertia): during t_c the load acceleration oscillates with amplitude
  |a_l,c| / a_max given by eq. (57) and the motor torque with (J_L/J_M)/(1 + J_L/J_M) times it
  (eqs. 58-59). The limit used is M / ((J_M + J_L) (1 + m)), m the worst eq. (59) over
  f_n / f_n,e in [1 - u, 1 + u] for the design's k_j = f_n,e t_j: with u = 0.1 and J_L = J_M,
  m = 0.0546 and the limit is 0.948 of eq. (19) (the paper rounds it to 0.94).

Rest-to-rest (beyond the paper): each ramp is the rest-to-velocity design at the cruise speed.
When the displacement D is too short for the requested speed (v t_a > D), the speed is lowered to
the largest one whose ramps fit with no cruise, with the same rule (the same k_j, or the same t_a
and t_j): v = 2 D / (t_j + sqrt(t_j^2 + 4 D / a_Max)) for eq. (61), D / (2 t_j) for the triangle,
D / t_a for a fixed t_a. Without a requested speed the move is the fastest one: no cruise.

Formulation (CasADi/IPOPT, in the worker pool). Variables alpha = t_a / t_a0 and the dimensionless
jerk time t^_j = t_j / t_a of eq. (12) in [t^_j,lo, 1/2], so t_j <= t_a/2 is a bound and
t_a - t_j >= t_a/2 never vanishes. For each pole lambda the free state is the factorised form of
models.stap, and |exp(lambda t) - 1|^2 = (1 - exp(sigma t))^2 + 4 exp(sigma t) sin^2(omega t / 2) is
written without cancellation. Objectives:

- ``residual``: minimise sum over the plant's modes of (residual / move)^2 at fixed t_a (the
  caller's or the closed-form one);
- ``worst_case``: minimise the largest (residual / move)^2 over a grid of f_n / f_n,e in
  [1 - u, 1 + u] and damping ratios (epigraph), at fixed t_a;
- ``residual_and_time``: minimise t_a subject to residual / move <= tol on that grid (at the
  nominal plant when u = 0), t_a in [1 / f_n,e (eq. 72), 4 x the closed-form t_a].

Constraints: v <= a_Max (t_a - t_j) (eqs. 11, 20; a_Max from max_acceleration only: the torque is
constrained directly), and for two_inertia plants with max_torque_nm, |J_M a_m + J_L a_l| <= M
(1 - 1e-4) on a grid of 16 points per period over [0, t_a] and the free oscillation's torque envelope
after t_a, at the nominal plant and (worst_case, residual_and_time) at five frequencies spread over
the band (its ends and quartiles), with the plant's damping. The returned samples are simulated and
any excess over a limit is reported as a warning. The acceleration constraint is met exactly: the
solution is projected onto it (IPOPT meets constraints to ~1e-8). The residual of a
rest-to-rest move is the ramp's times |exp(lambda D/v) - 1|, a constant for each pole, so the
same problem serves it (D/v does not depend on t_a). Each problem is built once per shape and
cached in the worker; starts are the closed-form design and the other zero-vibration jerk times at
its t_a (or the eq. 61/66 designs for k_j = 1..3 when t_a is free). The best converged design that
meets the constraints is returned, and the closed-form design competes too: when no solve improves
on it, it is returned with selection ``closed_form_kept`` (an interior-point run can leave the start's
basin). If no solve converges, the solver's status is raised: a failed solve is never a design.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from models.errors import Infeasible, InvalidParameter, NotApplicable
from models.plants import Mode, Plant, TwoInertiaPlant
from models.simulation import ModalForm, modal_form
from models.stap import (
    MAX_TIME_S,
    RestToRest,
    Stap,
    decimal_part,
    load_acceleration_oscillation,
    max_jerk_time,
    min_acceleration_time,
    nodal_acceleration_limit,
    paper_delta_f,
    paper_k_j_max,
    stap_sensitivity,
    torque_coefficient,
    worst_torque_overshoot,
    zero_vibration_jerk_time,
)
from optim.solver import SolveCaps, SolverReport, ipopt_options, parameter_layout, raise_for_status, report_of

DEFAULT_FREQUENCY_UNCERTAINTY = 0.1
DEFAULT_RESIDUAL_TOLERANCE = 0.05  # "a few hundredths" (Sec. 3)
BAND_POINTS = 401  # SC samples over the band for auto and the reported worst case
AUTO_MAX_PERIODS = 10  # the longest f_n,e t_a auto tries in the triangle case (Figs. 11-13)
MAX_LISTED_CANDIDATES = 64  # zero-vibration jerk times listed (and considered by auto) at a fixed t_a
LIMIT_RTOL = 1e-9  # a peak within this fraction of a_Max counts as reaching it
OBJECTIVES = ("residual", "worst_case", "residual_and_time")
MAX_FREQUENCY_POINTS = 41
MAX_BAND_DAMPING_RATIOS = 5
TORQUE_POINTS_PER_PERIOD = 16
TORQUE_BAND_POINTS = 5  # band frequencies where the torque is constrained (ends and quartiles)
TORQUE_MARGIN = 1e-4  # the torque limit is imposed 0.01 % tighter, absorbing the time grid
TORQUE_GRID_SIZES = (64, 128, 256, 512, 1024)
JERK_PERIODS_FLOOR = 1e-3  # the optimiser keeps t_j >= 0.001 / f_n,e
TIME_RANGE = 4.0  # residual_and_time searches t_a up to this times the closed-form t_a
MAX_STARTS = 8
OPTIONS = {"ipopt.tol": 1e-10, "ipopt.acceptable_tol": 1e-8, "ipopt.hessian_approximation": "limited-memory"}
FEASIBLE = 1e-6  # largest constraint breach accepted from IPOPT (scaled constraints)


# ------------------------------------------------------------------------------------------
# Requests and designs (frozen: they cross the worker-process boundary)


@dataclass(frozen=True)
class StapRequest:
    plant: Plant
    target_velocity: float | None = None  # rest-to-velocity v, or the cruise speed with a displacement
    displacement: float | None = None
    max_acceleration: float | None = None
    max_torque_nm: float | None = None
    jerk_periods: int | None = None  # k_j; None = auto
    delta: int = 0
    acceleration_time_s: float | None = None
    frequency_uncertainty: float = DEFAULT_FREQUENCY_UNCERTAINTY
    residual_tolerance: float = DEFAULT_RESIDUAL_TOLERANCE
    objective: str = "residual"
    band_damping_ratios: tuple[float, ...] | None = None
    frequency_points: int = 21
    caps: SolveCaps = field(default_factory=SolveCaps)


@dataclass(frozen=True)
class TorqueLimit:
    """The acceleration limit that keeps the motor torque within max_torque_nm (eqs. 19, 57-59)."""

    max_torque_nm: float
    nodal_acceleration_limit: float  # eq. (19)
    inertia_ratio: float  # J_L / J_M
    coefficient: float  # (J_L/J_M)/(1 + J_L/J_M)
    load_acceleration_oscillation: float  # worst eq. (57) over the band
    torque_overshoot: float  # worst eq. (59) over the band
    worst_frequency_ratio: float
    factor: float  # 1 / (1 + torque_overshoot)
    acceleration_limit: float  # nodal limit times factor


@dataclass(frozen=True)
class Candidate:
    """A zero-vibration jerk time at a fixed t_a (eq. 49), marked."""

    k_j: int
    delta: int
    jerk_time_s: float
    kind: str  # fundamental, multiple, side_band
    peak_acceleration: float
    acceleration_limit: float | None
    reaches_limit: bool
    note: str


@dataclass(frozen=True)
class AutoStep:
    what: str
    acceleration_time_s: float
    jerk_time_s: float
    band_worst_residual: float
    meets: bool


@dataclass(frozen=True)
class StapDesign:
    """A closed-form design of the ramp (rest-to-velocity), and the move it belongs to."""

    stap: Stap
    estimated_frequency_hz: float
    k_j: int | None
    delta: int | None
    rule: str
    acceleration_limit: float | None  # a_Max used for this design
    min_acceleration_time_s: float | None  # eq. (21) with it
    limit_reached: bool
    torque: TorqueLimit | None
    candidates: tuple[Candidate, ...] = ()
    candidates_truncated: bool = False
    k_j_max: int | None = None  # exact enumeration at a fixed t_a
    delta_f: int | None = None
    paper_k_j_max: int | None = None  # eq. (45)
    paper_delta_f: int | None = None  # eq. (46)
    auto_steps: tuple[AutoStep, ...] = ()
    band_worst_residual: float = 0.0
    frequency_uncertainty: float = 0.0
    notes: tuple[str, ...] = ()
    fixed_acceleration_time: bool = False  # t_a given by the caller
    keeps_acceleration_time: bool = False  # t_a does not follow the speed (caller's, or auto's n/f_n,e)
    # rest-to-rest
    move: RestToRest | None = None
    move_notes: tuple[str, ...] = ()  # what the rest-to-rest rules did (lowered speed, ...)
    requested_velocity: float | None = None
    velocity_lowered: bool = False


@dataclass(frozen=True)
class OptimizedDesign:
    stap: Stap
    objective: str
    start: Stap
    nominal_residual: float  # sum over the plant's modes of residual / move (the optimiser's model)
    start_nominal_residual: float
    grid_worst_residual: float | None  # largest residual / move over the optimiser's band grid
    start_grid_worst_residual: float | None
    solver: SolverReport
    solves: int
    selection: str  # optimized, or closed_form_kept when no solve improved on the start
    acceleration_time_bounds_s: tuple[float, float]
    jerk_time_floor_s: float
    move: RestToRest | None = None


# ------------------------------------------------------------------------------------------
# Elementary rules


def estimated_mode(plant: Plant) -> Mode:
    """The mode the STAP is designed for: the plant's first (lowest) vibration mode (f_n,e)."""
    modes = plant.modes()
    if not modes:
        raise InvalidParameter("plant", plant.kind, "the plant has no vibration mode to design the STAP for")
    return modes[0]


def torque_plant(request: StapRequest) -> TwoInertiaPlant:
    """The plant whose motor torque ``max_torque_nm`` limits: only a two_inertia plant defines it (eq. 58)."""
    plant = request.plant
    if not isinstance(plant, TwoInertiaPlant):
        raise InvalidParameter(
            "max_torque_nm",
            request.max_torque_nm,
            f"a {plant.kind} plant does not define the motor torque (two_inertia does)",
        )
    return plant


def no_acceleration_limit_error() -> InvalidParameter:
    """The error of a rule that needs a_Max (eq. 21) when the request gives none."""
    return InvalidParameter(
        "max_acceleration",
        None,
        "give max_acceleration and/or max_torque_nm (a_Max of eq. 21), or acceleration_time_s",
    )


def torque_limit(request: StapRequest, k_j: float) -> TorqueLimit | None:
    """The lowered acceleration limit of the module docstring, for a design with k_j = f_n,e t_j."""
    if request.max_torque_nm is None:
        return None
    plant = torque_plant(request)
    j_m, j_l = plant.motor_inertia_kgm2, plant.load_inertia_kgm2
    nodal = nodal_acceleration_limit(request.max_torque_nm, j_m, j_l)
    load, overshoot, rho = worst_torque_overshoot(k_j, j_l / j_m, request.frequency_uncertainty)
    factor = 1.0 / (1.0 + overshoot)
    return TorqueLimit(
        max_torque_nm=request.max_torque_nm,
        nodal_acceleration_limit=nodal,
        inertia_ratio=j_l / j_m,
        coefficient=torque_coefficient(j_l / j_m),
        load_acceleration_oscillation=load,
        torque_overshoot=overshoot,
        worst_frequency_ratio=rho,
        factor=factor,
        acceleration_limit=nodal * factor,
    )


def acceleration_limit(request: StapRequest, k_j: float) -> tuple[float | None, TorqueLimit | None]:
    """a_Max for a design with k_j = f_n,e t_j: the smaller of max_acceleration and the lowered
    torque-derived limit; None when neither is given."""
    torque = torque_limit(request, k_j)
    limits = [x for x in (request.max_acceleration, torque.acceleration_limit if torque else None) if x is not None]
    return (min(limits) if limits else None), torque


def band_ratios(uncertainty: float, points: int = BAND_POINTS) -> np.ndarray:
    """f_n / f_n,e over [1 - u, 1 + u] (1 included), or just 1 when u = 0."""
    if uncertainty <= 0.0:
        return np.array([1.0])
    return np.union1d(np.linspace(1.0 - uncertainty, 1.0 + uncertainty, points), [1.0])


def band_worst(stap: Stap, frequency_hz: float, uncertainty: float) -> float:
    """The largest undamped SC (Appendix B) over the band."""
    return float(np.max(stap_sensitivity(stap, frequency_hz, band_ratios(uncertainty))))


# ------------------------------------------------------------------------------------------
# Closed-form designs


def _periods_rule(request: StapRequest, velocity: float, frequency_hz: float, k_j: int) -> StapDesign:
    """t_j = k_j / f_n,e with t_a from eq. (61) or (66)."""
    t_j = zero_vibration_jerk_time(frequency_hz, k_j)
    a_max, torque = acceleration_limit(request, float(k_j))
    if a_max is None:
        raise no_acceleration_limit_error()
    t_a_min = min_acceleration_time(velocity, a_max)
    if t_j <= t_a_min * (1.0 + 1e-12):
        t_a, rule = t_a_min + t_j, "eq. 61: t_a = t_a,min + k_j/f_n,e (k_j/f_n,e <= t_a,min, eq. 60)"
        _check_duration(t_a, "max_acceleration" if request.max_acceleration is not None else "max_torque_nm")
    else:
        t_a, rule = 2.0 * t_j, "eq. 66: triangle t_a = 2 k_j/f_n,e (k_j/f_n,e > t_a,min, eq. 65), peak by eq. 31"
        _check_duration(t_a, "jerk_periods")
    stap = Stap(velocity, t_a, t_j)
    reached = abs(abs(stap.peak_acceleration) - a_max) <= LIMIT_RTOL * a_max
    return StapDesign(
        stap=stap,
        estimated_frequency_hz=frequency_hz,
        k_j=k_j,
        delta=0,
        rule=rule,
        acceleration_limit=a_max,
        min_acceleration_time_s=t_a_min,
        limit_reached=reached,
        torque=torque,
        band_worst_residual=band_worst(stap, frequency_hz, request.frequency_uncertainty),
        frequency_uncertainty=request.frequency_uncertainty,
    )


def _check_duration(t: float, field_name: str) -> None:
    if not math.isfinite(t) or t > MAX_TIME_S:
        raise Infeasible(
            f"the design needs an acceleration time of {t:.9g} s, beyond the {MAX_TIME_S:g} s this service handles "
            "(raise the acceleration limit or lower the velocity)",
            field=field_name,
        )


def _candidate_note(
    k_j: int, delta: int, reaches: bool, frequency_hz: float, t_a: float, t_a_min: float | None
) -> tuple[str, str]:
    if delta == 0:
        if k_j == 1:
            return "fundamental", "fundamental value t_j = 1/f_n,e (eqs. 47, 50): one whole period in each ramp"
        return "multiple", f"multiple of the fundamental value (eq. 48): {k_j} whole periods in each ramp"
    note = (
        "side band (eq. 44 with delta = 1): zero residual at f_n,e, but the load acceleration oscillates during t_c "
        "and the SC is poor (Sec. 3, Fig. 17)"
    )
    if k_j == 0:
        note += "; the only zero below the fundamental value (Appendix C, eq. A13)"
        if reaches and t_a_min is not None:
            whole = frequency_hz * t_a_min
            note += (
                f"; it reaches a_Max, which needs f_n,e t_a,min whole (A18: {whole:.9g}) and "
                f"t_a,min <= t_a < t_a,min + 1/f_n,e (A21: {t_a_min:.9g} <= {t_a:.9g} < {t_a_min + 1 / frequency_hz:.9g})"
            )
        elif t_a_min is not None:
            note += "; it does not reach a_Max: the peak is below the limit (A22-A28)"
    return "side_band", note


def zero_vibration_candidates(
    request: StapRequest, velocity: float, frequency_hz: float, t_a: float
) -> tuple[list[Candidate], bool, int | None, int | None]:
    """The zeros of eq. (44) at a fixed t_a that meet t_j <= t_a/2 (eq. 9) and the acceleration limit
    (eqs. 20, 27), in increasing t_j; whether the list was cut at MAX_LISTED_CANDIDATES; and the last
    one's (k_j, delta) (the exact k_j,max and delta_f). When f_n,e t_a is whole the side bands
    (k_j >= 1, delta = 1) coincide with the multiples and only (0, 1), the rectangle, is listed."""
    r = frequency_hz * t_a
    dec = float(decimal_part(r))
    out: list[Candidate] = []
    last: tuple[int, int] | None = None
    order = [(0, 1)] + [(k, d) for k in range(1, MAX_LISTED_CANDIDATES + 1) for d in (0, 1) if d == 0 or dec > 0.0]
    a_max: float | None = None
    for k, delta in order[:MAX_LISTED_CANDIDATES]:  # at most MAX_LISTED_CANDIDATES zeros
        t_j = zero_vibration_jerk_time(frequency_hz, k, delta, t_a)
        if t_j > 0.5 * t_a * (1.0 + 1e-12):
            return out, False, (last[0] if last else None), (last[1] if last else None)
        a_max, _ = acceleration_limit(request, frequency_hz * t_j)
        peak = velocity / (t_a - t_j)
        if a_max is not None and peak > a_max * (1.0 + LIMIT_RTOL):
            # t_j beyond t_a - t_a,min (eq. 27): a longer t_j only raises the peak.
            return out, False, (last[0] if last else None), (last[1] if last else None)
        last = (k, delta)
        reaches = a_max is not None and abs(peak - a_max) <= LIMIT_RTOL * a_max
        t_a_min = None if a_max is None else min_acceleration_time(velocity, a_max)
        kind, note = _candidate_note(k, delta, reaches, frequency_hz, t_a, t_a_min)
        out.append(Candidate(k, delta, t_j, kind, peak, a_max, reaches, note))
    # More zeros fit than are listed: the last one in closed form, with the last listed a_Max
    # (the torque-lowered limit changes by less than 1 % past k_j = 32).
    reach = max_jerk_time(t_a, velocity, a_max)
    n = math.floor(frequency_hz * reach * (1.0 + 1e-12))
    side = dec > 0.0 and (n + dec) / frequency_hz <= reach * (1.0 + 1e-12)
    final = (n, 1 if side else 0)
    return out, final != last, final[0], final[1]


def _no_acceleration_limit(request: StapRequest) -> bool:
    return request.max_acceleration is None and request.max_torque_nm is None


def _fixed_time_design(request: StapRequest, velocity: float, frequency_hz: float, t_a: float) -> StapDesign:
    """The design at the caller's t_a (``request.acceleration_time_s``)."""
    if t_a < 1.0 / frequency_hz * (1.0 - 1e-12):
        raise Infeasible(
            f"acceleration_time_s = {t_a:.6g} s is below 1/f_n,e = {1 / frequency_hz:.6g} s: no STAP reaches the velocity "
            "without residual vibration in less than one period of the mode (eq. 72)",
            field="acceleration_time_s",
        )
    a_one, _ = acceleration_limit(request, 1.0)
    a_best = request.max_acceleration
    if request.max_torque_nm is not None:
        plant = torque_plant(request)
        nodal = nodal_acceleration_limit(request.max_torque_nm, plant.motor_inertia_kgm2, plant.load_inertia_kgm2)
        a_best = nodal if a_best is None else min(a_best, nodal)
    if a_best is not None and t_a < velocity / a_best * (1.0 - 1e-12):
        raise Infeasible(
            f"acceleration_time_s = {t_a:.6g} s is below t_a,min = v/a_Max = {velocity / a_best:.6g} s (eqs. 21-22): "
            f"the acceleration limit {a_best:.6g} cannot reach the velocity {velocity:.6g} in that time",
            field="acceleration_time_s",
        )
    candidates, truncated, k_max, delta_f = zero_vibration_candidates(request, velocity, frequency_hz, t_a)
    r = frequency_hz * t_a
    notes: list[str] = []
    steps: list[AutoStep] = []
    if request.jerk_periods is not None:
        k, delta = request.jerk_periods, request.delta
        t_j = zero_vibration_jerk_time(frequency_hz, k, delta, t_a)
        if t_j > 0.5 * t_a * (1.0 + 1e-12):
            raise Infeasible(
                f"(k_j, delta) = ({k}, {delta}) gives t_j = {t_j:.6g} s (eq. 49), above t_a/2 = {0.5 * t_a:.6g} s (eq. 9): "
                f"lower jerk_periods or lengthen acceleration_time_s to at least {2 * t_j:.6g} s",
                field="jerk_periods",
            )
        a_max, _ = acceleration_limit(request, frequency_hz * t_j)
        peak = velocity / (t_a - t_j)
        if a_max is not None and peak > a_max * (1.0 + LIMIT_RTOL):
            raise Infeasible(
                f"(k_j, delta) = ({k}, {delta}) gives t_j = {t_j:.6g} s and a peak acceleration v/(t_a - t_j) = {peak:.9g} "
                f"(eq. 11) above a_Max = {a_max:.9g} (eq. 20): t_j must not exceed t_a - t_a,min = "
                f"{t_a - velocity / a_max:.6g} s (eq. 27); lengthen acceleration_time_s to at least "
                f"{velocity / a_max + t_j:.6g} s or lower jerk_periods",
                field="jerk_periods",
            )
        rule = "eq. 49: caller-fixed t_a, t_j = (k_j + delta dec(f_n,e t_a))/f_n,e"
    else:
        plain = [c for c in candidates if c.delta == 0]
        if plain:
            worst = [
                band_worst(Stap(velocity, t_a, c.jerk_time_s), frequency_hz, request.frequency_uncertainty)
                for c in plain
            ]
            for c, w in zip(plain, worst, strict=True):
                steps.append(
                    AutoStep(f"k_j = {c.k_j} at the given t_a", t_a, c.jerk_time_s, w, w <= request.residual_tolerance)
                )
            best = plain[int(np.argmin(worst))]
            k, delta, t_j = best.k_j, 0, best.jerk_time_s
            rule = "auto (caller-fixed t_a): the delta = 0 zero (eq. 49) with the lowest SC over the band"
        else:
            side = [c for c in candidates if c.k_j == 0 and c.delta == 1]
            if not side:
                needed = 1.0 / frequency_hz + (velocity / a_one if a_one else 0.0)
                raise Infeasible(
                    f"no zero-vibration jerk time fits acceleration_time_s = {t_a:.6g} s within the limits: the fundamental "
                    f"t_j = 1/f_n,e = {1 / frequency_hz:.6g} s needs t_a >= {max(needed, 2 / frequency_hz):.6g} s "
                    "(eqs. 61, 66) and the side band dec(f_n,e t_a)/f_n,e (Appendix C) does not fit either",
                    field="acceleration_time_s",
                )
            k, delta, t_j = 0, 1, side[0].jerk_time_s
            rule = "auto (caller-fixed t_a): only the side band (0, 1) fits (Appendix C, eq. A13)"
            notes.append(
                "only the side-band jerk time dec(f_n,e t_a)/f_n,e fits this acceleration time: zero residual at f_n,e "
                "but a poor sensitivity curve (Sec. 3, Fig. 17); lengthen acceleration_time_s for k_j = 1"
            )
    a_max, torque = acceleration_limit(request, frequency_hz * t_j)
    stap = Stap(velocity, t_a, t_j)
    t_hat_max = 0.5 if a_max is None else min(0.5, 1.0 - velocity / (a_max * t_a))
    if delta == 1:
        notes.append(
            "side-band jerk time (delta = 1): zero residual at f_n,e, but the load acceleration oscillates during t_c "
            f"(eq. 57: {float(load_acceleration_oscillation(1.0, frequency_hz * stap.jerk_time_s)):.3g} of a_max) and the "
            "sensitivity curve is poor (Sec. 3, Fig. 17)"
        )
    return StapDesign(
        stap=stap,
        estimated_frequency_hz=frequency_hz,
        k_j=k,
        delta=delta,
        rule=rule,
        acceleration_limit=a_max,
        min_acceleration_time_s=None if a_max is None else min_acceleration_time(velocity, a_max),
        limit_reached=a_max is not None and abs(abs(stap.peak_acceleration) - a_max) <= LIMIT_RTOL * a_max,
        torque=torque,
        candidates=tuple(candidates),
        candidates_truncated=truncated,
        k_j_max=k_max,
        delta_f=delta_f,
        paper_k_j_max=paper_k_j_max(t_hat_max, r),
        paper_delta_f=paper_delta_f(t_hat_max, r),
        auto_steps=tuple(steps),
        band_worst_residual=band_worst(stap, frequency_hz, request.frequency_uncertainty),
        frequency_uncertainty=request.frequency_uncertainty,
        notes=tuple(notes),
        fixed_acceleration_time=True,
        keeps_acceleration_time=True,
    )


def _auto_design(request: StapRequest, velocity: float, frequency_hz: float) -> StapDesign:
    tol, u = request.residual_tolerance, request.frequency_uncertainty
    first = _periods_rule(request, velocity, frequency_hz, 1)
    tried: list[StapDesign] = [first]
    steps = [
        AutoStep(
            "k_j = 1 (eq. 50)",
            first.stap.acceleration_time_s,
            first.stap.jerk_time_s,
            first.band_worst_residual,
            first.band_worst_residual <= tol,
        )
    ]
    whole = frequency_hz * (first.min_acceleration_time_s or 0.0)
    chosen: StapDesign | None = first if first.band_worst_residual <= tol else None
    if chosen is None and whole >= 1.0 - 1e-12:
        second = _periods_rule(request, velocity, frequency_hz, 2)
        if frequency_hz * (second.min_acceleration_time_s or 0.0) >= 2.0 - 1e-12:  # eq. 63 for k_j = 2
            tried.append(second)
            meets = second.band_worst_residual <= tol
            steps.append(
                AutoStep(
                    "k_j = 2 (eqs. 63, 75)",
                    second.stap.acceleration_time_s,
                    second.stap.jerk_time_s,
                    second.band_worst_residual,
                    meets,
                )
            )
            chosen = second if meets else None
    elif chosen is None:
        a_max = first.acceleration_limit
        for n in range(3, AUTO_MAX_PERIODS + 1):  # lengthen t_a to whole periods (eq. 76)
            t_a = n / frequency_hz
            _check_duration(t_a, "residual_tolerance")
            stap = Stap(velocity, t_a, 1.0 / frequency_hz)
            worst = band_worst(stap, frequency_hz, u)
            design = replace(
                first,
                stap=stap,
                rule=f"auto: t_a = {n}/f_n,e with k_j = 1 (f_n,e t_a,min < 1, eq. 76; whole f_n,e t_a)",
                limit_reached=a_max is not None and abs(abs(stap.peak_acceleration) - a_max) <= LIMIT_RTOL * a_max,
                band_worst_residual=worst,
                keeps_acceleration_time=True,
            )
            tried.append(design)
            steps.append(AutoStep(f"t_a = {n}/f_n,e, k_j = 1 (eq. 76)", t_a, stap.jerk_time_s, worst, worst <= tol))
            if worst <= tol:
                chosen = design
                break
    notes: list[str] = []
    if chosen is None:
        chosen = min(tried, key=lambda d: d.band_worst_residual)
        notes.append(
            f"no design of the auto rule keeps the undamped SC below residual_tolerance = {tol:.3g} over "
            f"f_n/f_n,e in [{1 - u:.3g}, {1 + u:.3g}]; the one with the lowest worst case ({chosen.band_worst_residual:.3g}) "
            "is returned (try method 'optimized' with objective 'worst_case', or a longer acceleration_time_s)"
        )
    rule = chosen.rule if chosen.rule.startswith("auto") else f"auto (Fig. 25): {chosen.rule}"
    return replace(chosen, rule=rule, auto_steps=tuple(steps), notes=chosen.notes + tuple(notes))


def _rest_to_velocity(request: StapRequest, speed: float) -> StapDesign:
    """The closed-form ramp to ``speed`` (> 0), unsigned."""
    mode = estimated_mode(request.plant)
    f = mode.natural_frequency_hz
    if request.acceleration_time_s is not None:
        return _fixed_time_design(request, speed, f, float(request.acceleration_time_s))
    if request.delta == 1:
        raise InvalidParameter(
            "delta",
            1,
            "a side-band jerk time (delta = 1) depends on t_a (eq. 49): give acceleration_time_s (Appendix C)",
        )
    if _no_acceleration_limit(request):
        raise no_acceleration_limit_error()
    if request.jerk_periods is None:
        return _auto_design(request, speed, f)
    return _periods_rule(request, speed, f, request.jerk_periods)


def _signed(design: StapDesign, sign: float) -> StapDesign:
    if sign > 0:
        return design
    s = design.stap
    return replace(design, stap=Stap(-s.velocity, s.acceleration_time_s, s.jerk_time_s))


def _fixed_rule(request: StapRequest, design: StapDesign) -> StapRequest:
    """The request that reproduces ``design``'s rule at another speed (same k_j, or same t_a and t_j)."""
    if design.keeps_acceleration_time:
        return replace(
            request,
            acceleration_time_s=design.stap.acceleration_time_s,
            jerk_periods=design.k_j,
            delta=design.delta or 0,
        )
    return replace(request, jerk_periods=design.k_j, delta=0)


def _fitting_speed(request: StapRequest, design: StapDesign, distance: float) -> float:
    """The largest speed whose two ramps (same rule) fit in ``distance`` with no cruise."""
    t_j, t_a = abs(design.stap.jerk_time_s), design.stap.acceleration_time_s
    if design.keeps_acceleration_time:
        return distance / t_a
    a_max = design.acceleration_limit
    if a_max is None:
        raise no_acceleration_limit_error()
    if distance >= 2.0 * a_max * t_j * t_j:  # eq. 61 regime: D = v^2/a + v t_j
        return 2.0 * distance / (t_j + math.sqrt(t_j * t_j + 4.0 * distance / a_max))
    return distance / (2.0 * t_j)  # triangle: D = 2 v t_j


def closed_form(request: StapRequest) -> StapDesign:
    """The closed-form design of a request (rest-to-velocity, or rest-to-rest with a displacement)."""
    if request.displacement is None:
        if request.target_velocity is None:
            raise InvalidParameter(
                "target_velocity", None, "give target_velocity (rest-to-velocity) or displacement (rest-to-rest)"
            )
        v = float(request.target_velocity)
        return _signed(_rest_to_velocity(request, abs(v)), math.copysign(1.0, v))
    distance = abs(request.displacement)
    sign = math.copysign(1.0, request.displacement)
    requested = None if request.target_velocity is None else abs(request.target_velocity)
    notes: list[str] = []
    if requested is not None:
        ramp = _rest_to_velocity(request, requested)
        if requested * ramp.stap.acceleration_time_s <= distance * (1.0 + 1e-12):
            cruise = max(0.0, distance / requested - ramp.stap.acceleration_time_s)
            if cruise > MAX_TIME_S:
                raise InvalidParameter(
                    "target_velocity",
                    request.target_velocity,
                    f"the move of {distance:.6g} would cruise for {cruise:.6g} s at this speed, beyond the {MAX_TIME_S:g} s "
                    "this service handles",
                )
            return replace(
                _signed(ramp, sign), move=RestToRest(_signed(ramp, sign).stap, cruise), requested_velocity=requested
            )
    else:
        # Auto decides at the speed the fastest k_j = 1 move reaches; a fixed rule needs no probe.
        auto = request.jerk_periods is None and request.acceleration_time_s is None
        probe_request = replace(request, jerk_periods=1) if auto else request
        probe = _rest_to_velocity(probe_request, _probe_speed(probe_request, distance))
        ramp = _rest_to_velocity(request, _fitting_speed(probe_request, probe, distance)) if auto else probe
    fixed = _fixed_rule(request, ramp)
    speed = _fitting_speed(fixed, ramp, distance)
    if requested is not None:
        speed = min(speed, requested)
    final = _rest_to_velocity(fixed, speed)
    # Round-off can leave v t_a a hair above D: the cruise is clipped at zero.
    cruise = max(0.0, distance / speed - final.stap.acceleration_time_s)
    if requested is not None:
        notes.append(
            f"the displacement {distance:.6g} is too short to cruise at {requested:.6g} with these ramps "
            f"(they need {requested * ramp.stap.acceleration_time_s:.6g}): the cruise speed is lowered to {speed:.6g}, "
            "with no cruise phase"
        )
    else:
        notes.append(
            f"no target_velocity: the fastest move with these ramps, cruise speed {speed:.6g} and no cruise phase"
        )
    signed = _signed(final, sign)
    return replace(
        signed,
        move=RestToRest(signed.stap, cruise),
        requested_velocity=requested,
        velocity_lowered=requested is not None,
        auto_steps=ramp.auto_steps if request.jerk_periods is None else final.auto_steps,
        rule=ramp.rule,
        move_notes=tuple(notes),
    )


def _probe_speed(request: StapRequest, distance: float) -> float:
    """A speed at which to evaluate a rule before the fitting speed is known: any positive value
    works for the fitting formulas (they use only the rule's t_j, t_a and a_Max)."""
    if request.acceleration_time_s is not None:
        return distance / request.acceleration_time_s
    return 1.0


def check_request(request: StapRequest) -> StapRequest:
    """Refuse what no design can mean (the HTTP schema catches most of it first)."""
    v, d = request.target_velocity, request.displacement
    if d is None and v is None:
        raise InvalidParameter(
            "target_velocity", None, "give target_velocity (rest-to-velocity) or displacement (rest-to-rest)"
        )
    for name, value in (("target_velocity", v), ("displacement", d)):
        if value is not None and not (math.isfinite(value) and value != 0.0 and abs(value) <= 1e9):
            raise InvalidParameter(name, value, "must be finite, non-zero and within +-1e9")
    if d is not None and v is not None and math.copysign(1.0, v) != math.copysign(1.0, d):
        raise InvalidParameter(
            "target_velocity", v, "with a displacement it is the cruise speed: give it the displacement's sign"
        )
    if request.max_torque_nm is not None:
        torque_plant(request)
    if request.jerk_periods is not None and request.jerk_periods < 0:
        raise InvalidParameter("jerk_periods", request.jerk_periods, "must be a whole number >= 0, or 'auto'")
    if request.delta not in (0, 1):
        raise InvalidParameter("delta", request.delta, "must be 0 or 1 (eq. 44)")
    if request.jerk_periods == 0 and request.delta == 0:
        raise InvalidParameter(
            "jerk_periods", 0, "(k_j, delta) = (0, 0) is not a zero of eq. (44): k_j = 0 needs delta = 1"
        )
    if request.delta == 1 and request.jerk_periods is None:
        raise InvalidParameter("delta", 1, "a side band (delta = 1) needs a whole jerk_periods, not 'auto'")
    if not 0.0 <= request.frequency_uncertainty <= 0.9:
        raise InvalidParameter("frequency_uncertainty", request.frequency_uncertainty, "must lie in [0, 0.9]")
    if not 0.0 < request.residual_tolerance <= 1.0:
        raise InvalidParameter("residual_tolerance", request.residual_tolerance, "must lie in (0, 1]")
    if request.acceleration_time_s is not None and not (0.0 < request.acceleration_time_s <= MAX_TIME_S):
        raise InvalidParameter("acceleration_time_s", request.acceleration_time_s, f"must lie in (0, {MAX_TIME_S:g}] s")
    if request.objective not in OBJECTIVES:
        raise InvalidParameter("optimization.objective", request.objective, f"must be one of {', '.join(OBJECTIVES)}")
    if not 3 <= request.frequency_points <= MAX_FREQUENCY_POINTS:
        raise InvalidParameter(
            "optimization.frequency_points", request.frequency_points, f"must lie in 3..{MAX_FREQUENCY_POINTS}"
        )
    zetas = request.band_damping_ratios
    if zetas is not None:
        if not 1 <= len(zetas) <= MAX_BAND_DAMPING_RATIOS:
            raise InvalidParameter(
                "optimization.damping_ratios", list(zetas), f"give 1 to {MAX_BAND_DAMPING_RATIOS} damping ratios"
            )
        for i, z in enumerate(zetas):
            if not (math.isfinite(z) and 0.0 <= z < 1.0):
                raise InvalidParameter(f"optimization.damping_ratios[{i}]", z, "must satisfy 0 <= zeta < 1")
    estimated_mode(request.plant)
    return request


def design(request: StapRequest) -> StapDesign:
    """The closed-form design (in-process: no solver)."""
    return closed_form(check_request(request))


# ------------------------------------------------------------------------------------------
# The CasADi formulation, built once per shape


@dataclass
class _Compiled:
    solver: Any
    evaluate: Any  # Function (x, p) -> (f, g, residual squares per point)
    lbg: np.ndarray
    ubg: np.ndarray
    layout: dict[str, slice]
    parameter_count: int
    variables: int


_CACHE: dict[tuple, _Compiled] = {}


def _build(kind: str, points: int, torque_modes: int, torque_grid: int, caps: SolveCaps) -> _Compiled:
    import casadi as ca

    # One point: (residual / move)^2 = pre j^2 |exp(lambda (t_a - t_j)) - 1|^2 |exp(lambda t_j) - 1|^2.
    x2 = ca.SX.sym("x2", 2)  # t_a (s), t^_j
    v = ca.SX.sym("v")
    pt = ca.SX.sym("pt", 3)  # pre, Re(lambda), Im(lambda)
    t_a, t_hat = x2[0], x2[1]
    t_j = t_hat * t_a
    t_r = t_a - t_j
    jerk = v / (t_j * t_r)  # eq. (16)

    def gap2(sigma: Any, omega: Any, t: Any) -> Any:
        """|exp((sigma + i omega) t) - 1|^2 without cancellation."""
        es = ca.exp(sigma * t)
        return (1.0 - es) ** 2 + 4.0 * es * ca.sin(0.5 * omega * t) ** 2

    point = ca.Function("point", [x2, v, pt], [pt[0] * jerk**2 * gap2(pt[1], pt[2], t_r) * gap2(pt[1], pt[2], t_j)])

    names = [("ta0", 1), ("v", 1), ("inv_a", 1), ("pts", 3 * points), ("tq", 4 * torque_modes), ("jj", 3)]
    layout, start = parameter_layout(names)
    p = ca.MX.sym("p", start)
    n_x = 3 if kind == "max" else 2
    x = ca.MX.sym("x", n_x)
    ta0, speed, inv_a = p[layout["ta0"]], p[layout["v"]], p[layout["inv_a"]]
    ta = x[0] * ta0
    xs = ca.vertcat(ta, x[1])
    pts = ca.reshape(p[layout["pts"]], 3, points)
    squares = point.map(points)(xs, speed, pts)  # 1 x points
    g = [(speed * inv_a - ta * (1.0 - x[1])) / ta0]  # v <= a_Max (t_a - t_j), eqs. 11 and 20
    lbg, ubg = [-np.inf], [0.0]
    if kind == "sum":
        f = ca.sum2(squares)
    elif kind == "max":
        f = x[2]
        g.append(ca.transpose(squares) - x[2])
        lbg += [-np.inf] * points
        ubg += [0.0] * points
    else:  # time: the squares are normalised by the tolerance
        f = x[0]
        g.append(ca.transpose(squares) - 1.0)
        lbg += [-np.inf] * points
        ubg += [0.0] * points
    if torque_modes:
        s = ca.SX.sym("s")
        mode = ca.SX.sym("mode", 4)  # Re(lambda), Im(lambda), Re(q), Im(q) with q = 2 r / lambda^2
        jj = ca.SX.sym("jj", 3)  # J_M + J_L, J_L, 1 / M
        tau = s * t_a

        def ramp(t: Any) -> Any:
            return ca.fmax(t, 0.0)

        a_m = jerk * (ramp(tau) - ramp(tau - t_j) - ramp(tau - t_r))
        s_re, s_im = 0, 0
        for sign, t_k in ((1.0, 0.0), (-1.0, t_j), (-1.0, t_r), (1.0, t_a)):  # the four jerk jumps
            age = ca.fmax(tau - t_k, 0.0)
            on = ca.if_else(tau - t_k >= 0.0, sign, 0.0)
            decay = ca.exp(mode[0] * age)
            s_re += on * decay * ca.cos(mode[1] * age)
            s_im += on * decay * ca.sin(mode[1] * age)
        torque = (jj[0] * a_m + jj[1] * jerk * (mode[2] * s_re - mode[3] * s_im)) * jj[2]
        torque_at = ca.Function("torque", [x2, v, s, mode, jj], [torque])
        envelope2 = (
            (jj[1] * jerk * jj[2]) ** 2
            * (mode[2] ** 2 + mode[3] ** 2)
            * gap2(mode[0], mode[1], t_r)
            * gap2(mode[0], mode[1], t_j)
        )
        after = ca.Function("after", [x2, v, mode, jj], [envelope2])
        grid = ca.DM(np.linspace(0.0, 1.0, torque_grid)).T
        modes = ca.reshape(p[layout["tq"]], 4, torque_modes)
        jj_p = p[layout["jj"]]
        mapped = torque_at.map(torque_grid)
        for m in range(torque_modes):  # a loop over a few modes, not samples
            g.append(ca.transpose(mapped(xs, speed, grid, modes[:, m], jj_p)))
            lbg += [-(1.0 - TORQUE_MARGIN)] * torque_grid
            ubg += [1.0 - TORQUE_MARGIN] * torque_grid
        g.append(ca.transpose(after.map(torque_modes)(xs, speed, modes, jj_p)))
        lbg += [-np.inf] * torque_modes
        ubg += [(1.0 - TORQUE_MARGIN) ** 2] * torque_modes
    g_all = ca.vertcat(*g)
    nlp = {"x": x, "p": p, "f": f, "g": g_all}
    solver = ca.nlpsol("stap", "ipopt", nlp, ipopt_options(caps, **OPTIONS))
    evaluate = ca.Function("evaluate", [x, p], [f, g_all, squares])
    return _Compiled(solver, evaluate, np.array(lbg), np.array(ubg), layout, start, n_x)


def _compiled(kind: str, points: int, torque_modes: int, torque_grid: int, caps: SolveCaps) -> _Compiled:
    key = (kind, points, torque_modes, torque_grid, caps)
    if key not in _CACHE:
        _CACHE[key] = _build(kind, points, torque_modes, torque_grid, caps)
    return _CACHE[key]


def warm_up(caps: SolveCaps | None = None) -> None:
    """Build the common problems in a new worker: the nominal residual of a one-mode plant and the
    worst case over the default band (21 frequencies, one damping ratio), without torque limit."""
    caps = caps or SolveCaps()
    _compiled("sum", 1, 0, 0, caps)
    _compiled("max", 21, 0, 0, caps)


# ------------------------------------------------------------------------------------------
# Solving


def _oscillatory(plant: Plant) -> ModalForm:
    num, den = plant.load_transfer_function()
    modal = modal_form(num, den, 1)
    keep = modal.oscillatory
    return ModalForm(modal.taylor, modal.poles[keep], modal.residues[keep], modal.weights[keep])


def _mode_form(omega: np.ndarray, zeta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Upper poles and residues of (2 zeta w s + w^2)/(s^2 + 2 zeta w s + w^2) (as models.sensitivity)."""
    poles = omega * (-zeta + 1j * np.sqrt(1.0 - zeta * zeta))
    return poles, (2 * zeta * omega * poles + omega * omega) / (2 * poles + 2 * zeta * omega)


@dataclass(frozen=True)
class _Points:
    poles: np.ndarray
    factor: np.ndarray  # |residual / move| = factor * |h(t_a)|, h the ramp's free state (models.stap)


def _points(poles: np.ndarray, residues: np.ndarray, speed: float, distance: float | None) -> _Points:
    """Each pole's factor: |2 r lambda^m (exp(lambda D/v) - 1)| / move, m = 1 for
    rest-to-velocity (the velocity residual over v), 0 for rest-to-rest (position over D)."""
    if distance is None:
        factor = np.abs(2.0 * residues * poles) / speed
    else:
        factor = np.abs(2.0 * residues * np.expm1(poles * distance / speed)) / distance
    return _Points(poles, factor)


def _amplitudes(points: _Points, speed: float, t_a: float, t_j: float) -> np.ndarray:
    """|residual / move| at each point for the STAP (t_a, t_j) (models.stap.Stap.free_state)."""
    return points.factor * np.abs(Stap(speed, t_a, t_j).free_state(points.poles))


def _band(request: StapRequest, mode: Mode) -> tuple[np.ndarray, np.ndarray] | None:
    """The (poles, residues) of the robust grid (mode form, f_n/f_n,e x damping ratios), or None when
    it is the plant's own mode (u = 0 and no damping ratios given)."""
    u = request.frequency_uncertainty
    if u <= 0.0 and request.band_damping_ratios is None:
        return None
    ratios = np.linspace(1.0 - u, 1.0 + u, request.frequency_points) if u > 0.0 else np.array([1.0])
    zetas = np.asarray(request.band_damping_ratios or (mode.damping_ratio,), dtype=float)
    rho, zeta = np.meshgrid(ratios, zetas)
    return _mode_form(mode.natural_frequency_rad_s * rho.ravel(), zeta.ravel())


def _torque_grid(periods: float) -> int:
    for size in TORQUE_GRID_SIZES:
        if size >= TORQUE_POINTS_PER_PERIOD * periods + 16:
            return size
    raise InvalidParameter(
        "method",
        "optimized",
        f"with max_torque_nm the optimiser checks the torque at {TORQUE_POINTS_PER_PERIOD} points per period; t_a may span "
        f"{periods:.0f} periods, more than the {(TORQUE_GRID_SIZES[-1] - 16) / TORQUE_POINTS_PER_PERIOD:.0f} it supports "
        "(use method 'closed_form', whose torque rule is eqs. 57-59)",
    )


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

    modal = _oscillatory(plant)
    nominal = _points(modal.poles, modal.residues, speed, distance)
    band = _band(request, mode)
    grid = None if band is None else _points(band[0], band[1], speed, distance)
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
            poles_b, res_b = _mode_form(mode.natural_frequency_rad_s * ratios, own)
            torque_modes += list(zip(poles_b, res_b, strict=True))
        jj = np.array(
            [two.motor_inertia_kgm2 + two.load_inertia_kgm2, two.load_inertia_kgm2, 1.0 / request.max_torque_nm]
        )
    top_hz = max((abs(p) / (2 * math.pi) for p, _ in torque_modes), default=0.0)
    torque_grid = _torque_grid(top_hz * ta_hi) if torque_modes else 0
    compiled = _compiled(kind, used.poles.size, len(torque_modes), torque_grid, request.caps)

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

    def x_of(t_a: float, t_j: float, z: float = 1.0) -> np.ndarray:
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

    def breach(xs: np.ndarray) -> tuple[float, float]:
        fx, gx, _ = (np.asarray(a).ravel() for a in compiled.evaluate(xs, p))
        return float(fx[0]), float(np.max(np.concatenate([compiled.lbg - gx, gx - compiled.ubg])))

    # The closed-form design competes too: an interior-point run may leave its basin and stop at
    # a worse local optimum, and the answer must never be worse than the start.
    x_start = x_of(t_a0, s0.jerk_time_s)
    if compiled.variables == 3:
        x_start[2] = float(np.max(np.asarray(compiled.evaluate(x_start, p)[2]).ravel()))
    f_start, breach_start = breach(x_start)
    best: tuple[float, np.ndarray] | None = (f_start, x_start) if breach_start <= FEASIBLE else None
    improved = False
    iterations, elapsed, solves = 0, 0.0, 0
    last: SolverReport | None = None
    converged_any, converged_status = False, ""
    for t_a_s, t_j_s in starts:  # a handful of starts
        if elapsed > 2.0 * request.caps.max_wall_time_s:
            break
        x0 = x_of(t_a_s, t_j_s)
        if compiled.variables == 3:
            _, _, sq = (np.asarray(a).ravel() for a in compiled.evaluate(x0, p))
            x0[2] = float(np.max(sq))
        started = time.perf_counter()
        solution = compiled.solver(x0=np.clip(x0, lbx, ubx), p=p, lbx=lbx, ubx=ubx, lbg=compiled.lbg, ubg=compiled.ubg)
        report = report_of(compiled.solver, time.perf_counter() - started)
        iterations, elapsed, solves = iterations + report.iterations, elapsed + report.solve_time_s, solves + 1
        last = report
        if report.timed_out:
            break
        if not report.converged:
            continue
        converged_any, converged_status = True, report.status
        xs = np.clip(np.asarray(solution["x"]).ravel(), lbx, ubx)
        fx, worst = breach(xs)
        if worst > FEASIBLE:
            continue
        if best is None or fx < best[0] * (1.0 - 1e-9):
            best, improved = (fx, xs), True
    if last is None:  # no start with t_j > 0 (the closed form is the rectangle): nothing was solved
        raise NotApplicable(
            "method 'optimized' starts from designs with a jerk time t_j > 0: the closed-form design is the rectangle "
            f"(t_j = 0) and no other zero-vibration design fits t_a in [{ta_lo:.6g}, {ta_hi:.6g}] s within the limits; "
            "use method 'closed_form' or lengthen acceleration_time_s",
            field="method",
        )
    if best is None or not (improved or converged_any):
        if last.timed_out or not converged_any:
            raise_for_status(SolverReport(last.status, iterations, elapsed))
        raise Infeasible(
            "no STAP found that meets the limits"
            + (f" with a residual below {request.residual_tolerance:.3g} over the band" if kind == "time" else "")
            + f" for t_a in [{ta_lo:.6g}, {ta_hi:.6g}] s; raise the limits or the tolerance, or use method 'closed_form'",
            field="max_torque_nm" if request.max_torque_nm is not None else "residual_tolerance",
        )
    xs = best[1]
    t_a = float(xs[0] * t_a0)
    t_hat = float(xs[1])
    if request.max_acceleration is not None:  # project onto v <= a_Max (t_a - t_j) exactly
        if ta_lo == ta_hi:
            t_hat = max(min(t_hat, 1.0 - speed / (request.max_acceleration * t_a)), 0.0)
        else:
            t_a = max(t_a, speed / (request.max_acceleration * (1.0 - t_hat)))
    t_j = t_hat * t_a
    stap = Stap(math.copysign(speed, s0.velocity), t_a, t_j)
    move = None
    if distance is not None:
        move = RestToRest(stap, max(0.0, distance / speed - t_a))
    return OptimizedDesign(
        stap=stap,
        objective=request.objective,
        start=s0,
        nominal_residual=float(np.sum(_amplitudes(nominal, speed, t_a, stap.jerk_time_s))),
        start_nominal_residual=float(np.sum(_amplitudes(nominal, speed, t_a0, s0.jerk_time_s))),
        grid_worst_residual=None if grid is None else float(np.max(_amplitudes(grid, speed, t_a, stap.jerk_time_s))),
        start_grid_worst_residual=None
        if grid is None
        else float(np.max(_amplitudes(grid, speed, t_a0, s0.jerk_time_s))),
        solver=SolverReport(converged_status, iterations, elapsed),
        solves=solves,
        selection="optimized" if improved else "closed_form_kept",
        acceleration_time_bounds_s=(ta_lo, ta_hi),
        jerk_time_floor_s=t_hat_lo * ta_lo,
        move=move,
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
                    _periods_rule(replace(request, jerk_periods=k), abs(s0.velocity), f_e, k)
                    if not _no_acceleration_limit(request)
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
