"""The refined commands' closed-form peaks (optim.families.time_optimal.arcs.exact_peaks), which the family's exact
limit check uses, against the general piecewise-polynomial command's peaks (models.commands.PiecewiseCommand
.peak_abs: the derivative's roots inside every piece) and a hand-computed case."""

from __future__ import annotations

import numpy as np
import pytest

from optim.families.time_optimal.arcs import command_of, exact_peaks
from optim.families.time_optimal.types import Arc

SEED = 20261205
# Both integrate the same steps by cumulative sums over at most 30 arcs of O(1) values: they agree to ~1e-15; 1e-12
# leaves room for the different order of their operations and still fails on any wrong term (O(1) errors).
RTOL = 1e-12


def _arcs(durations: np.ndarray, levels: np.ndarray) -> tuple[Arc, ...]:
    starts = np.concatenate(([0.0], np.cumsum(durations)[:-1]))
    return tuple(Arc(float(s), float(d), float(lv)) for s, d, lv in zip(starts, durations, levels, strict=True))


def test_a_velocity_peak_inside_an_arc_is_found() -> None:
    """Jerk +1, -1 (2 s), +1 from rest: the acceleration 1 at t = 1 crosses 0 at t = 2, inside the second arc, where
    the velocity peaks at the area under the acceleration's triangle, 1; at every arc end it is 0.5 or 0, and the
    move ends at 2 (the velocity's area, a triangle-of-triangles: 1/6 + 5/6 + 5/6 + 1/6)."""
    peaks = exact_peaks(_arcs(np.array([1.0, 2.0, 1.0]), np.array([1.0, -1.0, 1.0])), 3)
    assert peaks.velocity == pytest.approx(1.0, rel=1e-15)
    assert peaks.acceleration == pytest.approx(1.0, rel=1e-15)
    assert peaks.jerk == 1.0
    assert peaks.end_position == pytest.approx(2.0, rel=1e-15)


@pytest.mark.parametrize("order", [2, 3])
def test_exact_peaks_are_the_general_commands_peaks(order: int) -> None:
    """Random arcs (bang, coast and fractional levels, 1 to 30 of them) from rest and from motion: every peak and
    the end position as PiecewiseCommand's."""
    rng = np.random.default_rng(SEED + order)
    inside = 0
    for _ in range(200):
        count = int(rng.integers(1, 31))
        durations = rng.uniform(0.01, 0.5, count)
        levels = rng.choice([-1.0, 0.0, 1.0, 0.37, -0.6], count) * rng.uniform(0.5, 20.0)
        initial = (0.0, *rng.uniform(-1.0, 1.0, order - 1)) if rng.random() < 0.5 else ()
        arcs = _arcs(durations, levels)
        command = command_of(arcs, order, True, initial)
        peaks = exact_peaks(arcs, order, initial)
        velocity = command.peak_abs(1)
        assert velocity is not None
        assert peaks.velocity == pytest.approx(velocity, rel=RTOL)
        assert peaks.acceleration == pytest.approx(command.peak_abs(2), rel=RTOL)
        scale = float(np.max(np.abs(command.derivatives[0])))
        assert peaks.end_position == pytest.approx(command.derivatives[0, -1], rel=RTOL, abs=RTOL * scale)
        if order == 3:
            assert peaks.jerk == pytest.approx(command.peak_abs(3), rel=RTOL)
            inside += velocity > np.max(np.abs(command.derivatives[1])) * (1 + 1e-9)
        else:
            assert peaks.jerk is None
    assert order == 2 or inside > 20  # the velocity's peak inside an arc is exercised, not only its ends
