"""The fastest design whose 5 % band covers an identified mode's frequency interval (the identify use case's
recommendation: requests to the family endpoints, and their answers read).

The plant designed for is the identified mode of lowest frequency, as ``{"kind": "mode"}`` with its
estimated natural frequency and damping ratio: every family designs for (and reports ``sensitivity`` and
its 5 % band about) a plant's first mode, and the lowest mode is the one a move excites most. The
interval to cover is that mode's 95 % interval of f_n, in frequency ratio f_true / f_estimated. Higher
modes are listed in the answer but not designed for.

``recommendation_candidates`` lists the requests to try, ready to POST to their endpoints: the
time-optimal command with ``robustness.frequency_ratio_range`` set to the interval and the nominal one,
every shaper of the catalogue, STAP with ``frequency_uncertainty`` covering the interval, and (for a
rest-to-rest move) the damped harmonic smoother, single and doubled. Each includes ``sensitivity`` on a
grid that extends past the interval, so its band is computed. ``recommend`` runs them with an injected
runner (the service's pipeline over HTTP, or in-process), keeps those whose returned
``sensitivity.band_5_percent`` covers the interval, and picks the one that settles first
(``metrics.settling_time_s``, the product's yardstick: docs/api.md, Settling).
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Awaitable, Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

from app.family_names import endpoint_of
from models.errors import DomainError, InvalidParameter, PoolUnavailable
from optim.families.input_shaped.shapers import CATALOGUE_NAMES
from optim.identification.modal import FittedMode

__all__ = [
    "Move",
    "MoveLimits",
    "RecommendationCandidate",
    "RunOne",
    "band_covers",
    "plant_interval",
    "recommend",
    "recommendation_candidates",
]

SENSITIVITY_COUNT = 401
SENSITIVITY_MARGIN = 0.05  # the grid runs this far past the interval (frequency ratio)


@dataclass(frozen=True)
class Move:
    """Rest-to-rest (``displacement``) or rest-to-velocity (``target_velocity``): exactly one."""

    displacement: float | None = None
    target_velocity: float | None = None


@dataclass(frozen=True)
class MoveLimits:
    max_velocity: float | None = None
    max_acceleration: float | None = None
    max_jerk: float | None = None

    def as_dict(self) -> dict[str, float]:
        return {k: v for k, v in vars(self).items() if v is not None}


class RecommendationCandidate(NamedTuple):
    family: str
    endpoint: str
    request: dict[str, Any]


RunOne = Callable[[str, dict[str, Any]], Awaitable[Mapping[str, Any]]]


def plant_interval(modes: Sequence[FittedMode]) -> tuple[FittedMode, tuple[float, float]]:
    """The mode designed for (the lowest) and its 95 % interval of f_n as ratios to its estimate."""
    if not modes:
        raise InvalidParameter("modes", "none", "no identified mode to design for")
    mode = min(modes, key=lambda m: m.natural_frequency_hz)
    lo, hi = mode.natural_frequency_ci_hz
    f = mode.natural_frequency_hz
    return mode, (lo / f, hi / f)


def _label(family: str, request: Mapping[str, Any]) -> str:
    if family == "input_shaped":
        return f"input_shaped/{request['shaper']}"
    if family == "time_optimal":
        return "time_optimal/robust" if "robustness" in request else "time_optimal/nominal"
    if family == "smoother":
        return f"smoother/{len(request['filters'])}x damped_harmonic"
    return family


def recommendation_candidates(
    modes: Sequence[FittedMode], move: Move, limits: MoveLimits
) -> list[RecommendationCandidate]:
    """(family, endpoint, request body) of every design to try for the lowest mode's interval (see the module)."""
    if (move.displacement is None) == (move.target_velocity is None):
        raise InvalidParameter("displacement", None, "give exactly one of displacement or target_velocity")
    mode, (lo, hi) = plant_interval(modes)
    plant = {
        "kind": "mode",
        "natural_frequency_hz": mode.natural_frequency_hz,
        "damping_ratio": mode.damping_ratio,
    }
    common: dict[str, Any] = {"plant": plant}
    if move.displacement is not None:
        common["displacement"] = move.displacement
    else:
        common["target_velocity"] = move.target_velocity
    if limits.as_dict():
        common["limits"] = limits.as_dict()
    common["sensitivity"] = {
        "min_ratio": max(0.01, min(0.5, lo - SENSITIVITY_MARGIN)),
        "max_ratio": max(1.5, hi + SENSITIVITY_MARGIN),
        "count": SENSITIVITY_COUNT,
    }
    out: list[RecommendationCandidate] = []

    def add(family: str, extra: dict[str, Any]) -> None:
        out.append(RecommendationCandidate(family, endpoint_of(family), {**common, **extra}))

    if limits.max_acceleration is not None or limits.max_jerk is not None:
        # the band a little wider than the interval: its V <= 5 % then holds at the interval's ends with margin
        half = max(1.0 - lo, hi - 1.0)
        ratio_range = [max(0.05, 1.0 - 1.02 * half), min(20.0, 1.0 + 1.02 * half)]
        add("time_optimal", {"robustness": {"frequency_ratio_range": ratio_range}})
        add("time_optimal", {})
    for shaper in CATALOGUE_NAMES:
        add("input_shaped", {"shaper": shaper})
    if limits.max_acceleration is not None:
        uncertainty = min(0.9, max(1.0 - lo, hi - 1.0) * 1.02)
        add("stap", {"frequency_uncertainty": uncertainty})
    if move.displacement is not None:
        add("smoother", {"filters": [{"type": "damped_harmonic"}]})
        add("smoother", {"filters": [{"type": "damped_harmonic"}, {"type": "damped_harmonic"}]})
    return out


def band_covers(band: Sequence[float | None] | None, interval: tuple[float, float]) -> bool:
    """Whether a 5 % band [low, high] (an end None: beyond the evaluated ratios) holds the interval."""
    if band is None or len(band) != 2:
        return False
    low, high = band
    return (low is None or low <= interval[0]) and (high is None or high >= interval[1])


def _outcome(
    candidate: RecommendationCandidate, answer: Mapping[str, Any], interval: tuple[float, float]
) -> dict[str, Any]:
    sensitivity = answer.get("sensitivity") or {}
    band = sensitivity.get("band_5_percent")
    settling = (answer.get("metrics") or {}).get("settling_time_s")
    covers = band_covers(band, interval)
    return {
        "family": candidate.family,
        "label": _label(candidate.family, candidate.request),
        "endpoint": candidate.endpoint,
        "settling_time_s": settling,
        "motion_time_s": (answer.get("metrics") or {}).get("motion_time_s"),
        "band_5_percent": band,
        "covers": covers,
        "reason": None if covers else "its 5 % band does not cover the interval",
    }


async def recommend(
    candidates: Sequence[RecommendationCandidate], run_one: RunOne, interval: tuple[float, float]
) -> tuple[RecommendationCandidate | None, list[dict[str, Any]]]:
    """Run every candidate (concurrently) with ``run_one(family, request) -> response body``; the one that
    settles first among those whose band covers ``interval`` (None if none does), and every outcome.

    A candidate whose run raises a DomainError (infeasible, not applicable, solver failure or time-out) is
    an outcome with its reason; a pool that cannot take work (PoolUnavailable) is raised, as compare does."""

    async def one(candidate: RecommendationCandidate) -> dict[str, Any]:
        try:
            answer = await run_one(candidate.family, candidate.request)
        except PoolUnavailable:
            raise
        except DomainError as exc:
            reason = f"{exc.field}: {exc.rule}" if isinstance(exc, InvalidParameter) else str(exc)
            return {
                "family": candidate.family,
                "label": _label(candidate.family, candidate.request),
                "endpoint": candidate.endpoint,
                "settling_time_s": None,
                "motion_time_s": None,
                "band_5_percent": None,
                "covers": False,
                "reason": f"{exc.problem_type}: {reason}",
            }
        return _outcome(candidate, answer, interval)

    outcomes = list(await asyncio.gather(*(one(c) for c in candidates)))
    best: int | None = None
    for i, outcome in enumerate(outcomes):
        if not outcome["covers"] or outcome["settling_time_s"] is None:
            continue
        key = (outcome["settling_time_s"], outcome["motion_time_s"] or math.inf)
        if best is None or key < (outcomes[best]["settling_time_s"], outcomes[best]["motion_time_s"] or math.inf):
            best = i
    chosen = candidates[best] if best is not None else None
    return chosen, outcomes
