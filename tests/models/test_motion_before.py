"""A command that continues a motion (PiecewiseCommand.motion_before): the load starts quasi-static in it, so the
exact simulation (models.simulation) equals scipy's lsim run over a long history of that motion before t_0."""

from __future__ import annotations

import numpy as np
from scipy import signal

from models.commands import PiecewiseCommand
from models.plants import ModePlant
from models.simulation import simulate


def test_a_command_in_motion_starts_its_load_quasi_static() -> None:
    """3 Hz, zeta 0.2: 10 s of the polynomial motion (p, v, a) = (0.1, 0.2, 0.5) before t_0 leave a free response
    of exp(-0.2 * 2 pi 3 * 10) = 4e-17 of the start's; lsim holds the 2e-5 s samples linearly, which errs by
    h^2 / 8 max|p''| (about 3e-11 here): the tolerance 1e-10."""
    hz, zeta = 3.0, 0.2
    command = PiecewiseCommand.from_held_steps([0.0, 0.5, 1.5], [-2.0, 0.0, 0.0], 3, initial=(0.1, 0.2, 0.5))
    assert command.motion_before == (0.2, 0.5)
    ours = simulate(ModePlant(hz, zeta), command).load_position
    w = 2 * np.pi * hz
    dt = 2e-5
    before = -dt * np.arange(500_000, 0, -1)
    after = dt * np.arange(75_001)
    position = np.concatenate([0.1 + 0.2 * before + 0.5 * before**2 / 2, command.evaluate(0, after)])
    time = np.concatenate([before, after])
    _, load, _ = signal.lsim(([2 * zeta * w, w * w], [1, 2 * zeta * w, w * w]), position, time - time[0])
    assert np.max(np.abs(ours - np.interp(command.time_s, time, load))) < 1e-10


def test_a_steady_motion_continued_leaves_no_vibration() -> None:
    """Constant velocity before and after t_0: no derivative jumps, so the load has no free response at all."""
    command = PiecewiseCommand.from_held_steps([0.0, 1.0], [0.0, 0.0], 2, initial=(0.0, 0.7))
    response = simulate(ModePlant(5.0, 0.0), command)
    assert np.all(response.free_amplitudes(1) == 0.0)
    assert response.load_position[-1] == 0.7
