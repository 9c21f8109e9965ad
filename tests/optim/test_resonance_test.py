"""optim.identification.resonance_test: Klipper's resonance test command (resonance_tester.py at 84104bbbd), against
tests/printer_records.chirp_switches (written separately from the same source) and gen_test's own numbers."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from models.errors import InvalidParameter
from optim.identification.resonance_test import (
    ResonanceTest,
    command_samples,
    command_switches,
    start_in_record,
    vibration_levels,
)
from tests.printer_records import chirp, chirp_switches, held_record


def test_the_vibration_follows_gen_test():
    ends, levels = vibration_levels(ResonanceTest())
    # the first quarter period at 5 Hz: 1/20 s at +60 x 5 mm/s^2, then -300; f then rises by 1 Hz/s x 1/10 s
    assert (ends[0], levels[0], levels[1]) == pytest.approx((0.05, 300.0, -300.0))
    assert 1.0 / (ends[3] - ends[1]) == pytest.approx(2.0 * 5.1, rel=1e-12)  # the next half period is at 5.1 Hz
    assert ends[-1] == pytest.approx(ResonanceTest().duration_s, abs=0.01)  # (135 - 5) / 1 s, to the last period


def test_the_sweeping_overlay_flips_where_klipper_flips_it():
    test = ResonanceTest(max_freq_hz=20.0)
    times, level, _ = command_switches(test, 3200.0)
    bare, bare_level, _ = command_switches(ResonanceTest(max_freq_hz=20.0, sweeping_period_s=0.0), 3200.0)
    flips = np.setdiff1d(times, bare)
    first = 1.2 * math.sqrt(2.0) / 8.0  # sweeping_period x accel_fraction
    assert flips[:3] == pytest.approx([first, first + 1.2 * (math.sqrt(2.0) / 8.0 + 0.25), 2 * first + 0.3 + 0.6])
    overlay = (level - bare_level[np.searchsorted(bare, times, side="right") - 1])[:-1]  # the last: at rest
    assert overlay[0] == pytest.approx(400.0) and np.unique(np.round(overlay)).tolist() == [-400.0, 400.0]
    assert level[-1] == 0.0 == bare_level[-1]


@pytest.mark.parametrize("sweeping_period", [0.0, 1.2, 0.37])
def test_the_switches_match_an_implementation_written_apart(sweeping_period):
    test = ResonanceTest(min_freq_hz=5.0, max_freq_hz=60.0, sweeping_period_s=sweeping_period)
    times, level, samples = command_switches(test, 3200.0)
    assert level[-1] == 0.0 and times[-1] == pytest.approx(samples / 3200.0, abs=1 / 3200.0)  # at rest after
    times, level = times[:-1], level[:-1]
    other, other_level, end = chirp_switches(
        5.0, 60.0, sweeping_accel=400.0 * (sweeping_period > 0), sweeping_period=sweeping_period
    )
    assert times == pytest.approx(other, abs=1e-9) and level == pytest.approx(other_level, abs=1e-9)
    assert samples == int(end * 3200.0)


def test_the_sampled_command_holds_each_samples_level():
    test = ResonanceTest(max_freq_hz=60.0, sweeping_period_s=0.0)
    assert command_samples(test, 1600.0) == pytest.approx(chirp(1600.0, 5.0, 60.0), abs=0.0)


def test_a_test_too_long_to_simulate_is_refused_naming_the_rate():
    with pytest.raises(InvalidParameter, match="at most") as caught:
        command_switches(ResonanceTest(min_freq_hz=1.0, max_freq_hz=300.0, hz_per_sec=0.1), 3200.0)
    assert caught.value.field == "sweep_hz_per_sec"


def test_the_test_starts_where_the_record_says():
    """A test starting 0.3 s into its record is the same switches 0.3 s later, at rest before; one that started
    0.3 s before the record holds at the record's start the level in force then."""
    test = ResonanceTest(max_freq_hz=20.0)
    times, level, _ = command_switches(test, 1000.0)
    late, late_level, late_samples = command_switches(replace(test, start_s=0.3), 1000.0, samples=30_000)
    assert late[0] == 0.0 and late_level[0] == 0.0 and late_samples == 30_000
    assert late[1:] == pytest.approx(times + 0.3) and late_level[1:] == pytest.approx(level)
    early, early_level, _ = command_switches(replace(test, start_s=-0.3), 1000.0)
    inside = np.searchsorted(times, 0.3, side="right")
    assert early[0] == 0.0 and early_level[0] == level[inside - 1]
    assert early[1:] == pytest.approx(times[inside:] - 0.3) and early_level[1:] == pytest.approx(level[inside:])


def test_the_tests_start_in_its_record_is_found_to_a_few_milliseconds():
    """A 35-80 Hz test at 2 Hz/s (tests/printer_records.held_record, 150 mm/s^2 of noise) recorded from its start,
    from 0.5 s before it (Klipper's accelerometer starts first) and from 0.2 s into it: the cross-correlation with
    the command finds each start within 10 ms (the modes' delay near resonance is a few ms; the ridge's line, 30
    times coarser, is off by about 0.1 s)."""
    test = ResonanceTest(min_freq_hz=35.0, max_freq_hz=80.0, hz_per_sec=2.0, sweeping_period_s=0.0)
    rate = 1600.0
    table = held_record(chirp_switches(35.0, 80.0, hz_per_sec=2.0), np.random.default_rng(3), rate_hz=rate)
    signals = table[:, 1:].T
    rest = np.random.default_rng(4).normal(0.0, 150.0, (3, 800))
    for record, start in ((signals, 0.0), (np.hstack([rest, signals]), 0.5), (signals[:, 320:], -0.2)):
        assert start_in_record(record, rate, test) == pytest.approx(start, abs=0.01)
