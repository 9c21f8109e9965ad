"""Newton on Pontryagin's conditions of a bang train (optim.families.time_optimal.shooting) against SLSQP on the
durations alone (optim.families.time_optimal.refine.refine: another method, from the same start) and the
certificate: both reach the same proven minimum-time command, with a held jerk and with a held acceleration on
three modes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from models.plants import ModePlant, TransferFunctionPlant
from optim.families.time_optimal.arcs import merged
from optim.families.time_optimal.certify import certificate
from optim.families.time_optimal.family import limits_met, selected_modes, spec_of
from optim.families.time_optimal.options import TimeOptimalOptions
from optim.families.time_optimal.refine import refine
from optim.families.time_optimal.report import TimeOptimalReport
from optim.families.time_optimal.shooting import shoot
from optim.families.time_optimal.types import Arc, Spec
from optim.problem import Limits, Problem
from optim.registry import FAMILIES
from optim.synthesis import synthesize

# bench/time_optimal_speed.py's held-jerk move 3: its minimum-time command is the bang train +-+-+-+ (7 arcs for 5
# end conditions: the end state and one mode's residual), found by a repair's notch and, before, SLSQP.
MOVE_3 = Problem(
    plant=ModePlant(natural_frequency_hz=36.14480673752081, damping_ratio=0.17950920643221377),
    displacement=0.032636985875315445,
    limits=Limits(max_acceleration=15.519850020351807, max_jerk=352.50828660284446),
)
# The answer's durations (s), rounded to 1e-4: a start the size of a repair's notch away from the optimum.
START = [0.0354, 0.0619, 0.0082, 0.0115, 0.0240, 0.0003, 0.0061]
TRAIN = [1.0, -1.0, 1.0, -1.0, 1.0, -1.0, 1.0]
# bench/time_optimal_speed.py's three-mode move 13 (three modes in one transfer function, each 1.5-4 times faster
# than the one before; a held acceleration): its proven answer is the 10-arc bang train +-+-+-+-+- (8 end
# conditions), found after the LP search.
THREE_MODES = Problem(
    plant=TransferFunctionPlant(
        numerator=(156552.92779907322, 786733281.0667441, 1210061737839.6658, 583471084684335.9),
        denominator=(
            1.0,
            398.22733372456486,
            987829.7450822078,
            76277381.30437633,
            67024368581.999146,
            1210061737839.6658,
            583471084684335.9,
        ),
    ),
    displacement=0.025120112584705184,
    limits=Limits(max_acceleration=2.137437820454822),
)
THREE_START = [0.1007, 0.0115, 0.0067, 0.0199, 0.0023, 0.0730, 0.0011, 0.0051, 0.0004, 0.0017]
CASES = {
    "held jerk, one mode": (MOVE_3, START, TRAIN, None),
    "held acceleration, three modes": (THREE_MODES, THREE_START, [1.0, -1.0] * 5, (0, 1, 2)),
}


def _spec(problem: Problem, modes: tuple[int, ...] | None = None) -> Spec:
    options = TimeOptimalOptions(modes=modes)
    return spec_of(problem, options, selected_modes(problem, options)[0])


@pytest.mark.parametrize("case", list(CASES))
def test_the_bang_train_is_slsqps_proven_answer(case: str) -> None:
    """Both methods from the same start: the same duration to 1e-12 and the same switching times to 1e-6 of it, and
    the certificate proves the Newton's command. (The duration is flat at the optimum: SLSQP, stopping at ftol 1e-10,
    leaves the switching times ~1e-9 s from the point where the conditions hold, which costs ~1e-16 of duration;
    the Newton solves those conditions to round-off.)"""
    problem, start, train, modes = CASES[case]
    spec = _spec(problem, modes)
    slsqp = refine(spec, start, train, [False] * len(train), [])
    assert slsqp is not None
    assert certificate(spec, merged(slsqp.arcs)) is not None  # the reference is itself proven
    arcs = shoot(spec, start, train)
    assert arcs is not None
    assert certificate(spec, merged(arcs)) is not None
    expected = np.array([a.duration_s for a in slsqp.arcs])
    got = np.array([a.duration_s for a in arcs])
    assert got.sum() == pytest.approx(expected.sum(), rel=1e-12)
    assert got == pytest.approx(expected, abs=1e-6 * expected.sum())
    assert [a.level for a in arcs] == [a.level for a in slsqp.arcs]


def test_only_bang_trains_with_more_arcs_than_end_conditions() -> None:
    """A rest (a level 0) is not a bang train, and 5 arcs for 5 end conditions are a square system on the
    durations alone (refine.newton's): neither is shot."""
    spec = _spec(MOVE_3)
    assert shoot(spec, [0.03, 0.02, 0.05, 0.02, 0.03], [1.0, 0.0, -1.0, 0.0, 1.0]) is None
    assert shoot(spec, START[:5], TRAIN[:5]) is None


def test_move_3s_design_is_proven_by_the_bang_trains_newton() -> None:
    """The whole design of move 3 (the pipeline) ends in a chain whose repaired bang train the Newton solves and the
    certificate proves: its note says so. Without the step in the chain, SLSQP proves the same command and the note
    names SLSQP instead."""
    summary = synthesize(FAMILIES["time_optimal"], MOVE_3, TimeOptimalOptions()).summary
    assert isinstance(summary, TimeOptimalReport)
    note = summary.refinement
    assert "Newton on the switching times and the multipliers (Pontryagin's conditions)" in note
    assert "certifies it the minimum-time command" in note
    assert summary.duration_s == pytest.approx(sum(START), rel=1e-3)  # the answer START was rounded from


def test_a_command_with_a_nan_duration_meets_no_limit() -> None:
    """limits_met on arcs of a NaN duration: every comparison with NaN is False, so the check must refuse them
    itself (exact_peaks' end position is NaN)."""
    spec = _spec(MOVE_3)
    arcs = (Arc(0.0, 0.01, spec.scale), Arc(0.01, math.nan, -spec.scale))
    assert not limits_met(MOVE_3, spec, arcs)
