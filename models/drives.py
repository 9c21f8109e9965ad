"""The drive (Chatlatanagulchai & Pongpanich Fig. 5): its rate limiter, and a position-mode time-optimal follower."""

from __future__ import annotations

import math

import numpy as np

from models.breakpoints import integrated, merge_tolerance
from models.commands import PiecewiseCommand, check_time_grid
from models.errors import InvalidParameter

# ------------------------------------------------------------------------------------------
# The drive's acceleration limit (Fig. 5)


def rate_limit(command: PiecewiseCommand, acceleration_limit: float) -> PiecewiseCommand:
    """v_a: the velocity command after the drive's rate limiter |dv_a/dt| <= a (Fig. 5).

    The limiter follows v_s while |dv_s/dt| <= a and v_a = v_s; otherwise v_a moves towards v_s
    at the full rate +-a until it meets it. For a velocity that is piecewise linear (steps and
    ramps; ``command`` of degree <= 2) the output is piecewise linear too and is found exactly:
    each piece of v_s gives at most two pieces of v_a (chase, then follow), the meeting time
    solving a linear equation. The loop runs over the command's pieces (a few dozen for shaped
    steps and ramps), not over samples. The drive starts at rest; the position is integrated.
    """
    a = float(acceleration_limit)
    if not (math.isfinite(a) and a > 0.0):
        raise InvalidParameter("acceleration_limit", a, "must be a finite number > 0")
    if command.degree > 2:
        raise InvalidParameter(
            "profile", f"degree {command.degree}", "the rate limiter needs a piecewise-linear velocity"
        )
    t = command.time_s
    v = command.derivative(1)
    s = command.derivative(2)
    scale = max(float(np.max(np.abs(v))), float(np.max(np.abs(command.left_limit(1)))), 1e-300)
    tol = 1e-12 * scale
    ends = np.append(t[1:], np.inf)
    out_t: list[float] = []
    out_slope: list[float] = []
    y = 0.0  # the drive's velocity, at rest before t_0
    for k in range(t.size):  # loop over the command's pieces
        start, length, u0, su = float(t[k]), float(ends[k] - t[k]), float(v[k]), float(s[k])
        tau = 0.0
        while True:
            error = u0 + su * tau - y
            if abs(error) <= tol:  # on the command: follow it if the drive can
                slope = min(max(su, -a), a)
                out_t.append(start + tau)
                out_slope.append(slope)
                if math.isfinite(length):
                    y = u0 + su * length if abs(su) <= a else y + slope * (length - tau)
                break
            slope = a if error > 0.0 else -a
            out_t.append(start + tau)
            out_slope.append(slope)
            closing = slope - su  # rate at which the gap closes
            meet = error / closing if closing * error > 0.0 else math.inf
            if tau + meet < length:
                y += slope * meet
                tau += meet
                continue
            if math.isfinite(length):
                y += slope * (length - tau)
            break
    times = np.array(out_t)
    slopes = np.array(out_slope)
    # Keep the last of breakpoints closer than the merge tolerance (it carries the right-hand slope).
    keep = np.concatenate((np.diff(times) > merge_tolerance(times), [True]))
    times, slopes = times[keep], slopes[keep]
    if times.size < 2:
        times = np.array([times[0], times[0] + 1.0])
        slopes = np.array([slopes[0], slopes[0]])
    # The output velocity is continuous: integrate the slopes (it is exactly what the drive does).
    velocity = np.concatenate(([0.0], np.cumsum(slopes[:-1] * np.diff(times))))
    return integrated(times, velocity, slopes, float(command.derivative(0)[0]), continuous_orders=2)


# ------------------------------------------------------------------------------------------
# A position-mode drive: the time-optimal follower of a position reference


def catch_up_plan(
    gap: float, velocity: float, target_velocity: float, acceleration_limit: float, velocity_limit: float
) -> tuple[tuple[float, float], ...]:
    """(duration_s, acceleration) phases that bring a double integrator onto a target moving at constant
    ``target_velocity`` in least time under |u| <= a and |velocity| <= velocity_limit (math.inf: none);
    ``gap`` = target - position.

    Bang-coast-bang, the classical time-optimal double integrator in the target's frame: the direction
    s is that of the gap left after braking, gap - w|w|/(2a) with w = velocity - target_velocity; the
    peak approach speed is sqrt(a s gap + w^2/2), or a coast at the top approach speed
    velocity_limit - s target_velocity when that is lower (a zero top speed coasts for ever).
    """
    a = acceleration_limit
    w = velocity - target_velocity
    s = 1.0 if gap >= w * abs(w) / (2.0 * a) else -1.0
    e, w = s * gap, s * w
    top = velocity_limit - s * target_velocity
    peak = math.sqrt(max(a * e + 0.5 * w * w, 0.0))
    if peak <= top:
        return ((max(peak - w, 0.0) / a, s * a), (peak / a, -s * a))
    if top <= 0.0:
        return ((max(-w, 0.0) / a, s * a), (math.inf, 0.0))
    coast = (e - (top * top - w * w) / (2.0 * a) - top * top / (2.0 * a)) / top
    return ((max(top - w, 0.0) / a, s * a), (max(coast, 0.0), 0.0), (top / a, -s * a))


def follow_position(
    reference: PiecewiseCommand, acceleration_limit: float, velocity_limit: float | None = None
) -> PiecewiseCommand:
    """What a position-mode drive makes of a position reference that moves at constant velocity between
    its breakpoints (a shaped velocity staircase): at every breakpoint its profile generator replans the
    time-optimal catch-up onto the reference under |a| <= acceleration_limit and |v| <= velocity_limit
    (``catch_up_plan``), then follows it. It starts at rest on the reference and reaches the final
    position at rest; piecewise constant in acceleration, so exact. The reference must not move faster
    than the velocity limit (then the follower's top approach speed is never negative).
    """
    a = float(acceleration_limit)
    if not (math.isfinite(a) and a > 0.0):
        raise InvalidParameter("acceleration_limit", a, "must be a finite number > 0")
    top = math.inf if velocity_limit is None else float(velocity_limit)
    if command_has_slopes(reference):
        raise InvalidParameter("profile", "ramps", "the position follower needs a reference of velocity steps")
    t, p_ref, v_ref = reference.time_s, reference.derivative(0), reference.derivative(1)
    if float(np.max(np.abs(v_ref))) > top * (1.0 + 1e-12):  # round-off of the impulses' sum allowed
        raise InvalidParameter("velocity_limit", top, "the reference itself moves faster than the velocity limit")
    on_reference = tuple(1e-13 * max(float(np.max(np.abs(x))), 1e-300) for x in (p_ref, v_ref))
    rows: list[tuple[float, float, float, float]] = []  # (time, position, velocity, acceleration) of each piece
    p, v = float(p_ref[0]), 0.0
    for k in range(t.size):  # loop over the reference's pieces (impulses x steps: a few dozen)
        start = float(t[k])
        length = float(t[k + 1] - t[k]) if k + 1 < t.size else math.inf
        gap, target_v = float(p_ref[k]) - p, float(v_ref[k])
        phases: tuple[tuple[float, float], ...] = ()
        if abs(gap) > on_reference[0] or abs(v - target_v) > on_reference[1]:
            phases = catch_up_plan(gap, v, target_v, a, top)
        elapsed = 0.0
        for duration, accel in (*phases, (math.inf, None)):  # the plan, then on the reference
            step = min(duration, length - elapsed)
            if step <= 0.0:
                continue
            if accel is None:  # on the reference (round-off of the plan removed)
                p, v, accel = float(p_ref[k]) + target_v * elapsed, target_v, 0.0
            rows.append((start + elapsed, p, v, accel))
            if not math.isfinite(step):
                break
            p, v, elapsed = p + v * step + 0.5 * accel * step * step, v + accel * step, elapsed + step
            if elapsed >= length:
                break
    table = np.array(rows)
    # Of breakpoints closer than the merge tolerance keep the last (its state is exact): a plan's phase
    # that short changes the velocity by at most a x 2e-9 s.
    table = table[np.concatenate((np.diff(table[:, 0]) > merge_tolerance(table[:, 0]), [True]))]
    if table.shape[0] < 2:
        table = np.vstack([table, table + np.array([1.0, 0.0, 0.0, 0.0])])
    return PiecewiseCommand(check_time_grid(table[:, 0]), table[:, 1:].T.copy(), continuous_orders=2)


def command_has_slopes(command: PiecewiseCommand) -> bool:
    """Whether any piece of a degree-2 command accelerates (else its velocity is a staircase)."""
    return command.degree > 2 or bool(np.any(command.derivative(2) != 0.0))
