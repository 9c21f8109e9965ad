"""Chains of trajectory smoothers under kinematic limits (Biagiotti, Melchiorri and Moriello 2020).

- Kinematic limits: T_1 = |h|/v, T_i = q_max^(i-1)/q_max^(i) (eq. 2) under the ordering T_k >= sum_{i>k} T_i
  (eq. 3); where eq. 3 fails a bound is not reached and the level's peak is lowered until eq. 3 holds
  with equality (the time-optimal multi-segment law of the paper's ref. [8]). The harmonic filter's
  duration under limits is eq. (6).
- Vibration: the filters tuned to the plant's mode (eqs. 11, 13, 15 corrected; ``filter_tuning`` here).
- Both: the vibration filters are kept and rectangular filters are put in front of them, with eq. (3)
  extended to the whole chain, so every peak has a closed form (see ``design_chain``).

The eq. (17) discrete filters of a drive are in ``discrete_filters`` (this package) and the identification of
the mode from a free vibration (eq. 16) in ``optim.identification.free_vibration``; both are re-exported here.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from models.errors import Infeasible, InvalidParameter
from models.plants import Mode, Plant
from models.smoothers import (
    DAMPED,
    MAX_DURATION_S,
    MIN_DURATION_S,
    Chain,
    FilterKind,
    Smoother,
    mode_residuals,
    refinement,
    step_response,
)
from optim.families.smoother.discrete_filters import DiscreteDesign, commensurate_sample_period_s, design_discrete
from optim.families.smoother.filter_tuning import (
    VIBRATION_FREE_TOLERANCE,
    cancels,
    same_time_ratio,
    tuned_duration_s,
    tuned_filter,
    vibration_free_durations_s,
)
from optim.identification.free_vibration import Identification, identify, two_peak_estimate

__all__ = [
    "VIBRATION_FREE_TOLERANCE",
    "ChainDesign",
    "ChainResidual",
    "DiscreteDesign",
    "FilterSpec",
    "Identification",
    "SmootherLimits",
    "cancels",
    "chain_residual",
    "commensurate_sample_period_s",
    "design_chain",
    "design_discrete",
    "fixed_chain_peaks",
    "harmonic_duration_s",
    "identify",
    "limited_durations_s",
    "rectangular_durations_s",
    "same_time_ratio",
    "tuned_duration_s",
    "tuned_filter",
    "two_peak_estimate",
    "vibration_free_durations_s",
]

_PEAK_SAMPLES = 4096  # samples of a fixed chain's step response when its peaks are measured
_MAX_PEAK_SAMPLES = 1 << 17  # bounds that work for chains mixing very different time scales


# ------------------------------------------------------------------------------------------
# Kinematic limits


@dataclass(frozen=True)
class SmootherLimits:
    """Bounds on |velocity|, |acceleration| and |jerk| of the motor command (None: unbounded)."""

    velocity: float | None = None
    acceleration: float | None = None
    jerk: float | None = None

    def by_order(self) -> tuple[float | None, float | None, float | None]:
        return self.velocity, self.acceleration, self.jerk

    @property
    def highest_order(self) -> int:
        """1 for velocity, 2 for acceleration, 3 for jerk; 0 when nothing is bounded."""
        orders = [k + 1 for k, value in enumerate(self.by_order()) if value is not None]
        return max(orders) if orders else 0


def _bracket_root(g: Callable[[float], float], start: float) -> tuple[float, float]:
    """(lo, hi) with g(lo) > 0 >= g(hi), by factors of 4 from ``start`` (bounded search)."""
    hi = start
    for _ in range(400):
        if g(hi) <= 0.0:
            break
        hi *= 4.0
    else:
        raise Infeasible("the limits leave a level of the chain unbounded")
    lo = hi
    for _ in range(400):
        lo /= 4.0
        if g(lo) > 0.0:
            return lo, hi
    raise Infeasible("the limits admit no chain of rectangular filters")


def limited_durations_s(amount: float, caps: list[float], tail_s: float = 0.0) -> list[float]:
    """The shortest T_k..T_m of rectangular filters that take ``amount`` of derivative k-1 with the
    peak of derivative k+i at most caps[i], under T_j >= T_{j+1} + ... + T_m + tail_s (eq. 3; tail_s
    is the duration of the filters that follow).

    A peak that can be reached gives eq. (2), T_k = amount/cap. When it cannot (eq. 3 fails), the level's
    peak v is the root of amount/v = T_{k+1}(v) + ... + tail_s: the left side falls and the right side rises
    with v, so it is unique (scipy.optimize.brentq, on log v).
    """
    cap = caps[0]
    if len(caps) == 1:
        return [max(amount / cap if math.isfinite(cap) else 0.0, tail_s)]

    def rest(v: float) -> list[float]:
        return limited_durations_s(v, caps[1:], tail_s)

    if math.isfinite(cap):
        below = rest(cap)
        if amount / cap >= sum(below) + tail_s:
            return [amount / cap, *below]

    def g(v: float) -> float:
        return amount / v - sum(rest(v)) - tail_s

    lo, hi = _bracket_root(g, cap if math.isfinite(cap) else 1.0)
    log_v = brentq(lambda u: g(math.exp(u)), math.log(lo), math.log(hi), xtol=1e-15, rtol=4 * np.finfo(float).eps)
    v = math.exp(log_v)
    return [amount / v, *rest(v)]


def rectangular_durations_s(displacement: float, limits: SmootherLimits) -> tuple[float, ...]:
    """T_1..T_n of the time-optimal chain of n rectangular filters (eqs. 2-3), n = highest bounded order.

    v = 1, a = 2, j = 8 and h = 1 give (1, 0.5, 0.25) s.
    """
    order = limits.highest_order
    if order == 0:
        raise InvalidParameter("limits", "none", "give at least one of max_velocity, max_acceleration, max_jerk")
    caps = [value if value is not None else math.inf for value in limits.by_order()[:order]]
    return tuple(limited_durations_s(abs(displacement), caps))


def harmonic_duration_s(peak_n: float, limit_n1: float | None, limit_n2: float | None) -> float:
    """T_{n+1} of a harmonic filter after n rectangular ones whose output peaks at ``peak_n`` in its
    n-th derivative, so that derivatives n+1 and n+2 stay within their limits (eq. 6):
    max(pi/2 q^(n)/q^(n+1), sqrt(pi^2/2 q^(n)/q^(n+2)))."""
    candidates = []
    if limit_n1 is not None:
        candidates.append(0.5 * math.pi * peak_n / limit_n1)
    if limit_n2 is not None:
        candidates.append(math.sqrt(0.5 * math.pi**2 * peak_n / limit_n2))
    if not candidates:
        raise InvalidParameter("limits", "none", "eq. (6) needs a limit on derivative n+1 or n+2")
    return max(candidates)


# ------------------------------------------------------------------------------------------
# Chains meeting limits and suppression


@dataclass(frozen=True)
class FilterSpec:
    """A requested filter: its kind and duration (None: tuned to the plant's first mode)."""

    kind: FilterKind
    duration_s: float | None = None


@dataclass(frozen=True)
class ChainDesign:
    chain: Chain
    roles: tuple[str, ...]  # per filter: "limits" (designed for the limits), "tuned" or "given"
    mode: Mode | None  # the mode the filters are tuned to (the plant's first)
    predicted_peaks: tuple[float | None, float | None, float | None]  # |v|, |a|, |j| by the closed forms
    warnings: tuple[str, ...] = ()

    @property
    def total_duration_s(self) -> float:
        return self.chain.total_duration_s


def fixed_chain_peaks(filters: tuple[Smoother, ...]) -> tuple[float, float, float]:
    """c_q = sup |f^(q)| for q = 0, 1, 2, f the unit-area impulse response of the chain (inf where
    impulsive): the velocity, acceleration and jerk peaks of its unit step response.

    Measured on the exact step response (at least 4096 samples and |lambda| Ts <= 0.2, Taylor degree 7 in
    between, 16 points per piece): the relative error is below 1e-9 (and the peaks of the final profile are
    checked again). A closed form exists for one filter only (eq. 6 uses the harmonic's).
    """
    chain = Chain(filters)
    period = chain.total_duration_s / _PEAK_SAMPLES
    period = max(period / refinement(chain, period), chain.total_duration_s / _MAX_PEAK_SAMPLES)
    response = step_response(chain, 1.0, period)
    command = response.command()
    peaks = [command.peak_abs(q + 1) for q in range(3)]
    velocity, acceleration, jerk = (math.inf if p is None else p * (1.0 + 1e-9) for p in peaks)
    return velocity, acceleration, jerk


def _prefix_for(
    displacement: float, limits: SmootherLimits, fixed_s: float, peaks: tuple[float, float, float], m: int
) -> tuple[list[float], list[float | None]] | None:
    """m rectangular filters in front of the fixed ones (duration fixed_s, unit-step peaks ``peaks``)
    that keep every bounded derivative within its limit, or None when m filters cannot.

    With eq. (3) extended to the whole chain (T_k >= T_{k+1} + ... + T_m + fixed_s), the peak of
    derivative k is |h|/(T_1 ... T_k) for k <= m and |h| c_(k-m-1)/(T_1 ... T_m) above.
    """
    h = abs(displacement)
    bounds = limits.by_order()
    caps: list[float] = [b if b is not None else math.inf for b in bounds[:m]]
    ceiling = math.inf
    for k in range(m + 1, 4):  # derivatives carried by the fixed filters
        bound = bounds[k - 1]
        if bound is not None:
            c = peaks[k - m - 1]
            ceiling = min(ceiling, bound / c if c > 0 else math.inf)
    if m == 0:
        if ceiling < h:
            return None
        return [], [h * peaks[q] if math.isfinite(peaks[q]) else None for q in range(3)]
    if ceiling == 0.0:
        return None
    caps[m - 1] = min(caps[m - 1], ceiling)
    if not math.isfinite(caps[m - 1]) and fixed_s == 0.0:
        return None
    durations = limited_durations_s(h, caps, fixed_s)
    if not all(math.isfinite(t) and t > 0.0 for t in durations):
        return None
    predicted: list[float | None] = []
    product = 1.0
    for k in range(1, 4):
        if k <= m:
            product *= durations[k - 1]
            predicted.append(h / product)
        else:
            c = peaks[k - m - 1]
            predicted.append(h * c / product if math.isfinite(c) else None)
    return durations, predicted


def design_chain(plant: Plant, displacement: float, specs: list[FilterSpec], limits: SmootherLimits) -> ChainDesign:
    """The requested filters (tuned to the plant's first mode where no duration is given) preceded by
    the rectangular filters that the limits need: the shortest such chain satisfying eq. (3)."""
    if not (math.isfinite(displacement) and displacement != 0.0):
        raise InvalidParameter("displacement", displacement, "must be a finite, non-zero number")
    modes = plant.modes()
    mode = modes[0] if modes else None
    fixed: list[Smoother] = []
    roles: list[str] = []
    warnings: list[str] = []
    for i, spec in enumerate(specs):
        try:
            if mode is not None:
                fixed.append(tuned_filter(spec.kind, mode, spec.duration_s))
            elif spec.duration_s is not None and spec.kind not in DAMPED:
                fixed.append(Smoother(spec.kind, spec.duration_s))  # what tuned_filter gives: no decay rate
            else:
                what = "duration" if spec.duration_s is None else "decay rate"
                raise InvalidParameter(
                    "duration_s" if spec.duration_s is None else "type",
                    spec.duration_s if spec.duration_s is not None else spec.kind,
                    f"the plant has no vibration mode to take the {what} from",
                )
        except InvalidParameter as exc:
            if exc.field == "decay_rate_1_s":  # the decay rate comes from the plant, not from the request
                exc = InvalidParameter(
                    "duration_s" if spec.duration_s is not None else "type",
                    spec.duration_s if spec.duration_s is not None else spec.kind,
                    f"{exc.rule}; the decay rate is the plant's ({exc.value:.6g} 1/s)",
                )
            raise exc.under(f"filters[{i}]") from None
        roles.append("tuned" if spec.duration_s is None else "given")
    if not fixed and limits.highest_order == 0:
        raise InvalidParameter(
            "filters", [], "give at least one filter, or a limit (max_velocity, max_acceleration, max_jerk)"
        )
    fixed_s = float(sum(f.duration_s for f in fixed))
    peaks = fixed_chain_peaks(tuple(fixed)) if fixed else (math.inf, math.inf, math.inf)
    best: tuple[float, list[float], list[float | None]] | None = None
    for m in range(0 if fixed else 1, limits.highest_order + 1):
        found = _prefix_for(displacement, limits, fixed_s, peaks, m)
        if found is None:
            continue
        durations, predicted = found
        total = sum(durations) + fixed_s
        if best is None or total < best[0] * (1 - 1e-12):
            best = (total, durations, predicted)
    if best is None:  # m = highest order always succeeds; kept for safety
        raise Infeasible("no chain of rectangular filters meets these limits", "limits")
    total, durations, predicted = best
    if total > MAX_DURATION_S:
        raise Infeasible(
            f"at these limits the move lasts {total:.4g} s, longer than the {MAX_DURATION_S:g} s a smoother may last",
            "limits",
        )
    prefix = []
    for t in sorted(durations, reverse=True):
        if t < MIN_DURATION_S:
            warnings.append(
                f"a limit needs a rectangular filter of {t:.3g} s; it is lengthened to {MIN_DURATION_S:g} s"
            )
            t = MIN_DURATION_S
        prefix.append(Smoother("rectangular", t))
    chain = Chain((*prefix, *fixed))
    velocity, acceleration, jerk = predicted  # one per derivative 1..3 (``_prefix_for``)
    roles_all = ("limits",) * len(prefix) + tuple(roles)
    return ChainDesign(chain, roles_all, mode, (velocity, acceleration, jerk), tuple(warnings))


@dataclass(frozen=True)
class ChainResidual:
    """The residual vibration of a chain, in closed form (see models.smoothers.mode_residuals)."""

    amplitude: float  # sum over modes, load units, when the command ends
    fraction_of_move: float  # amplitude / the load's move |G(0) displacement|
    percent_residual_vibration: float | None  # 100 |F(p)| on the tuning mode (Sec. IV); None if it overflows
    vibration_free: bool | None  # the chain's zeros cancel the tuning mode; None without a mode


def chain_residual(chain: Chain, plant: Plant, displacement: float, mode: Mode | None) -> ChainResidual:
    amplitudes, _ = mode_residuals(chain, plant, displacement)
    total = float(np.sum(amplitudes))
    if mode is None:
        return ChainResidual(total, total / plant.load_move(displacement), None, None)
    prv = same_time_ratio(chain, mode)
    finite = math.isfinite(prv)
    return ChainResidual(
        total,
        total / plant.load_move(displacement),
        100.0 * prv if finite else None,
        bool(finite and prv <= VIBRATION_FREE_TOLERANCE),
    )
