"""A sweep told from a free decay (optim.identification.excitation) on tests/printer_records.py's records: the
issue's axis (42 and 71 Hz) at 3200 Hz, 150 mm/s^2 of noise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from optim.identification.excitation import MIN_DISTINCT, excitation_of, sweep_band
from tests.optim.test_identification_modal import accelerometer_record
from tests.printer_records import RATE_HZ, chirp, chirp_switches, held_record, knock, raw_record, sweep_table


@pytest.mark.parametrize(("start", "end", "rate"), [(5.0, 135.0, 1.0), (25.0, 95.0, 5.0), (95.0, 25.0, -5.0)])
def test_a_resonance_test_is_a_sweep(start, end, rate):
    """Klipper's chirp (and one falling: the rank correlation's sign does not matter)."""
    command = chirp(RATE_HZ, start, end, hz_per_sec=rate) if rate > 0 else chirp(RATE_HZ, end, start, -rate)[::-1]
    table = raw_record(command, np.random.default_rng(1))
    assert excitation_of(table[:, 1:].T, RATE_HZ) == "sweep"


def test_decays_and_noise_are_not():
    rng = np.random.default_rng(2)
    knocked = raw_record(knock(RATE_HZ, 10.0), rng)
    assert excitation_of(knocked[:, 1:].T, RATE_HZ) == "free_decay"
    assert excitation_of(rng.normal(0.0, 1.0, (3, 32_000)), RATE_HZ) == "free_decay"
    _, signals = accelerometer_record(seed=3)  # 2 s at 2 kHz: too short to tell (4 segments): a free decay
    assert excitation_of(signals, 2000.0) == "free_decay"


def test_a_decay_stepping_from_mode_to_mode_is_not_a_sweep():
    """A record whose dominant frequency steps 150 -> 90 -> 60 -> 40 Hz, 3 s each (modes taking turns as the faster
    ones decay): a monotone trend of the peak (rank correlation -0.94: a sweep by that alone), through 4 values,
    fewer than a sweep's MIN_DISTINCT."""
    t = np.arange(int(12 * RATE_HZ)) / RATE_HZ
    frequency = np.select([t < 3, t < 6, t < 9], [150.0, 90.0, 60.0], 40.0)
    y = np.cos(2 * math.pi * frequency * t) + np.random.default_rng(3).normal(0.0, 1e-3, t.size)
    assert excitation_of(y[None, :], RATE_HZ) == "free_decay"
    assert MIN_DISTINCT > 4


def test_a_sweep_of_constant_power_is_a_sweep():
    """A chirp through no resonance (every segment as loud: "live" is a tone above its own segment's floor, not a
    segment louder than the record's quietest)."""
    t = np.arange(int(12 * RATE_HZ)) / RATE_HZ
    phase = 2 * math.pi * np.cumsum(20.0 + 5.0 * t) / RATE_HZ
    assert excitation_of(np.cos(phase)[None, :], RATE_HZ) == "sweep"


def test_a_sweeps_band_and_rate_are_read_off_its_ridge():
    """Klipper's test from 5 to 200 Hz at 1 Hz/s (tests/printer_records.sweep_table, noise up to 30 %), and 35-80 Hz
    at 2 Hz/s: the Theil-Sen line through the ridge at the record's ends gives the band within a ridge bin (2 Hz at
    0.5 s segments, its median within 1 Hz) and the rate to 1 %."""
    for seed in range(4):
        _, _, table = sweep_table(seed)
        start, end, rate = sweep_band(table[:, 1:].T, RATE_HZ)
        assert (start, end, rate) == pytest.approx((5.0, 200.0, 1.0), abs=1.0, rel=0.01)
    table = held_record(chirp_switches(35.0, 80.0, hz_per_sec=2.0), np.random.default_rng(1), rate_hz=1600.0)
    assert sweep_band(table[:, 1:].T, 1600.0) == pytest.approx((35.0, 80.0, 2.0), abs=1.0, rel=0.01)
    falling = raw_record(chirp(RATE_HZ, 25.0, 95.0, hz_per_sec=5.0)[::-1], np.random.default_rng(1))
    assert sweep_band(falling[:, 1:].T, RATE_HZ) is None  # not Klipper's test: no band read
