"""The time-optimal oracle (tests/time_optimal_oracle.py) checked on its own, before it judges the family.

Expected values: the known answer (40 Hz, a = 10, v = 5, D = 0.12 -> 219.7077 ms, arcs 104.03 / 5.83 / 5.83 /
104.03 ms, Singh & Vadali 1993's symmetric three-switch structure); the residual by an independent simulation
(scipy.signal.lsim of w^2 / (s^2 + w^2)); and the two brackets any zero-residual minimum time must sit in: no
faster than the rigid minimum time, and faster than the rigid command convolved with ZV (+ half a period),
itself a zero-residual command.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from tests.time_optimal_oracle import (
    KNOWN,
    OutOfRange,
    coast_structure_upper_bound,
    coast_upper_bound,
    minimum_time,
    minimum_time_command,
    pmp_check,
    position_at_end,
    residual_by_quadrature,
    rigid_minimum_time,
    self_test,
)

W_KNOWN = 2 * math.pi * KNOWN["frequency_hz"]


def test_self_test_passes() -> None:
    self_test()


def test_known_answer() -> None:
    bang = minimum_time_command(W_KNOWN, KNOWN["a"], KNOWN["v"], KNOWN["d"])
    assert bang.duration_s == pytest.approx(0.2197077, rel=1e-4)
    assert [1e3 * x for x in bang.durations_s] == pytest.approx([104.03, 5.83, 5.83, 104.03], abs=6e-3)
    assert bang.levels == (10.0, -10.0, 10.0, -10.0)
    assert pmp_check(bang, W_KNOWN)


def _motor_position(times: np.ndarray, switches: list[float], levels: list[float]) -> np.ndarray:
    """Exact motor position of the piecewise-constant acceleration, evaluated at ``times`` (held after the end)."""
    p = np.zeros_like(times)
    p0 = v0 = 0.0
    for k, level in enumerate(levels):
        lo, hi = switches[k], switches[k + 1]
        inside = (times >= lo) & (times < hi)
        h = times[inside] - lo
        p[inside] = p0 + v0 * h + 0.5 * level * h * h
        p0, v0 = p0 + v0 * (hi - lo) + 0.5 * level * (hi - lo) ** 2, v0 + level * (hi - lo)
    p[times >= switches[-1]] = p0
    return p


def test_residual_vanishes_by_lsim() -> None:
    """lsim's first-order hold of the motor position is exact for piecewise-linear input; the position is
    piecewise quadratic, so the hold is off by at most a h^2 / 8 inside a sample. That error is a smooth offset
    (mean a h^2 / 12) whose jumps at the 5 acceleration steps (each at most 2a h^2 / 12) excite the mode; with
    h = 10 us the residual it adds is below 5 x 2 x 10 x 1e-10 / 12 ~ 1e-9, far under the 1e-6 x D = 1.2e-7
    asserted, while an error of one part in 1e3 of the arcs would leave ~1e-5 (checked below)."""
    bang = minimum_time_command(W_KNOWN, KNOWN["a"], KNOWN["v"], KNOWN["d"])
    switches, levels = bang.command()
    period = 2 * math.pi / W_KNOWN
    h = 1e-5
    t = np.arange(0.0, bang.duration_s + 3 * period, h)
    system = signal.lti([W_KNOWN**2], [1.0, 0.0, W_KNOWN**2])

    def residual(sw: list[float]) -> float:
        _, y, _ = signal.lsim(system, _motor_position(t, sw, levels), t)
        after = t > sw[-1]
        return float(np.max(np.abs(y[after] - _motor_position(t[after], sw, levels))))

    assert residual(switches) < 1e-6 * KNOWN["d"]
    perturbed = [s * (1 + 1e-3) for s in switches]  # a wrong answer must be visible to this check
    assert residual(perturbed) > 1e-5 * KNOWN["d"]


def test_residual_by_quadrature_and_end_state() -> None:
    for hz, a, d in [(40.0, 10.0, 0.12), (2.0, 3.0, 0.5), (10.0, 1.0, 0.01)]:
        w = 2 * math.pi * hz
        bang = minimum_time_command(w, a, None, d)
        switches, levels = bang.command()
        p, v = position_at_end(switches, levels)
        assert p == pytest.approx(d, rel=1e-12)
        assert abs(v) < 1e-12 * a * bang.duration_s
        assert residual_by_quadrature(switches, levels, w) < 1e-10 * d


@pytest.mark.parametrize("periods", [0.3, 0.8, 1.5, 2.5, 5.3, 10.0])
def test_between_rigid_and_zv(periods: float) -> None:
    """Rigid minimum <= the zero-residual minimum < rigid + half a period (the ZV-shaped rigid command ends
    then and leaves no residual, so a slower 'optimum' would be wrong)."""
    hz, a = 5.0, 2.0
    w = 2 * math.pi * hz
    d = a * (periods / hz / 2) ** 2  # rigid bang-bang lasting `periods` periods
    rigid = rigid_minimum_time(a, None, d)
    t = minimum_time(w, a, None, d)
    assert rigid * (1 - 1e-12) <= t < rigid + 0.5 / hz
    assert rigid == pytest.approx(periods / hz)


def test_signed_move_and_rigid_times() -> None:
    bang = minimum_time_command(W_KNOWN, 10.0, None, -0.12)
    assert bang.levels[0] < 0
    assert bang.duration_s == pytest.approx(0.2197077, rel=1e-4)
    assert rigid_minimum_time(10.0, 5.0, 0.12) == pytest.approx(2 * math.sqrt(0.012))
    assert rigid_minimum_time(10.0, 0.5, 0.12) == pytest.approx(0.12 / 0.5 + 0.05)


def test_coast_is_out_of_range() -> None:
    with pytest.raises(OutOfRange, match="velocity limit"):
        minimum_time(W_KNOWN, 10.0, 0.5, 0.12)


def test_velocity_limited_upper_bound_is_feasible() -> None:
    """Where the velocity limit is active the oracle gives only a feasible bound: it must end at rest at D,
    leave no residual, never exceed the limits, and lie between the rigid minimum and the tuned trapezoid."""
    w, a, v, d = W_KNOWN, 10.0, 0.5, 0.12
    bang = coast_structure_upper_bound(w, a, v, d, points=41)
    assert bang is not None
    switches, levels = bang.command()
    p, vel = position_at_end(switches, levels)
    assert p == pytest.approx(d, rel=1e-12) and abs(vel) < 1e-12
    assert residual_by_quadrature(switches, levels, w) < 1e-10 * d
    assert max(abs(x) for x in levels) <= a
    speeds = np.cumsum([h * x for h, x in zip(bang.durations_s, levels, strict=True)])
    assert np.max(np.abs(speeds)) <= v * (1 + 1e-9)
    assert rigid_minimum_time(a, v, d) <= bang.duration_s
    assert bang.duration_s <= coast_upper_bound(w, a, v, d)  # here the structure beats the tuned trapezoid
