"""Benchmark: the time-optimal family against the exact minimum, the rigid move and the shaped commands.

Figures for docs/benchmarks.md. Everything goes through the app (``TestClient(app)``, its solver pool), side by side
on rest-to-rest moves spanning about 0.8 to 10 periods of the mode, under acceleration and velocity limits:

a. nominal: time-optimal duration vs the exact minimum time (tests/time_optimal_oracle.py, undamped and
   without coast, else n/a; target within 0.2 %; for undamped moves with a coast, the oracle's feasible upper
   bound, "bound"), vs the rigid minimum time, and vs the ZV and ZVD-shaped rigid commands of
   /v1/profiles/input-shaped (their end and settling);
b. robust: the V <= 5 % band of the ZVD-shaped command (its sensitivity on a dense grid, band_5_percent)
   asked of the time-optimal family as robustness.frequency_ratio_range; settling compared (target: >= 5 %
   sooner on moves longer than ~2 periods), and the achieved band checked to cover the requested one (and
   re-measured on the service's own dense sensitivity grid);
c. with max_jerk: the jerk-limited time-optimal design vs ZV shaping of Ruckig's jerk-limited rigid profile
   (convolved here with A1 = 1/(1+K), A2 = K/(1+K) half a damped period apart, settling from /v1/simulate
   with the same vibration window; target: never slower). Ruckig is a dependency of the service (models.rigid_motion);
d. speed: p50 wall time of nominal and robust single-mode designs and of two- and three-mode
   transfer-function plants (targets 100 ms, 1 s, 2 s).

Every answer is also checked for defects (limits, residual by an independent quadrature of the returned
arcs, lower_bound_s <= duration_s, band coverage); they are listed at the end.
"""

from __future__ import annotations

import math
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench.time_optimal_checks import acceleration_pieces, arc_checks, independent_v  # noqa: E402
from bench.time_optimal_moves import DEFECTS, MOVES, Move, base_body, defect, oracle_s, post  # noqa: E402

ENDPOINT = "/v1/profiles/time-optimal"
RUNS = 10
DENSE = {"min_ratio": 0.5, "max_ratio": 1.5, "count": 2001}


# --- the shaped and Ruckig references -----------------------------------------------------------------------


def shaped(client: Any, move: Move, shaper: str, sensitivity: dict[str, Any] | None = None) -> dict[str, Any] | None:
    body = base_body(move, shaper=shaper)
    if sensitivity is not None:
        body["sensitivity"] = sensitivity
    answer, _ = post(client, "/v1/profiles/input-shaped", body)
    return answer


def ruckig_zv(client: Any, move: Move, vibration_window: float | None) -> tuple[float, float, float | None] | None:
    """(Ruckig duration, ZV-shaped end, settling of the shaped command from /v1/simulate)."""
    try:
        from ruckig import InputParameter, Result, Ruckig, Trajectory
    except ImportError:
        return None
    inp = InputParameter(1)
    inp.current_position, inp.target_position = [0.0], [move.d]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [move.v], [move.a], [move.j]
    trajectory = Trajectory(1)
    if Ruckig(1).calculate(inp, trajectory) != Result.Working:
        defect(f"ruckig failed on {move.name}")
        return None
    profile = trajectory.profiles[0][0]
    durations, jerks = np.array(profile.t, dtype=float), np.array(profile.j, dtype=float)
    starts = np.concatenate([[0.0], np.cumsum(durations)[:-1]])
    keep = durations > 0
    starts, durations, jerks = starts[keep], durations[keep], jerks[keep]
    w = 2 * math.pi * move.hz
    wd = w * math.sqrt(1 - move.zeta**2)
    k = math.exp(-move.zeta * math.pi / math.sqrt(1 - move.zeta**2))
    amplitudes, delays = (1 / (1 + k), k / (1 + k)), (0.0, math.pi / wd)
    # shaped jerk: sum of the two scaled, delayed copies (piecewise constant)
    edges = np.unique(np.concatenate([np.concatenate([starts, starts + durations]) + d for d in delays]))

    def jerk_at(t: np.ndarray) -> np.ndarray:
        out = np.zeros_like(t)
        for amp, delay in zip(amplitudes, delays, strict=True):
            for s, h, jk in zip(starts + delay, durations, jerks, strict=True):
                out += amp * jk * ((t >= s) & (t < s + h))
        return out

    end = float(edges[-1])
    horizon = end + 5 / move.hz
    grid = np.unique(np.concatenate([edges, np.linspace(0.0, horizon, 4001)]))
    grid = grid[np.concatenate([[True], np.diff(grid) > 1e-12 * horizon])]  # round-off twins of one edge merged
    held = np.append(jerk_at(0.5 * (grid[1:] + grid[:-1])), 0.0)  # zero-order hold: the value on [t_k, t_k+1)
    body = {
        "plant": move.plant,
        "profile": {"time_s": grid.tolist(), "jerk": held.tolist()},
        "held_quantity": "jerk",
        "hold": "zero",
    }
    if vibration_window is not None:
        body["settling"] = {"vibration_tolerance": vibration_window}
    answer, _ = post(client, "/v1/simulate", body)
    if answer is None:
        return float(trajectory.duration), end, None
    final = answer["profile"]["position"][-1]
    if abs(final - move.d) > 1e-6 * move.d:
        defect(f"ZV-shaped ruckig of {move.name}: ends at {final} (D = {move.d}): the bench's shaping is wrong")
    return float(trajectory.duration), end, answer["metrics"]["settling_time_s"]


# --- the four parts -----------------------------------------------------------------------------------------


def fmt(x: float | None, spec: str = ".4f") -> str:
    return "n/a" if x is None else format(x, spec)


def ms(x: float | None) -> float | None:
    return None if x is None else 1e3 * x


SERVED = True  # whether the time-optimal endpoint exists (the references are measured either way)


def time_optimal(client: Any, body: dict[str, Any]) -> dict[str, Any] | None:
    return post(client, ENDPOINT, body)[0] if SERVED else None


def part_a(client: Any) -> None:
    print("\na. nominal: duration (ms) vs the exact minimum, the rigid minimum and the ZV / ZVD-shaped rigid commands")
    print(
        f"{'move':13} {'T/per':>5} {'rigid':>8} {'exact':>8} {'bound':>8} {'t-opt':>8} {'vs ex %':>8} {'/rigid':>6} "
        f"{'ZV end':>8} {'ZVD end':>8} {'/ZV':>5} {'/ZVD':>5} {'settle':>8} {'ZVset':>8} {'ZVDset':>8} {'resid':>8}"
    )
    for move in MOVES:
        answer = time_optimal(client, base_body(move))
        zv, zvd = shaped(client, move, "zv"), shaped(client, move, "zvd")
        exact, bound = oracle_s(move)
        zv_end = None if zv is None else zv["metrics"]["motion_time_s"]
        zvd_end = None if zvd is None else zvd["metrics"]["motion_time_s"]
        t = settle = residual = gap = None
        if answer is not None:
            t = answer["design"]["duration_s"]
            settle = answer["metrics"]["settling_time_s"]
            residual = arc_checks(move, answer, move.limits, "nominal")
            if residual is not None and residual > 1e-6:
                defect(f"nominal {move.name}: residual by quadrature of the arcs {residual:.2e} of the move")
            gap = None if exact is None else 100 * (t / exact - 1)
            if gap is not None and exact is not None and abs(gap) > 0.2:
                defect(f"nominal {move.name}: {1e3 * t:.4f} ms is {gap:+.3f} % from the exact {1e3 * exact:.4f} ms")
            if bound is not None and t > bound * (1 + 1e-6):
                defect(f"nominal {move.name}: {1e3 * t:.4f} ms is slower than a feasible {1e3 * bound:.4f} ms (oracle)")
            if t < move.rigid_s * (1 - 1e-9):
                defect(f"nominal {move.name}: faster than the rigid minimum ({t} < {move.rigid_s})")
            if zv_end is not None and t > zv_end * (1 + 1e-9):
                defect(f"nominal {move.name}: slower than ZV-shaped ({t} > {zv_end})")
        print(
            f"{move.name:13} {move.periods:5.2f} {1e3 * move.rigid_s:8.3f} {fmt(ms(exact), '8.3f')} "
            f"{fmt(ms(bound), '8.3f')} "
            f"{fmt(ms(t), '8.3f')} {fmt(gap, '+8.4f')} {fmt(t and t / move.rigid_s, '6.3f')} "
            f"{fmt(ms(zv_end), '8.3f')} {fmt(ms(zvd_end), '8.3f')} "
            f"{fmt(t and zv_end and t / zv_end, '5.3f')} {fmt(t and zvd_end and t / zvd_end, '5.3f')} "
            f"{fmt(ms(settle), '8.3f')} {fmt(ms(zv and zv['metrics']['settling_time_s']), '8.3f')} "
            f"{fmt(ms(zvd and zvd['metrics']['settling_time_s']), '8.3f')} {fmt(residual, '8.1e')}"
        )


def part_b(client: Any) -> None:
    print("\nb. robust: time-optimal on the ZVD-shaped command's 5 % band (settling in ms)")
    print(
        f"{'move':13} {'T/per':>5} {'ZVD band':>15} {'achieved':>15} {'worstV':>6} {'V dense':>7} {'ZVD set':>8} "
        f"{'t-opt set':>9} {'gain %':>7} {'t-opt T':>8} {'LB':>8} {'V@1 %':>7}"
    )
    for move in MOVES:
        zvd = shaped(client, move, "zvd", DENSE)
        if zvd is None:
            continue
        band = zvd["sensitivity"]["band_5_percent"]
        tz = zvd["metrics"]["settling_time_s"]
        if band is None or None in band:
            print(f"{move.name:13} ZVD band {band}: skipped")
            continue
        body = base_body(
            move,
            robustness={"frequency_ratio_range": band, "max_percentage_vibration": 5},
            sensitivity={"min_ratio": band[0], "max_ratio": band[1], "count": 801},
        )
        answer = time_optimal(client, body)
        achieved = worst = dense_v = ts = gain = duration = lower = nominal_v = None
        if answer is not None:
            arc_checks(move, answer, move.limits, "robust")
            design = answer["design"]
            duration, lower = design["duration_s"], design.get("lower_bound_s")
            robustness = design.get("robustness") or {}
            achieved = (robustness.get("achieved") or {}).get("frequency_ratio_range")
            worst = robustness.get("worst_percentage_vibration")
            if achieved is None or achieved[0] > band[0] + 1e-9 or achieved[1] < band[1] - 1e-9:
                defect(f"robust {move.name}: achieved band {achieved} does not cover the requested {band}")
            dense_v = max(answer["sensitivity"]["percentage_vibration"])
            if dense_v > 5 * (1 + 1e-6):
                defect(f"robust {move.name}: V reaches {dense_v:.4f} % inside the requested band (service's grid)")
            own_v = independent_v(move, acceleration_pieces(design, move.limits), np.linspace(*band, 401))
            if abs(float(np.max(own_v)) - dense_v) > 1e-3 * max(1.0, dense_v):
                defect(f"robust {move.name}: max V by the arcs {np.max(own_v):.4f} % != service's {dense_v:.4f} %")
            if np.max(own_v) > 5 * (1 + 1e-6):
                defect(f"robust {move.name}: V by quadrature of the arcs reaches {np.max(own_v):.5f} % in the band")
            ts = answer["metrics"]["settling_time_s"]
            nominal_v = answer["metrics"].get("percentage_vibration")
            if ts is None:
                defect(f"robust {move.name}: never settles (V at the nominal mode {nominal_v:.3g} %, undamped)")
            gain = None if ts is None or tz is None else 100 * (1 - ts / tz)
            if gain is not None and move.periods > 2 and gain < 5:
                defect(f"robust {move.name}: settles only {gain:.2f} % sooner than ZVD (target >= 5 %)")
        print(
            f"{move.name:13} {move.periods:5.2f} {band[0]:7.4f}-{band[1]:7.4f} "
            f"{fmt(achieved and achieved[0], '7.4f')}-{fmt(achieved and achieved[1], '7.4f')} {fmt(worst, '6.3f')} "
            f"{fmt(dense_v, '7.3f')} {fmt(ms(tz), '8.3f')} {fmt(ms(ts), '9.3f')} {fmt(gain, '+7.2f')} "
            f"{fmt(ms(duration), '8.3f')} {fmt(ms(lower), '8.3f')} {fmt(nominal_v, '7.3f')}"
        )


def part_c(client: Any) -> None:
    print("\nc. jerk-limited: time-optimal vs ZV-shaped Ruckig (ms)")
    try:
        import ruckig  # noqa: F401
    except ImportError:
        print("ruckig is not installed (pip install ruckig): part c skipped")
        return
    print(
        f"{'move':13} {'jerk':>7} {'ruckig':>8} {'ZV end':>8} {'t-opt T':>8} {'/ZV':>6} {'ZV set':>8} {'t-opt set':>9} "
        f"{'resid':>8}"
    )
    for move in MOVES:
        limits = {**move.limits, "max_jerk": move.j}
        answer = time_optimal(client, {"plant": move.plant, "displacement": move.d, "limits": limits})
        t = ts = residual = window = None
        if answer is not None:
            residual = arc_checks(move, answer, limits, "jerk")
            if residual is not None and residual > 1e-6:
                defect(f"jerk {move.name}: residual by quadrature of the arcs {residual:.2e} of the move")
            window = answer["metrics"].get("settling_vibration_window")
            t, ts = answer["design"]["duration_s"], answer["metrics"]["settling_time_s"]
        reference = ruckig_zv(client, move, window)
        if reference is None:
            continue
        duration, zv_end, zv_settle = reference
        if t is not None and t > zv_end * (1 + 1e-9):
            defect(f"jerk {move.name}: time-optimal {1e3 * t:.4f} ms slower than ZV-shaped Ruckig {1e3 * zv_end:.4f}")
        if ts is not None and zv_settle is not None and ts > zv_settle * (1 + 1e-9):
            defect(f"jerk {move.name}: settles at {1e3 * ts:.4f} ms, after ZV-shaped Ruckig {1e3 * zv_settle:.4f}")
        print(
            f"{move.name:13} {move.j:7g} {1e3 * duration:8.3f} {1e3 * zv_end:8.3f} {fmt(ms(t), '8.3f')} "
            f"{fmt(t and t / zv_end, '6.3f')} {fmt(ms(zv_settle), '8.3f')} {fmt(ms(ts), '9.3f')} "
            f"{fmt(residual, '8.1e')}"
        )


def product_of_modes(modes: list[tuple[float, float]]) -> dict[str, Any]:
    """Unit-DC-gain product of 'mode' factors (2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2), as a transfer function."""
    num, den = np.array([1.0]), np.array([1.0])
    for hz, zeta in modes:
        w = 2 * math.pi * hz
        num = np.convolve(num, [2 * zeta * w, w * w])
        den = np.convolve(den, [1.0, 2 * zeta * w, w * w])
    return {"kind": "transfer_function", "numerator": num.tolist(), "denominator": den.tolist()}


def part_d(client: Any) -> None:
    print(f"\nd. speed: p50 wall time over {RUNS} runs (first call excluded, failed runs too)")
    single = MOVES[-1]
    robust = {"frequency_ratio_range": [0.9, 1.1], "max_percentage_vibration": 5}
    two = product_of_modes([(5.0, 0.02), (13.0, 0.05)])
    three = product_of_modes([(5.0, 0.02), (13.0, 0.05), (31.0, 0.03)])
    limits = {"max_velocity": 1.0, "max_acceleration": 5.0}
    cases = [
        ("nominal 1 mode", base_body(single), 0.1),
        ("robust 1 mode", base_body(single, robustness=robust), 1.0),
        ("2-mode tf", {"plant": two, "displacement": 0.3, "limits": limits, "modes": [0, 1]}, 2.0),
        ("3-mode tf", {"plant": three, "displacement": 0.3, "limits": limits, "modes": [0, 1, 2]}, 2.0),
    ]
    print(f"{'case':16} {'p50 ms':>8} {'max ms':>8} {'target':>7} {'T ms':>9} {'LB ms':>9} {'resid/D':>8}")
    for name, body, target in cases:
        answer, _ = post(client, ENDPOINT, body)
        if answer is None:
            print(f"{name:16} failed")
            continue
        times, failures = [], 0
        for _ in range(RUNS):
            again, elapsed = post(client, ENDPOINT, body)
            if again is None:
                failures += 1
                continue
            answer = again
            times.append(elapsed)
        if failures:
            defect(f"speed {name}: {failures} of {RUNS} runs failed (excluded from the timing)")
        if not times:
            print(f"{name:16} every run failed")
            continue
        p50 = statistics.median(times)
        if p50 > target:
            defect(f"speed {name}: p50 {1e3 * p50:.0f} ms > target {1e3 * target:.0f} ms")
        design = answer["design"] if answer else {}
        lb = design.get("lower_bound_s")
        if lb is not None and lb > design["duration_s"] * (1 + 1e-12):
            defect(f"speed {name}: lower_bound_s {lb} > duration_s {design['duration_s']}")
        if (
            "robustness" not in body
            and answer
            and answer["metrics"]["residual_amplitude"] > 1e-6 * abs(body["displacement"])
        ):
            defect(f"speed {name}: residual_amplitude {answer['metrics']['residual_amplitude']:.3g} > 1e-6 of the move")
        print(
            f"{name:16} {1e3 * p50:8.1f} {1e3 * max(times):8.1f} {1e3 * target:7.0f} "
            f"{fmt(ms(design.get('duration_s')), '9.3f')} {fmt(ms(lb), '9.3f')} "
            f"{fmt(answer and answer['metrics']['residual_amplitude'] / abs(body['displacement']), '8.1e')}"
        )


def main() -> None:
    from fastapi.testclient import TestClient

    from app.main import app

    with TestClient(app) as client:
        while client.get("/readyz").status_code != 200:
            time.sleep(0.2)
        global SERVED
        SERVED = client.post(ENDPOINT, json={}).status_code != 404
        if not SERVED:
            print(f"{ENDPOINT} is not served by this build: only the references are measured")
        part_a(client)
        part_b(client)
        part_c(client)
        if SERVED:
            part_d(client)
    print(f"\ndefects: {len(DEFECTS)}")
    for line in DEFECTS:
        print(f"- {line}")


if __name__ == "__main__":
    main()
