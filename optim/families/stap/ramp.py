"""Closed-form STAP ramps at one speed and the Fig. 25 flowchart (Cusimano 2022, Secs. 2-4).

In-process, no solver. v is the target speed, a_Max the limit of ``optim.families.stap.limits``.

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
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from models.errors import Infeasible, InvalidParameter
from models.stap import MAX_TIME_S, Stap, load_acceleration_oscillation
from models.stap_design import (
    decimal_part,
    max_jerk_time,
    min_acceleration_time,
    nodal_acceleration_limit,
    paper_delta_f,
    paper_k_j_max,
    zero_vibration_jerk_time,
)
from optim.families.stap.limits import (
    LIMIT_RTOL,
    acceleration_limit,
    band_worst,
    estimated_mode,
    has_no_acceleration_limit,
    no_acceleration_limit_error,
    torque_plant,
)
from optim.families.stap.types import AutoStep, StapDesign, StapRequest, ZeroVibrationCandidate

AUTO_MAX_PERIODS = 10  # the longest f_n,e t_a auto tries in the triangle case (Figs. 11-13)
MAX_LISTED_CANDIDATES = 64  # zero-vibration jerk times listed (and considered by auto) at a fixed t_a


def periods_rule(request: StapRequest, velocity: float, frequency_hz: float, k_j: int) -> StapDesign:
    """t_j = k_j / f_n,e with t_a from eq. (61) or (66)."""
    t_j = zero_vibration_jerk_time(frequency_hz, k_j)
    a_max, torque = acceleration_limit(request, float(k_j))
    if a_max is None:
        raise no_acceleration_limit_error()
    t_a_min = min_acceleration_time(velocity, a_max)
    if t_j <= t_a_min * (1.0 + 1e-12):
        t_a, rule = t_a_min + t_j, "eq. 61: t_a = t_a,min + k_j/f_n,e (k_j/f_n,e <= t_a,min, eq. 60)"
        check_duration(t_a, "max_acceleration" if request.max_acceleration is not None else "max_torque_nm")
    else:
        t_a, rule = 2.0 * t_j, "eq. 66: triangle t_a = 2 k_j/f_n,e (k_j/f_n,e > t_a,min, eq. 65), peak by eq. 31"
        check_duration(t_a, "jerk_periods")
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


def check_duration(t: float, field_name: str) -> None:
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
                f"t_a,min <= t_a < t_a,min + 1/f_n,e (A21: {t_a_min:.9g} <= {t_a:.9g} "
                f"< {t_a_min + 1 / frequency_hz:.9g})"
            )
        elif t_a_min is not None:
            note += "; it does not reach a_Max: the peak is below the limit (A22-A28)"
    return "side_band", note


def zero_vibration_candidates(
    request: StapRequest, velocity: float, frequency_hz: float, t_a: float
) -> tuple[list[ZeroVibrationCandidate], bool, int | None, int | None]:
    """The zeros of eq. (44) at a fixed t_a that meet t_j <= t_a/2 (eq. 9) and the acceleration limit
    (eqs. 20, 27), in increasing t_j; whether the list was cut at MAX_LISTED_CANDIDATES; and the last
    one's (k_j, delta) (the exact k_j,max and delta_f). When f_n,e t_a is whole the side bands
    (k_j >= 1, delta = 1) coincide with the multiples and only (0, 1), the rectangle, is listed."""
    r = frequency_hz * t_a
    dec = float(decimal_part(r))
    out: list[ZeroVibrationCandidate] = []
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
        out.append(ZeroVibrationCandidate(k, delta, t_j, kind, peak, a_max, reaches, note))
    # More zeros fit than are listed: the last one in closed form, with the last listed a_Max
    # (the torque-lowered limit changes by less than 1 % past k_j = 32).
    reach = max_jerk_time(t_a, velocity, a_max)
    n = math.floor(frequency_hz * reach * (1.0 + 1e-12))
    side = dec > 0.0 and (n + dec) / frequency_hz <= reach * (1.0 + 1e-12)
    final = (n, 1 if side else 0)
    return out, final != last, final[0], final[1]


def _fixed_time_design(request: StapRequest, velocity: float, frequency_hz: float, t_a: float) -> StapDesign:
    """The design at the caller's t_a (``request.acceleration_time_s``)."""
    if t_a < 1.0 / frequency_hz * (1.0 - 1e-12):
        raise Infeasible(
            f"acceleration_time_s = {t_a:.6g} s is below 1/f_n,e = {1 / frequency_hz:.6g} s: "
            "no STAP reaches the velocity without residual vibration in less than one period of the mode (eq. 72)",
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
                f"(k_j, delta) = ({k}, {delta}) gives t_j = {t_j:.6g} s (eq. 49), "
                f"above t_a/2 = {0.5 * t_a:.6g} s (eq. 9): "
                f"lower jerk_periods or lengthen acceleration_time_s to at least {2 * t_j:.6g} s",
                field="jerk_periods",
            )
        a_max, _ = acceleration_limit(request, frequency_hz * t_j)
        peak = velocity / (t_a - t_j)
        if a_max is not None and peak > a_max * (1.0 + LIMIT_RTOL):
            raise Infeasible(
                f"(k_j, delta) = ({k}, {delta}) gives t_j = {t_j:.6g} s "
                f"and a peak acceleration v/(t_a - t_j) = {peak:.9g} "
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
                    f"no zero-vibration jerk time fits acceleration_time_s = {t_a:.6g} s within the limits: "
                    f"the fundamental t_j = 1/f_n,e = {1 / frequency_hz:.6g} s "
                    f"needs t_a >= {max(needed, 2 / frequency_hz):.6g} s "
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
            f"(eq. 57: {float(load_acceleration_oscillation(1.0, frequency_hz * stap.jerk_time_s)):.3g} of a_max) "
            "and the sensitivity curve is poor (Sec. 3, Fig. 17)"
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
    first = periods_rule(request, velocity, frequency_hz, 1)
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
        second = periods_rule(request, velocity, frequency_hz, 2)
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
            check_duration(t_a, "residual_tolerance")
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
            f"f_n/f_n,e in [{1 - u:.3g}, {1 + u:.3g}]; "
            f"the one with the lowest worst case ({chosen.band_worst_residual:.3g}) "
            "is returned (try method 'optimized' with objective 'worst_case', or a longer acceleration_time_s)"
        )
    rule = chosen.rule if chosen.rule.startswith("auto") else f"auto (Fig. 25): {chosen.rule}"
    return replace(chosen, rule=rule, auto_steps=tuple(steps), notes=chosen.notes + tuple(notes))


def rest_to_velocity(request: StapRequest, speed: float) -> StapDesign:
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
    if has_no_acceleration_limit(request):
        raise no_acceleration_limit_error()
    if request.jerk_periods is None:
        return _auto_design(request, speed, f)
    return periods_rule(request, speed, f, request.jerk_periods)
