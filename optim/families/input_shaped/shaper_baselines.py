"""Baseline velocity commands that keep an input-shaped command within an acceleration limit.

Baselines under the acceleration limit a (Sec. 4 of Chatlatanagulchai & Pongpanich):

- ``modified``: a ramp-plus-step of rise time Delta = a1 max|A_i| / a, so every shaped ramp has a
  slope a1 |A_i| / Delta <= a, provided the no-overlap condition t_{i+1} - t_i >= Delta holds
  (PAPER-NOTES: every shaped ramp lasts Delta). When it fails the closed form is not valid: that
  is reported as infeasible, with the limits that would make it hold.
- a single ramp lengthened past the overlap (``single_ramp_baseline``): where the modified ramp
  would overlap, the shortest ramp whose shaped copies, added where they overlap, keep the slope
  <= a. The slope at t is V/Delta times the sum of the A_i with t_i in (t - Delta, t], so the
  shortest valid Delta is the least Delta >= V W(Delta) / a with W(Delta) the largest sum of
  amplitudes in a window shorter than Delta: closed form, one regime per impulse-time difference
  (Delta = V max A_i / a, the modified baseline, in the first; V / a, the plain ramp at the limit, in
  the last). It always exists (the shaped slope of a ramp at a is at most a sum A_i = a).
- ``multi_step``: steps at the first m impulse times, each a ramp of rise Delta (Fig. 10). The
  paper's two-step relations (a1 + a2 = V, a1 A1/Delta = (a1 A2 + a2 A1)/Delta = a) are used
  where they hold: two impulses with A1 >= A2 (ZV) and no overlap. Otherwise (ZVD has A2 > A1, and
  the relations give a2 < 0 and a slope of 2a), the fastest such baseline is found exactly: the
  smallest Delta with non-negative step heights summing to V such that the shaped command's
  slope, with overlapping ramps added, never exceeds a. It is a linear programme on each interval
  of Delta where the overlaps do not change (scipy ``linprog``, HiGHS).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linprog

from models.errors import Infeasible, InvalidParameter
from models.shapers import ImpulseSequence, RampTrain

__all__ = [
    "Baseline",
    "BaselineChoice",
    "BaselineKind",
    "design_baseline",
    "fastest_cruise_velocity",
    "fastest_single_ramp_cruise",
    "fastest_steps",
    "modified_baseline",
    "modified_ramp_time_s",
    "multi_step_baseline",
    "paper_two_step",
    "single_ramp_baseline",
    "single_ramp_time_s",
    "step_baseline",
    "window_sums",
]

FloatArray = NDArray[np.float64]
BaselineKind = Literal["step", "modified", "multi_step"]
BaselineChoice = Literal["auto", "step", "modified", "multi_step"]


@dataclass(frozen=True)
class Baseline:
    """Velocity steps of ``step_heights`` at ``step_times_s``, each spread over a ramp of
    ``ramp_time_s`` (0 for the plain step baseline)."""

    kind: BaselineKind
    step_times_s: FloatArray
    step_heights: FloatArray
    ramp_time_s: float
    method: str

    def train(self) -> RampTrain:
        return RampTrain(self.step_times_s, np.full(self.step_times_s.size, self.ramp_time_s), self.step_heights)


def step_baseline(velocity: float) -> Baseline:
    """The original baseline: a velocity step of height V at t = 0 (Sec. 3.2)."""
    return Baseline("step", np.array([0.0]), np.array([velocity]), 0.0, "velocity step")


def modified_ramp_time_s(velocity: float, shaper: ImpulseSequence, acceleration_limit: float) -> float:
    """Delta = a1 max|A_i| / a (Sec. 4): the shortest ramp whose shaped copies have slopes <= a."""
    return abs(velocity) * float(np.max(np.abs(shaper.amplitudes))) / acceleration_limit


def modified_baseline(velocity: float, shaper: ImpulseSequence, acceleration_limit: float) -> Baseline:
    """The paper's ramp-plus-step (Fig. 7), valid when t_{i+1} - t_i >= Delta for every i."""
    delta = modified_ramp_time_s(velocity, shaper, acceleration_limit)
    if shaper.count > 1:
        gaps = np.diff(shaper.times_s)
        shortest = float(np.min(gaps))
        if shortest < delta * (1.0 - 1e-12):
            biggest = float(np.max(np.abs(shaper.amplitudes)))
            train = RampTrain.single(0.0, delta, velocity).shaped(shaper)
            raise Infeasible(
                f"the modified baseline's ramp would last Delta = a1 max|A_i| / a = {delta:.6g} s, longer than "
                f"the shortest gap between the shaper's impulses ({shortest:.6g} s): the shaped ramps would "
                f"overlap and the command's slope would reach {train.max_slope():.6g} > the acceleration limit "
                f"{acceleration_limit:.6g} (the no-overlap condition t_(i+1) - t_i >= Delta of Sec. 4 fails). It "
                f"holds for an acceleration limit >= {abs(velocity) * biggest / shortest:.6g} or a velocity of at most "
                f"{acceleration_limit * shortest / biggest:.6g}; baseline 'multi_step' (with baseline_steps = 1 "
                f"for a single ramp) lengthens the ramps until the overlapping slopes respect the limit, and "
                f"baseline 'auto' (the default) takes the earliest-ending baseline that does",
                "acceleration_limit",
            )
    method = "closed form: Delta = a1 max|A_i| / a (Sec. 4)"
    return Baseline("modified", np.array([0.0]), np.array([velocity]), delta, method)


def paper_two_step(velocity: float, shaper: ImpulseSequence, acceleration_limit: float) -> Baseline | None:
    """Fig. 10's relations a1 + a2 = V, a1 A1 / Delta = (a1 A2 + a2 A1) / Delta = a, i.e.
    a1 = V A1/(2A1 - A2), a2 = V (A1 - A2)/(2A1 - A2), Delta = V A1^2 / (a (2A1 - A2)).

    They describe the shaped command only for two impulses with A1 >= A2 (ZV) and
    Delta <= t_2 (PAPER-NOTES); None otherwise.
    """
    if shaper.count != 2:
        return None
    a1_amp, a2_amp = (float(x) for x in shaper.amplitudes)
    if not (a2_amp > 0.0 and a1_amp >= a2_amp):
        return None
    v = abs(velocity)
    denominator = 2.0 * a1_amp - a2_amp
    heights = np.array([v * a1_amp / denominator, v * (a1_amp - a2_amp) / denominator])
    delta = v * a1_amp * a1_amp / (acceleration_limit * denominator)
    if delta > float(shaper.times_s[1]) * (1.0 + 1e-12):
        return None
    return Baseline(
        "multi_step",
        np.array(shaper.times_s, dtype=np.float64),
        math.copysign(1.0, velocity) * heights,
        delta,
        "closed form: the paper's two-step relations (Sec. 4, Fig. 10; two impulses with A1 >= A2)",
    )


def _distinct(values: FloatArray) -> FloatArray:
    """Sorted values with those within round-off (1e-12 relative, 2e-9 s) of the previous dropped."""
    v = np.sort(np.asarray(values, dtype=float))
    if v.size == 0:
        return v
    tolerance = max(2e-9, 1e-12 * float(np.max(np.abs(v))))
    return v[np.concatenate(([True], np.diff(v) > tolerance))]


def fastest_steps(
    velocity: float, shaper: ImpulseSequence, acceleration_limit: float, step_times_s: FloatArray
) -> tuple[FloatArray, float]:
    """Non-negative step heights b_j (sum V) at the given times and the smallest ramp time Delta
    such that the shaped command sum_ij A_i b_j r_Delta(t - t_i - tau_j) has slope <= a.

    The shaped ramps start at the distinct sums s_l = t_i + tau_j, with heights G_l(b) linear in b.
    Ramp l is active on [s_l, s_l + Delta), so the slope at t = s_k is sum over
    s_k - Delta < s_l <= s_k of G_l / Delta, and with G >= 0 these are the largest. Which ramps
    overlap changes only where Delta crosses a difference s_k - s_l: on each interval between
    those differences the problem is a linear programme in (b, Delta); the first feasible interval
    gives the answer. Delta = V/a is always feasible (the slope is then at most V/Delta sum A_i), so
    only differences below V/a matter.
    """
    if np.any(shaper.amplitudes < 0.0):
        raise InvalidParameter("shaper", "negative impulses", "the multi-step baseline needs non-negative amplitudes")
    v = abs(velocity)
    m = step_times_s.size
    sums = (shaper.times_s[:, None] + step_times_s[None, :]).ravel()  # impulse i, step j
    starts = _distinct(sums)
    group = np.argmin(np.abs(sums[:, None] - starts[None, :]), axis=1)
    weights = np.zeros((starts.size, m))  # G_l(b) = weights[l] @ b, for V = 1
    np.add.at(weights, (group, np.tile(np.arange(m), shaper.count)), np.repeat(shaper.amplitudes, m))
    # Solve for V = 1 with times in units of V/a, the longest ramp ever needed (then every
    # coefficient of the LP is O(1) and HiGHS' tolerances are relative).
    unit_s = v / acceleration_limit
    s = starts / unit_s
    differences = _distinct((s[None, :] - s[:, None])[np.triu_indices(s.size, 1)])
    # Delta = 1 (V/a) is feasible, so the intervals past the first difference >= 1 never matter.
    edges = np.concatenate(([0.0], differences[differences < 1.0], differences[differences >= 1.0][:1], [math.inf]))
    cost = np.zeros(m + 1)
    cost[-1] = 1.0
    equality = np.concatenate([np.ones(m), [0.0]])[None, :]

    def active(delta: float) -> FloatArray:
        """Row k: the ramps active just after s_k (s_k - Delta < s_l <= s_k)."""
        return ((s[None, :] <= s[:, None]) & (s[None, :] > s[:, None] - delta)).astype(float) @ weights

    for low, high in itertools.pairwise(edges):  # a loop over overlap patterns (a few dozen)
        rows = active(low + 1.0 if math.isinf(high) else 0.5 * (low + high))
        result = linprog(
            cost,
            A_ub=np.hstack([rows, np.full((s.size, 1), -1.0)]),
            b_ub=np.zeros(s.size),
            A_eq=equality,
            b_eq=[1.0],
            bounds=[(0.0, None)] * m + [(low, None if math.isinf(high) else high)],
            method="highs",
        )
        if result.status != 0:
            continue
        heights = np.clip(result.x[:m], 0.0, None)
        heights /= heights.sum()
        delta = float(result.x[-1])
        # The exact slope at the solution decides (the LP's tolerances are ~1e-9).
        slope = float(np.max(active(delta) @ heights)) / delta
        if slope > 1.0:
            delta *= slope
        return math.copysign(v, velocity) * heights, delta * unit_s
    # Unreachable in exact arithmetic (the last interval is feasible); valid in any case: one step
    # at t = 0 ramped over V/a has shaped slope V/a sum(window A_i)/(V/a) <= a.
    return math.copysign(v, velocity) * np.eye(m)[0], unit_s


def multi_step_baseline(
    velocity: float, shaper: ImpulseSequence, acceleration_limit: float, steps: int = 2
) -> Baseline:
    """Fig. 10's baseline with ``steps`` steps at the first impulse times: the paper's relations
    where they hold, the fastest valid heights and ramp time otherwise (``fastest_steps``)."""
    if not 1 <= steps <= shaper.count:
        raise InvalidParameter("baseline_steps", steps, f"must lie in [1, {shaper.count}] (the shaper's impulse count)")
    if steps == 2:
        closed = paper_two_step(velocity, shaper, acceleration_limit)
        if closed is not None:
            return closed
    step_times = np.array(shaper.times_s[:steps], dtype=np.float64)
    heights, delta = fastest_steps(velocity, shaper, acceleration_limit, step_times)
    why = "" if steps != 2 else " (the paper's two-step relations assume two impulses with A1 >= A2 and no overlap)"
    return Baseline("multi_step", step_times, heights, delta, "fastest non-negative steps by linear programming" + why)


def design_baseline(
    kind: BaselineKind, velocity: float, shaper: ImpulseSequence, acceleration_limit: float | None, steps: int = 2
) -> Baseline:
    if kind == "step":
        return step_baseline(velocity)
    if acceleration_limit is None:
        raise InvalidParameter("acceleration_limit", None, f"is required for baseline '{kind}'")
    if kind == "modified":
        return modified_baseline(velocity, shaper, acceleration_limit)
    return multi_step_baseline(velocity, shaper, acceleration_limit, steps)


def fastest_cruise_velocity(
    displacement: float, shaper: ImpulseSequence, acceleration_limit: float, max_velocity: float | None = None
) -> float:
    """The cruise velocity of the fastest rest-to-rest move with the modified baseline, within max_velocity.

    The move lasts D/V + V max|A_i|/a + t_n, convex in V with its minimum at
    V = sqrt(a D / max|A_i|) (the baseline is then a triangle: cruise = Delta); the no-overlap
    condition Delta <= min(t_(i+1) - t_i) caps V at a min gap / max|A_i|, and so does max_velocity.
    """
    biggest = float(np.max(np.abs(shaper.amplitudes)))
    best = math.sqrt(acceleration_limit * abs(displacement) / biggest)
    if shaper.count > 1:
        best = min(best, acceleration_limit * float(np.min(np.diff(shaper.times_s))) / biggest)
    return best if max_velocity is None else min(best, max_velocity)


def window_sums(shaper: ImpulseSequence) -> tuple[FloatArray, FloatArray]:
    """(d_k, W_k), k = 0..K: for a window length Delta in (d_k, d_(k+1)] (d_0 = 0, d_(K+1) = inf) the
    largest sum of amplitudes of impulses closer together than Delta is W_k. The d_k are the distinct
    differences t_j - t_i; W_0 = max A_i, W_K = sum A_i."""
    t, a = shaper.times_s, shaper.amplitudes
    i, j = np.triu_indices(t.size)  # pairs i <= j
    cumulative = np.concatenate(([0.0], np.cumsum(a)))
    differences, sums = t[j] - t[i], cumulative[j + 1] - cumulative[i]
    edges = _distinct(differences)
    group = np.searchsorted(edges, differences - max(2e-9, 1e-12 * float(t[-1])))
    best = np.full(edges.size, -math.inf)
    np.maximum.at(best, group, sums)
    return edges, np.maximum.accumulate(best)


def single_ramp_time_s(velocity: float, shaper: ImpulseSequence, acceleration_limit: float) -> tuple[float, int]:
    """(Delta, k): the shortest ramp of height V whose shaped command keeps |slope| <= a, and its regime.

    The slope is V/Delta x (sum of A_i within a window shorter than Delta), at most V W_k / Delta on
    (d_k, d_(k+1)] (``window_sums``): the answer is Delta = V W_k / a in the first regime where that
    is <= d_(k+1); it then exceeds d_k (otherwise the regime before was already feasible).
    """
    if np.any(shaper.amplitudes < 0.0):
        raise InvalidParameter("shaper", "negative impulses", "the single-ramp baseline needs non-negative amplitudes")
    edges, sums = window_sums(shaper)
    tops = np.append(edges[1:], math.inf)
    deltas = abs(velocity) * sums / acceleration_limit
    k = int(np.flatnonzero(deltas <= tops * (1.0 + 1e-12))[0])
    return float(deltas[k]), k


def single_ramp_baseline(velocity: float, shaper: ImpulseSequence, acceleration_limit: float) -> Baseline:
    """The shortest single ramp within the limit: the modified baseline (Sec. 4) where its shaped ramps do
    not overlap, else the ramp lengthened until the overlapping slopes add up to at most a."""
    delta, k = single_ramp_time_s(velocity, shaper, acceleration_limit)
    if k == 0:
        return modified_baseline(velocity, shaper, acceleration_limit)
    sums = window_sums(shaper)[1]
    method = (
        f"a single ramp lengthened past the overlap: Delta = V W / a with W = {sums[k]:.6g}, the largest sum of "
        f"amplitudes within a window of Delta (the modified baseline's shaped ramps would overlap)"
    )
    return Baseline("multi_step", np.array([0.0]), np.array([velocity]), delta, method)


def fastest_single_ramp_cruise(
    displacement: float, shaper: ImpulseSequence, acceleration_limit: float, max_velocity: float | None
) -> float:
    """The cruise V <= max_velocity of the fastest rest-to-rest single-ramp move, exactly.

    The move ends at D/V + Delta(V) + t_n with Delta(V) = V W_k / a in regime k
    (``single_ramp_time_s``): convex on each regime, least at sqrt(a D / W_k). The optimum is one of
    those points (clipped to their regimes), a regime's end a d_(k+1) / W_k, or max_velocity; all are
    evaluated with the exact Delta(V).
    """
    edges, sums = window_sums(shaper)
    a, d = acceleration_limit, abs(displacement)
    tops = np.append(edges[1:], math.inf)
    lows, highs = a * edges / sums, a * tops / sums
    candidates = np.concatenate([np.clip(np.sqrt(a * d / sums), lows, highs), highs[np.isfinite(highs)]])
    if max_velocity is not None:
        candidates = np.append(candidates[candidates <= max_velocity], max_velocity)
    candidates = candidates[candidates > 0.0]

    def end_s(v: float) -> float:
        return d / v + single_ramp_time_s(v, shaper, a)[0]

    return float(min(candidates, key=end_s))
