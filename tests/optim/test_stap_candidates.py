"""Issue 11, compare: STAP offers its closed form and ``optimized`` in one group, and compare keeps
``optimized`` only where it settles first."""

from __future__ import annotations

from dataclasses import replace

import pytest

from models.plants import ModePlant
from optim.families.stap.family import StapFamily, StapOptions
from optim.problem import Limits, Problem
from optim.registry import FAMILIES
from optim.synthesis import synthesize
from tests.optim.compare_runner import run_compare


def settle(problem: Problem, options: StapOptions) -> float:
    time_s = synthesize(StapFamily(), problem, options).metrics.settling.time_s
    assert time_s is not None
    return time_s


def test_the_candidates_are_one_group_with_labels():
    problem = Problem(ModePlant(40.0, 0.0), target_velocity=150.0, limits=Limits(max_acceleration=1000.0))
    labels = [(c.label, c.group, c.options.method) for c in StapFamily().candidates(problem)]
    assert labels == [("stap/closed_form", "stap", "closed_form"), ("stap/optimized", "stap", "optimized")]
    assert StapFamily().default_options(problem) == StapOptions()  # the endpoint's default stays one design


class FixedTime(StapFamily):
    """STAP at the damped_optimized example's t_a = 0.2 s (the OpenAPI example)."""

    def candidates(self, problem):
        return tuple(
            replace(c, options=replace(c.options, acceleration_time_s=0.2)) for c in super().candidates(problem)
        )


@pytest.mark.parametrize(
    ("zeta", "fixed", "label"),
    [
        (0.0, False, "stap/closed_form"),  # Sec. 3: the closed form has zero residual, IPOPT cannot beat it
        (0.1, False, "stap/closed_form"),  # t_a = t_a,min + t_j: the acceleration limit pins t_j, a tie
        (0.1, True, "stap/optimized"),  # the damped_optimized example: IPOPT over t_j beats k_j = 1
    ],
)
def test_compare_keeps_the_candidate_that_settles_first(monkeypatch, zeta, fixed, label):
    problem = Problem(ModePlant(40.0, zeta), target_velocity=150.0, limits=Limits(max_acceleration=1000.0))
    family = FixedTime() if fixed else StapFamily()
    monkeypatch.setitem(FAMILIES, "stap", family)
    rows, unavailable = run_compare(problem, ["stap"])
    assert unavailable == [] and [r.label for r in rows] == [label]
    # Independent: each candidate through the pipeline by itself; the row is the one that settles first.
    closed, optimized = (settle(problem, c.options) for c in family.candidates(problem))
    assert rows[0].result.metrics.settling.time_s == pytest.approx(min(closed, optimized), rel=1e-12)
    if label == "stap/optimized":
        assert optimized < closed * (1 - 1e-6)
    else:
        assert optimized == closed  # the optimiser returned the closed form itself (closed_form_kept)
