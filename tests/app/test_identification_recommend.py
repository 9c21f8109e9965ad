"""app.services.recommend: the candidates for an identified mode's interval, and the choice among their results.

The runner is a fake (a table of answers), so the choice is tested by itself: the least settling time among the
candidates whose returned band covers the interval; failures and uncovered bands are listed, never chosen.
"""

from __future__ import annotations

import pytest

from app.services.recommend import (
    Move,
    MoveLimits,
    RecommendationCandidate,
    band_covers,
    plant_interval,
    recommend,
    recommendation_candidates,
)
from models.errors import Infeasible, PoolUnavailable
from optim.identification.modal import IdentifiedMode
from tests import aio


def mode(f: float, ci: tuple[float, float], zeta: float = 0.03) -> IdentifiedMode:
    return IdentifiedMode(
        natural_frequency_hz=f,
        damping_ratio=zeta,
        natural_frequency_ci_hz=ci,
        damping_ratio_ci=(zeta * 0.9, zeta * 1.1),
        natural_frequency_std_hz=(ci[1] - ci[0]) / 3.92,
        damping_ratio_std=zeta * 0.05,
        damped_frequency_hz=f,
        decay_rate_1_s=1.0,
        peak_frequency_hz=f,
        amplitude=(1.0,),
        signal_to_noise=50.0,
        detection_snr=500.0,
        periods=40.0,
        periods_above_noise=20.0,
        samples_per_period=80.0,
    )


MODES = [mode(61.0, (60.0, 62.0), 0.05), mode(23.0, (22.54, 23.46))]  # the lowest is designed for: +-2 %


def test_the_plant_is_the_lowest_mode_and_the_interval_its_ratio():
    chosen, interval = plant_interval(MODES)
    assert chosen.natural_frequency_hz == 23.0
    assert interval == pytest.approx((0.98, 1.02))


def test_candidates_carry_the_interval_into_each_family_request():
    candidates = recommendation_candidates(MODES, Move(displacement=0.1), MoveLimits(0.5, 5.0, None))
    families = [c.family for c in candidates]
    assert families.count("time_optimal") == 2 and families.count("input_shaped") == 8
    assert "stap" in families and families.count("smoother") == 2
    for c in candidates:
        assert c.request["plant"] == {"kind": "mode", "natural_frequency_hz": 23.0, "damping_ratio": 0.03}
        assert c.request["displacement"] == 0.1
        assert c.request["limits"] == {"max_velocity": 0.5, "max_acceleration": 5.0}
        grid = c.request["sensitivity"]
        assert grid["min_ratio"] <= 0.98 - 0.05 and grid["max_ratio"] >= 1.02 + 0.05  # the band's ends are seen
    robust = next(c for c in candidates if "robustness" in c.request)
    lo, hi = robust.request["robustness"]["frequency_ratio_range"]
    assert lo <= 0.98 and hi >= 1.02
    stap = next(c for c in candidates if c.family == "stap")
    assert stap.request["frequency_uncertainty"] >= 0.02
    # no acceleration or jerk limit: no time-optimal nor STAP; a velocity target: no smoother
    velocity = recommendation_candidates(MODES, Move(target_velocity=1.0), MoveLimits())
    assert {c.family for c in velocity} == {"input_shaped"}


def test_band_covers():
    assert band_covers([0.97, 1.03], (0.98, 1.02))
    assert band_covers([None, 1.03], (0.98, 1.02))  # an open end runs past the evaluated ratios
    assert not band_covers([0.99, 1.03], (0.98, 1.02))
    assert not band_covers(None, (0.98, 1.02))


def answer(settling: float | None, band: list[float | None] | None) -> dict:
    return {
        "metrics": {"settling_time_s": settling, "motion_time_s": settling},
        "sensitivity": {"band_5_percent": band},
    }


def test_the_choice_is_the_least_settling_time_among_covering_bands():
    candidates = [
        RecommendationCandidate("time_optimal", "/a", {"robustness": {}, "n": 1}),  # fastest, but too narrow a band
        RecommendationCandidate("input_shaped", "/b", {"shaper": "zv"}),
        RecommendationCandidate("input_shaped", "/b", {"shaper": "zvd"}),  # covers and settles first of those
        RecommendationCandidate("stap", "/c", {}),  # fails
    ]
    table = {
        ("time_optimal", None): answer(0.1, [0.99, 1.01]),
        ("input_shaped", "zv"): answer(0.3, [0.9, 1.1]),
        ("input_shaped", "zvd"): answer(0.2, [0.8, None]),
    }

    async def run_one(family: str, body: dict) -> dict:
        if family == "stap":
            raise Infeasible("no STAP within the limits")
        return table[(family, body.get("shaper"))]

    chosen, outcomes = aio.run(recommend(candidates, run_one, (0.98, 1.02)))
    assert chosen is candidates[2]
    assert [o["covers"] for o in outcomes] == [False, True, True, False]
    assert outcomes[3]["reason"].startswith("infeasible: no STAP")
    # none covers: no choice
    chosen, _ = aio.run(recommend(candidates[:1], run_one, (0.98, 1.02)))
    assert chosen is None


def test_a_pool_that_cannot_take_work_is_raised():
    async def run_one(family: str, body: dict) -> dict:
        raise PoolUnavailable("starting")

    with pytest.raises(PoolUnavailable):
        aio.run(recommend([RecommendationCandidate("stap", "/c", {})], run_one, (0.98, 1.02)))
