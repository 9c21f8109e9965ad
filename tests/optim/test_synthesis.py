"""The one pipeline: every family through ``synthesize`` honours the same sampling, horizon, settling and
limit rules (optim/synthesis.py's docstring states them)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.presenters import answer_body
from models.errors import Infeasible, NotApplicable
from models.plants import make_plant
from optim.problem import Limits, Problem, SettlingCriteria, nice_period
from optim.registry import FAMILIES
from optim.synthesis import synthesize

PLANT = make_plant("mode", natural_frequency_hz=5.0, damping_ratio=0.05)  # period 0.2 s
LIMITS = Limits(max_velocity=2.0, max_acceleration=20.0)


def problem(move: str, **changes) -> Problem:
    return Problem(PLANT, **{move: 1.0}, limits=changes.pop("limits", LIMITS), **changes)


def applicable(name: str, move: str) -> bool:
    return FAMILIES[name].not_applicable(problem(move)) is None


PAIRS = [(name, move) for name in FAMILIES for move in ("displacement", "target_velocity")]
CASES = [pair for pair in PAIRS if applicable(*pair)]


def test_which_families_apply():
    # Pseudo-polynomial laws and smoothers are rest-to-rest by construction (Incerti eq. 17, Biagiotti's
    # filtered step); STAP and input shaping do both. A family that does not apply says why.
    assert sorted(p for p in PAIRS if p not in CASES) == [
        ("pseudo_polynomial", "target_velocity"),
        ("smoother", "target_velocity"),
    ]
    with pytest.raises(NotApplicable, match="rest-to-rest"):
        synthesize(
            FAMILIES["smoother"],
            problem("target_velocity"),
            FAMILIES["smoother"].default_options(problem("target_velocity")),
        )


def run(name: str, move: str, **changes):
    family = FAMILIES[name]
    p = problem(move, **changes)
    return synthesize(family, p, family.default_options(p))


@pytest.mark.parametrize(("name", "move"), CASES)
def test_default_horizon_and_sampling(name, move):
    result = run(name, move)
    end = result.design.command_end_s
    # Horizon: the command's end plus 5 natural periods of the (only) mode, 5 x 0.2 s.
    assert result.run.grid.horizon_s == pytest.approx(end + 1.0, rel=1e-12)
    assert result.command.time_s[-1] == pytest.approx(end + 1.0, rel=1e-12)
    # Sampling: 1, 2 or 5 times a power of ten, at most 2000 samples over the horizon, more than 800.
    period = result.run.grid.period_s
    mantissa = period / 10 ** math.floor(math.log10(period) + 1e-12)
    assert min(abs(mantissa - m) for m in (1, 2, 5)) < 1e-9
    assert 800 < result.run.grid.horizon_s / period <= 2000
    steps = np.diff(result.command.time_s)
    assert steps.max() == pytest.approx(period, rel=1e-9)  # corners only ever shorten a step


@pytest.mark.parametrize(("name", "move"), CASES)
def test_requested_sampling_horizon_and_settling_are_honoured(name, move):
    first = run(name, move)
    horizon = first.design.command_end_s + 0.37
    result = run(
        name, move, sample_period_s=1e-3, horizon_s=horizon, settling=SettlingCriteria(position_tolerance=0.02)
    )
    assert result.run.grid.period_s == 1e-3
    assert result.command.time_s[-1] == pytest.approx(horizon, abs=1e-12)
    # The settling window is the tolerance times the load's simulated move (|G(0)| = 1, the move is 1; the
    # simulated move carries the residual at the horizon, hence 1e-3 rather than round-off).
    assert result.metrics.settling.window == pytest.approx(0.02, rel=1e-3)


@pytest.mark.parametrize(("name", "move"), CASES)
def test_limits_are_reported_the_same_way_by_every_family(name, move):
    # A jerk limit no family is forced to meet at this level: each either meets it or reports it.
    limits = Limits(max_velocity=2.0, max_acceleration=20.0, max_jerk=150.0)
    try:
        result = run(name, move, limits=limits)
    except Exception as exc:  # a family that designs for jerk may find the limits infeasible: that is honest
        # (the shapers, whose acceleration steps make the jerk impulsive, do not apply under a jerk limit)
        assert type(exc).__name__ in ("Infeasible", "SolverFailed", "NotApplicable"), exc
        return
    command = result.command
    dense = np.linspace(0.0, float(command.time_s[-1]), 200_001)
    peaks = {
        "max_velocity": np.max(np.abs(command.evaluate(1, dense))),
        "max_acceleration": np.max(np.abs(command.evaluate(2, dense))),
    }
    reported = {v.split(":")[0] for v in result.limit_violations}
    for name_, peak in peaks.items():
        limit = getattr(limits, name_)
        if peak > limit * (1 + 1e-6):  # a breach seen on a dense grid is always reported ...
            assert f"limits.{name_}" in reported
        if peak < limit * (1 - 1e-6):  # ... and a clear margin never is
            assert f"limits.{name_}" not in reported
    for line in result.limit_violations:  # one wording, and every violation is also a warning
        assert line.startswith("limits.max_") and line in result.warnings
        assert " peaks at " in line or " is impulsive" in line


def test_a_design_above_a_limit_is_refused_unless_asked_for():
    # A STAP is not designed for jerk: t_j = 1/f = 0.2 s and a = 20 give |j| = v/(t_j (t_a - t_j)) >> 1.
    limits = Limits(max_acceleration=20.0, max_jerk=1.0)
    with pytest.raises(Infeasible, match=r"limits\.max_jerk: the jerk peaks at ") as refused:
        run("stap", "target_velocity", limits=limits)
    assert refused.value.field == "limits.max_jerk"
    result = run("stap", "target_velocity", limits=limits, allow_limit_violation=True)
    (line,) = result.limit_violations
    assert line.startswith("limits.max_jerk: the jerk peaks at ")
    assert result.metrics.peak_jerk > 1.0
    assert answer_body(result)["limits_met"] is False


def test_nice_period_rule():
    # span / 2000 rounded up to 1, 2 or 5 x 10^k: 1e-3 exactly; 1.0038e-3 -> 2e-3; 3.5e-3 -> 5e-3.
    assert nice_period(2.0) == 1e-3
    assert nice_period(2.0077) == 2e-3
    assert nice_period(7.0) == 5e-3
    assert nice_period(1e-9) == 1e-6  # the floor of every family
