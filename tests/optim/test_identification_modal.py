"""Modes from a measured record (optim.identification.modal, optim.identification.record_csv): frequencies, dampings
and their 95 % intervals.

The record is synthesised, so the truth is known: a three-axis accelerometer on a structure with two modes,
23 Hz (zeta 0.03) and 61 Hz (zeta 0.05), each seen by every axis with its own gain and phase, an offset per
axis (gravity on z), sampled at 2 kHz for 2 s, with white Gaussian noise of std 0.02 on every axis: the
modes' initial amplitudes (0.2 to 1.0) are 10 to 50 times the noise (20 to 34 dB SNR).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import welch

from models.errors import InvalidParameter
from optim.identification.modal import identify_modes
from optim.identification.record import Record, uniform_record
from optim.identification.record_csv import parse_record_csv

TRUTH = ((23.0, 0.03), (61.0, 0.05))  # (f_n Hz, zeta)
RATE_HZ = 2000.0
DURATION_S = 2.0
NOISE_STD = 0.02
GAINS = np.array([[1.0, 0.4], [0.5, 1.0], [0.2, 0.3]])  # axis x, y, z by mode
PHASES = np.array([[0.3, 1.1], [0.9, -0.4], [-1.2, 2.0]])
OFFSETS = np.array([0.0, 0.1, 9.81])
NAMES = ("accel_x", "accel_y", "accel_z")


def free_vibration(t: np.ndarray) -> np.ndarray:
    """(3, n): the noise-free accelerations, sum over modes of G e^(-zeta wn t) cos(wd t + phi), plus offsets."""
    out = np.tile(OFFSETS[:, None], (1, t.size))
    for k, (f, zeta) in enumerate(TRUTH):
        wn = 2 * math.pi * f
        wd = wn * math.sqrt(1 - zeta**2)
        out += GAINS[:, k : k + 1] * np.exp(-zeta * wn * t) * np.cos(wd * t + PHASES[:, k : k + 1])
    return out


def accelerometer_record(seed: int, rate_hz: float = RATE_HZ, duration_s: float = DURATION_S):
    rng = np.random.default_rng(seed)
    t = np.arange(round(rate_hz * duration_s)) / rate_hz
    return t, free_vibration(t) + NOISE_STD * rng.standard_normal((3, t.size))


def to_csv(t: np.ndarray, signals: np.ndarray, names=NAMES, time_name: str = "time_s") -> str:
    rows = np.column_stack([t, signals.T])
    lines = [",".join([time_name, *names])]
    lines += [",".join(f"{v:.10g}" for v in row) for row in rows]
    return "\n".join(lines) + "\n"


def test_two_modes_from_an_accelerometer_csv_within_1_percent_and_their_intervals_cover_the_truth():
    t, signals = accelerometer_record(seed=7)
    record = parse_record_csv(to_csv(t, signals), max_rows=10_000)
    assert record.names == NAMES
    result = identify_modes(record)
    assert len(result.modes) == 2
    for mode, (f, zeta) in zip(result.modes, TRUTH, strict=True):
        # the acceptance: within 1 % (the standard errors are 0.01 % and 0.05 % of f: far inside it)
        assert mode.natural_frequency_hz == pytest.approx(f, rel=0.01)
        lo, hi = mode.natural_frequency_ci_hz
        assert lo <= f <= hi
        lo, hi = mode.damping_ratio_ci
        assert lo <= zeta <= hi
        assert mode.damping_ratio == pytest.approx(zeta, rel=0.05)  # SE ~ 0.4 % and 1 % of zeta
    assert result.r_squared > 0.9
    assert result.noise_rms == pytest.approx([NOISE_STD] * 3, rel=0.05)  # the residual is the noise
    # the offset's standard error is about noise / sqrt(samples) = 3e-4: 5 of them
    assert result.offsets == pytest.approx(OFFSETS.tolist(), abs=5 * NOISE_STD / math.sqrt(t.size))
    assert result.t_quantile == pytest.approx(1.96, abs=1e-3)  # Student t at ~12 000 dof
    assert result.spectrum.psd.size <= 2049
    assert result.warnings == ()


def test_the_fit_agrees_with_an_independent_welch_peak_within_a_bin():
    # scipy's welch on the raw record (not the service's spectrum): its peak near each mode is within one
    # bin (fs / nperseg) of the fitted damped frequency, and the fitted natural frequency of the truth.
    t, signals = accelerometer_record(seed=11)
    result = identify_modes(Record(t, signals, NAMES))
    nperseg = 4000
    f, psd = welch(signals, fs=RATE_HZ, window="boxcar", nperseg=nperseg, axis=-1)
    total = psd.sum(axis=0)
    bin_hz = RATE_HZ / nperseg
    for mode, (truth, _) in zip(result.modes, TRUTH, strict=True):
        near = (f > truth - 5) & (f < truth + 5)
        peak = float(f[near][np.argmax(total[near])])
        assert abs(peak - mode.damped_frequency_hz) <= bin_hz  # the PSD peaks at the damped frequency
        assert abs(peak - truth) <= bin_hz + truth * 0.05**2  # wd = wn sqrt(1 - zeta^2): <= 0.13 % below
        assert mode.peak_frequency_hz == pytest.approx(peak, abs=bin_hz)


def test_a_single_signal_record_and_a_known_command():
    # The response to a known command: a ramp of the command, then rest; the free vibration is fitted from
    # where the command last changes (its samples before hold the forced response, which the model lacks).
    rng = np.random.default_rng(5)
    t = np.arange(3000) / RATE_HZ
    end = 0.5
    command = np.clip(t / end, 0.0, 1.0)
    forced = np.where(t < end, np.sin(2 * math.pi * 4 * t) * 3.0, 0.0)  # anything: it is cut away
    f, zeta = TRUTH[0]
    wn = 2 * math.pi * f
    tail = np.where(t >= end, np.exp(-zeta * wn * (t - end)) * np.cos(wn * math.sqrt(1 - zeta**2) * (t - end)), 0.0)
    y = forced + tail + NOISE_STD * rng.standard_normal(t.size)
    record = Record(t, y[None, :], ("load",), command, "command")
    result = identify_modes(record)
    assert result.window_source == "command_end"
    assert result.window_start_s == pytest.approx(end, abs=1.0 / RATE_HZ)
    (mode,) = result.modes
    assert mode.natural_frequency_ci_hz[0] <= f <= mode.natural_frequency_ci_hz[1]
    assert mode.damping_ratio_ci[0] <= zeta <= mode.damping_ratio_ci[1]


def test_quoted_cells_read_as_the_plain_record():
    # Plain numbers go through numpy's reader, a quoted cell through the csv module: the same record either way.
    t, signals = accelerometer_record(seed=7)
    plain = to_csv(t, signals)
    lines = plain.splitlines()
    time_cell, rest = lines[1].split(",", 1)
    quoted = "\n".join([lines[0], f'"{time_cell}",{rest}', *lines[2:]]) + "\n"  # the first data row's time quoted
    a, b = parse_record_csv(plain, max_rows=10_000), parse_record_csv(quoted, max_rows=10_000)
    np.testing.assert_array_equal(a.time_s, b.time_s)
    np.testing.assert_array_equal(a.signals, b.signals)


def test_csv_rules_name_the_column_and_row():
    good = "time_s,accel_x\n0,1\n0.001,2\n0.002,3\n"
    assert parse_record_csv(good, max_rows=10).signals.shape == (1, 3)
    # Klipper-style header (a leading '#') and comment lines
    record = parse_record_csv("#time,accel_x,accel_y\n# a comment\n0,1,2\n0.001,2,3\n", max_rows=10)
    assert record.names == ("accel_x", "accel_y")
    cases = [
        ("time_s,accel_x\n0,1\n0.001,abc\n", "accel_x[1]", "number"),
        ("time_s,accel_x\n0,1\n0.001,2,3\n", "row[1]", "fields"),
        ("time_s,accel_x\n0,1\n0.001,nan\n", "accel_x[1]", "finite"),
        ("time_s,accel_x\n0,1\n0,2\n", "time_s[1]", "increase"),
        ("0,1\n0.001,2\n", "header", "header"),
        ("time_s\n0\n1\n", "header", "signal"),
        ("time_s,a,a\n0,1,1\n1,2,2\n", "header", "unique"),
        ("", "body", "empty"),
        ("time_s,accel_x\n" + "0,1\n" * 11, "body", "at most 10"),
        ("t," + ",".join(f"s{i}" for i in range(17)) + "\n" + ",".join(["0"] * 18) + "\n", "header", "at most 16"),
    ]
    for text, field, words in cases:
        with pytest.raises(InvalidParameter) as info:
            parse_record_csv(text, max_rows=10)
        assert info.value.field == field, (text, info.value)
        assert words in info.value.rule, (text, info.value.rule)


def test_jitter_is_interpolated_and_a_gap_refused():
    t = np.arange(100) * 1e-3
    jittered = t + np.r_[0.0, 1e-5 * np.sin(np.arange(1, 100))]
    dt, _, resampled = uniform_record(jittered, np.sin(t)[None, :])
    assert resampled and dt == pytest.approx(1e-3, rel=1e-3)
    gap = np.r_[t[:50], t[50:] + 0.01]
    with pytest.raises(InvalidParameter) as info:
        uniform_record(gap, np.zeros((1, 100)))
    assert info.value.field == "time_s[50]" and "gap" in info.value.rule


def test_rounded_timestamps_are_a_uniform_record():
    """Klipper's ACCELEROMETER_MEASURE prints times as %.6f: at 3200 Hz the steps read 312 and 313 us (their median,
    313 us, is 3194.9 Hz; the issue saw 3205.13 Hz). Each printed time is within 0.5 us of the true grid, so the
    record is the uniform one, its period the least-squares slope: its error is about 0.29 us sqrt(12 / n^3) =
    4e-13 s for n = 12,800 (1e-9 relative; bound 1e-7), and nothing is interpolated."""
    rate = 3200.0
    t = 1234.567891 + np.arange(12_800) / rate
    printed = np.array([float(f"{x:.6f}") for x in t])
    dt, _, resampled = uniform_record(printed, np.sin(t)[None, :])
    assert not resampled and dt == pytest.approx(1 / rate, rel=1e-7)
    lines = "\n".join(
        f"{x:.6f},{a:.3f},{b:.3f},{c:.3f}" for x, (a, b, c) in zip(t, free_vibration(t - t[0]).T, strict=True)
    )
    result = identify_modes(parse_record_csv("#time,accel_x,accel_y,accel_z\n" + lines, max_rows=20_000))
    assert not result.resampled and result.sample_rate_hz == pytest.approx(rate, rel=1e-7)
    assert not any("not uniform" in w for w in result.warnings)


def test_pure_noise_and_constant_records_are_refused():
    rng = np.random.default_rng(2)
    t = np.arange(2000) / RATE_HZ
    with pytest.raises(InvalidParameter):
        identify_modes(Record(t, rng.standard_normal((2, t.size)), ("a", "b")))
    with pytest.raises(InvalidParameter) as info:
        identify_modes(Record(t, np.ones((1, t.size)), ("a",)))
    assert "constant" in info.value.rule


def test_a_fit_larger_than_its_cap_is_refused_before_it_runs():
    # The truth's record at 2 kHz for 21.85 s on 3 axes: 43700 samples x 3 signals = 131100 values, just past
    # MAX_FIT_VALUES (131072; the fit's Jacobians take ~800 B per value: 2.2 GB and minutes for the 200000 rows x
    # 16 signals a CSV may hold). Fitted from t = 0 (start_s), it is refused as invalid input naming start_s, the
    # field that sets the fit's window; its first 10 s (20000 samples x 3 signals) are fitted.
    from optim.identification.modal import MAX_FIT_VALUES

    t = np.arange(43_700) / RATE_HZ
    assert 3 * t.size > MAX_FIT_VALUES >= 3 * 20_000
    record = Record(t, free_vibration(t), NAMES)
    with pytest.raises(InvalidParameter, match="at most 131072 values") as refused:
        identify_modes(record, start_s=0.0)
    assert refused.value.field == "start_s"
    short = t[:20_000]
    modes = identify_modes(Record(short, free_vibration(short), NAMES), start_s=0.0).modes
    assert [round(m.natural_frequency_hz, 3) for m in modes] == [f for f, _ in TRUTH]
