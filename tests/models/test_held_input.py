"""models.held_input: a base-excited mode's response to a piecewise-constant input with switches between samples.

References nobody here wrote: the step response in closed form (1 - e^(-s t) (cos w_d t - s / w_d sin w_d t) for
G(s) = (2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2)), scipy's zero-order-hold discretisation (cont2discrete, in
tests/printer_records.toolhead) where the switches fall on the samples, and the same hold on a grid m times finer
where they do not: its error is the switches' rounding to that grid, so it falls as 1/m.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from models.errors import InvalidParameter
from models.held_input import base_excited_response
from tests.printer_records import toolhead

RATE_HZ = 1000.0
F_HZ, ZETA = 23.0, 0.08


def test_a_step_from_rest_is_the_closed_form_step_response():
    t = np.arange(500) / RATE_HZ
    w = 2 * math.pi * F_HZ
    s, wd = ZETA * w, w * math.sqrt(1 - ZETA**2)
    closed = 1.0 - np.exp(-s * t) * (np.cos(wd * t) - s / wd * np.sin(wd * t))
    got = base_excited_response(F_HZ, ZETA, RATE_HZ, np.array([0.0]), np.array([1.0]), t.size)
    assert got == pytest.approx(closed, abs=1e-12)  # both exact: rounding only


def test_switches_on_the_samples_are_scipys_zero_order_hold():
    rng = np.random.default_rng(3)
    levels = rng.normal(0.0, 1.0, 40)
    times = np.sort(rng.choice(np.arange(1, 600), 39, replace=False)) / RATE_HZ
    times = np.concatenate([[0.0], times])
    held = levels[np.searchsorted(times, np.arange(600) / RATE_HZ, side="right") - 1]
    expected = toolhead(held, RATE_HZ, ((F_HZ, ZETA, 1.0),))
    got = base_excited_response(F_HZ, ZETA, RATE_HZ, times, levels, 600)
    assert got == pytest.approx(expected, abs=1e-12 * np.max(np.abs(expected)))


def test_switches_between_samples_are_the_limit_of_a_finer_hold():
    rng = np.random.default_rng(5)
    times = np.concatenate([[0.0], np.sort(rng.uniform(0.0, 0.3, 30))])
    levels = rng.normal(0.0, 1.0, times.size)
    exact = base_excited_response(F_HZ, ZETA, RATE_HZ, times, levels, 400)
    errors = []
    for m in (16, 64, 256):
        fine = np.arange(400 * m) / (RATE_HZ * m)
        held = levels[np.searchsorted(times, fine, side="right") - 1]
        errors.append(np.max(np.abs(toolhead(held, RATE_HZ * m, ((F_HZ, ZETA, 1.0),))[::m] - exact)))
    # the finer hold's switches move by under 1/m of a sample: its error falls as 1/m (x4 per step, within 2x)
    assert errors[0] / errors[1] == pytest.approx(4.0, rel=0.5)
    assert errors[1] / errors[2] == pytest.approx(4.0, rel=0.5)
    assert errors[2] < 2e-3 * np.max(np.abs(exact))


def test_an_overdamped_mode_is_refused():
    with pytest.raises(InvalidParameter, match="zeta < 1"):
        base_excited_response(F_HZ, 1.0, RATE_HZ, np.array([0.0]), np.array([1.0]), 10)
