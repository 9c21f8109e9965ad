"""The closed-form design of a request: rest-to-velocity, or rest-to-rest (beyond Cusimano 2022).

``check_request`` refuses what no design can mean (the HTTP schema catches most of it first);
``closed_form`` signs the ramp of ``optim.families.stap.ramp`` (Secs. 2-4) or builds the move. Rest-to-rest:
each ramp is the rest-to-velocity design at the cruise speed. When the displacement D is too short
for the requested speed (v t_a > D), the speed is lowered to the largest one whose ramps fit with no
cruise, with the same rule (the same k_j, or the same t_a and t_j): v = 2 D / (t_j + sqrt(t_j^2 +
4 D / a_Max)) for eq. (61), D / (2 t_j) for the triangle, D / t_a for a fixed t_a. Without a
requested speed the move is the fastest one: no cruise.
"""

from __future__ import annotations

import math
from dataclasses import replace

from models.errors import InvalidParameter
from models.stap import MAX_TIME_S, RestToRest, Stap
from optim.families.stap.limits import estimated_mode, no_acceleration_limit_error, torque_plant
from optim.families.stap.ramp import rest_to_velocity
from optim.families.stap.torque import lower_acceleration
from optim.families.stap.types import (
    MAX_BAND_DAMPING_RATIOS,
    MAX_FREQUENCY_POINTS,
    OBJECTIVES,
    StapDesign,
    StapRequest,
)


def _signed(design: StapDesign, sign: float) -> StapDesign:
    """The design with its ramp's velocity given ``sign``."""
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
        return _signed(rest_to_velocity(request, abs(v)), math.copysign(1.0, v))
    distance = abs(request.displacement)
    sign = math.copysign(1.0, request.displacement)
    requested = None if request.target_velocity is None else abs(request.target_velocity)
    notes: list[str] = []
    if requested is not None:
        ramp = rest_to_velocity(request, requested)
        if requested * ramp.stap.acceleration_time_s <= distance * (1.0 + 1e-12):
            cruise = max(0.0, distance / requested - ramp.stap.acceleration_time_s)
            if cruise > MAX_TIME_S:
                raise InvalidParameter(
                    "target_velocity",
                    request.target_velocity,
                    f"the move of {distance:.6g} would cruise for {cruise:.6g} s at this speed, "
                    f"beyond the {MAX_TIME_S:g} s this service handles",
                )
            return replace(
                _signed(ramp, sign), move=RestToRest(_signed(ramp, sign).stap, cruise), requested_velocity=requested
            )
    else:
        # Auto decides at the speed the fastest k_j = 1 move reaches; a fixed rule needs no probe.
        auto = request.jerk_periods is None and request.acceleration_time_s is None
        probe_request = replace(request, jerk_periods=1) if auto else request
        probe = rest_to_velocity(probe_request, _probe_speed(probe_request, distance))
        ramp = rest_to_velocity(request, _fitting_speed(probe_request, probe, distance)) if auto else probe
    fixed = _fixed_rule(request, ramp)
    speed = _fitting_speed(fixed, ramp, distance)
    if requested is not None:
        speed = min(speed, requested)
    final = rest_to_velocity(fixed, speed)
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
    """The closed-form design (in-process: no solver), its acceleration lowered where the real motor
    torque would break max_torque_nm (``optim.families.stap.torque``)."""
    request = check_request(request)
    return lower_acceleration(request, closed_form(request), closed_form)
