"""Benchmark: a 2,000-sample command through the drive (issue 26's target: <= 5 ms p50 in-process).

Cusimano Sec. 7's machine (R 0.9 ohm, L 0.015 H, K_T = K_E 0.8, J_M = J_L = 0.005 kg m^2, 8 Hz shaft) under a
cascade of the named rules (current 800 Hz, velocity 20 Hz, position 2 Hz), driven by a held-jerk move sampled
on 2,000 uniform steps. Interleaved medians, reported as ratios measured in the same run:

- ours: ``models.servo_response.simulate_drive``, the closed loop assembled, its stability checked and every
  output (motor position, velocity, acceleration, current, torque, voltage, load, tracking error) exact at the
  samples, the load's Response ready for its metrics; cold (the machine's closed loop built anew: the target),
  and with it kept from the last command (``models.servo_response.prepared``, as a server simulating the same
  machine again);
- the ideal motor: ``models.simulation.simulate`` of the same command (what every answer already computes);
- ``scipy.signal.lsim`` of the same closed loop (its matrices, the command's position, velocity and acceleration as
  inputs, linearly interpolated: exact for a held jerk only in the limit), every output: the reference that a user
  would write, and the disagreement with it relative to each output's range;
- the same command through a 0.1 N m motor, which the loop would need 0.3 N m of: the drive at its limit
  (models.servo_limits, LSODA at rtol 1e-10; no target, it runs only where the linear loop saturates);
- the same drive sampled every 0.4 ms (models.servo_sampled: 2,000 samples over the 0.8 s command), cold (its
  discretisation and eigenbasis built anew), against ``scipy.signal.dlsim`` of the same discrete loop (F, G: a
  Python loop over the samples).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
from scipy import signal

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench.simulation import medians_ms
from models.commands import PiecewiseCommand
from models.plants import example_plants
from models.servo import OUTPUTS, Drive, Motor, closed_loop, current_pi, velocity_pi
from models.servo_response import prepared, simulate_drive
from models.servo_sampled import sampled_loop
from models.simulation import simulate

SAMPLES = 2_000
REPEATS = 100
TARGET_MS = 5.0


DURATION_S = 0.8


def command() -> PiecewiseCommand:
    """Up to 20 rad/s^2 in 50 ms, down, back to rest at 0.3 s; 2,000 steps of 0.4 ms to 0.8 s (every switch on a
    step, so that it ends at rest)."""
    t = np.linspace(0.0, DURATION_S, SAMPLES + 1)
    edge = 1e-9  # (the switching instants are grid points up to round-off)
    jerk = np.select(
        [t < 0.05 - edge, t < 0.1 - edge, (t >= 0.2 - edge) & (t < 0.25 - edge), (t >= 0.25 - edge) & (t < 0.3 - edge)],
        [400, -400, -400, 400],
        0,
    )
    return PiecewiseCommand.from_held_steps(t, jerk.astype(float), 3)


def main() -> int:
    plant = example_plants()["cusimano_8hz_equal_inertia"]
    motor = Motor(0.9, 0.015, 0.8, max_torque_nm=10.0)
    drive = Drive(2 * math.pi * 2.0, velocity_pi(20.0, 0.01), current_pi(800.0, motor), motor)
    move = command()
    loop = closed_loop(plant, drive)
    outputs_c = np.vstack([loop.outputs[name][0] for name in OUTPUTS])
    outputs_d = np.vstack([loop.outputs[name][1] for name in OUTPUTS])
    system = signal.StateSpace(loop.a, loop.b, outputs_c, outputs_d)
    inputs = move.derivatives[:3].T.copy()

    def lsim() -> np.ndarray:
        return signal.lsim(system, inputs, move.time_s)[1]

    def cold() -> object:
        prepared.cache_clear()
        return simulate_drive(plant, drive, move)

    sampled = Drive(drive.position_kp_per_s, drive.velocity, drive.current, motor, sample_period_s=DURATION_S / SAMPLES)
    digital = sampled_loop(plant, sampled)
    grid = digital.period_s * np.arange(SAMPLES + 1)
    at = move.evaluate_at_instants(grid, orders=3).T.copy()
    dsystem = (
        digital.f,
        digital.g,
        np.atleast_2d(digital.outputs["load_position"][0]),
        np.zeros((1, 3)),
        digital.period_s,
    )

    def sampled_cold() -> object:
        sampled_loop.cache_clear()
        return simulate_drive(plant, sampled, move)

    weak = Drive(drive.position_kp_per_s, drive.velocity, drive.current, Motor(0.9, 0.015, 0.8, max_torque_nm=0.1))

    def limited() -> object:
        prepared.cache_clear()
        return simulate_drive(plant, weak, move)

    def dlsim() -> np.ndarray:
        return signal.dlsim(dsystem, at, grid)[1][:, 0]

    times = medians_ms(
        {
            "ours": cold,
            "ours, the machine's closed loop kept": lambda: simulate_drive(plant, drive, move),
            "ideal": lambda: simulate(plant, move),
            "lsim": lsim,
            "ours, a 0.1 N m motor: the drive at its limit": limited,
            "ours, sampled every 0.4 ms": sampled_cold,
            "dlsim of the sampled loop": dlsim,
        },
        REPEATS,
    )
    ours = simulate_drive(plant, drive, move)
    reference = lsim()
    mine = {
        "motor_position": ours.motor_position,
        "current_a": ours.current_a,
        "torque_nm": ours.torque_nm,
        "load_position": ours.load.load_position,
        "tracking_error": ours.tracking_error,
    }
    print(f"{SAMPLES} samples, Cusimano Sec. 7 machine, {loop.a.shape[0]} states")
    print("| what | p50 | ratio to ours |")
    print("|---|---|---|")
    for name, ms in times.items():
        print(f"| {name} | {ms:.2f} ms | {ms / times['ours']:.2f} |")
    for name, values in mine.items():
        ref = reference[:, OUTPUTS.index(name)]
        print(f"{name}: max |ours - lsim| / range = {np.max(np.abs(values - ref)) / np.ptp(ref):.1e}")
    at_limit = simulate_drive(plant, weak, move)
    assert at_limit.simulation == "limited", at_limit.note  # (the row times the drive at its limit)
    discrete = simulate_drive(plant, sampled, move).load.load_position
    reference_d = dlsim()
    print(
        f"sampled load: max |ours - dlsim| / range = {np.max(np.abs(discrete - reference_d)) / np.ptp(reference_d):.1e}"
    )
    met = times["ours"] <= TARGET_MS and times["ours, sampled every 0.4 ms"] <= TARGET_MS
    print(f"target <= {TARGET_MS} ms: {'met' if met else 'NOT met'}")
    return 0 if met else 1


if __name__ == "__main__":
    sys.exit(main())
