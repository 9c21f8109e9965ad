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
   with the same vibration window; target: never slower). Needs ``pip install ruckig``; skipped without it;
d. speed: p50 wall time of nominal and robust single-mode designs and of two- and three-mode
   transfer-function plants (targets 100 ms, 1 s, 2 s).

Every answer is also checked for defects (limits, residual by an independent quadrature of the returned
arcs, lower_bound_s <= duration_s, band coverage); they are listed at the end.
"""

from __future__ import annotations

import cmath
import itertools
import math
import statistics
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.integrate import quad

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tests.time_optimal_oracle import (  # noqa: E402
    OutOfRange,
    minimum_time,
    rigid_minimum_time,
    velocity_limited_upper_bound,
)

ENDPOINT = "/v1/profiles/time-optimal"
RUNS = 10
DENSE = {"min_ratio": 0.5, "max_ratio": 1.5, "count": 2001}
DEFECTS: list[str] = []


@dataclass(frozen=True)
class Move:
    name: str
    hz: float
    zeta: float
    d: float
    a: float
    v: float
    j: float  # jerk limit for part c

    @property
    def plant(self) -> dict[str, Any]:
        return {"kind": "mode", "natural_frequency_hz": self.hz, "damping_ratio": self.zeta}

    @property
    def limits(self) -> dict[str, float]:
        return {"max_velocity": self.v, "max_acceleration": self.a}

    @property
    def rigid_s(self) -> float:
        return rigid_minimum_time(self.a, self.v, self.d)

    @property
    def periods(self) -> float:
        return self.rigid_s * self.hz


MOVES = [
    Move("2Hz short", 2.0, 0.0, 0.08, 2.0, 1.0, 40.0),  # bang-bang 0.4 s: 0.8 periods
    Move("10Hz z.1", 10.0, 0.1, 0.1, 20.0, 2.0, 2000.0),  # bang-bang 0.141 s: 1.4 periods
    Move("40Hz 3.6T", 40.0, 0.0, 0.02, 10.0, 5.0, 2000.0),  # bang-bang 89 ms: 3.6 periods
    Move("5Hz z.05 cst", 5.0, 0.05, 0.5, 5.0, 0.6, 100.0),  # trapezoid 0.953 s: 4.8 periods
    Move("10Hz cst", 10.0, 0.0, 0.53, 20.0, 1.0, 1000.0),  # trapezoid 0.58 s: 5.8 periods
    Move("40Hz known", 40.0, 0.0, 0.12, 10.0, 5.0, 1000.0),  # bang-bang 219 ms: 8.8 periods (219.7077 ms)
]


def defect(text: str) -> None:
    DEFECTS.append(text)


def post(client: Any, path: str, body: dict[str, Any]) -> tuple[dict[str, Any] | None, float]:
    start = time.perf_counter()
    answer = client.post(path, json=body)
    elapsed = time.perf_counter() - start
    if answer.status_code != 200:
        detail = answer.json() if answer.headers.get("content-type", "").endswith("json") else answer.text
        defect(f"{path} {answer.status_code}: {str(detail)[:300]} for {str(body)[:200]}")
        return None, elapsed
    return answer.json(), elapsed


def base_body(move: Move, **extra: Any) -> dict[str, Any]:
    return {"plant": move.plant, "displacement": move.d, "limits": move.limits, **extra}


def oracle_s(move: Move) -> tuple[float | None, float | None]:
    """(exact minimum, upper bound): the exact minimum for undamped moves without coast, else for undamped moves
    the oracle's feasible bound where the velocity limit is active (an answer slower than it is not optimal)."""
    if move.zeta != 0.0:
        return None, None
    w = 2 * math.pi * move.hz
    try:
        return minimum_time(w, move.a, move.v, move.d), None
    except OutOfRange:
        return None, velocity_limited_upper_bound(w, move.a, move.v, move.d)


# --- independent checks of a time-optimal answer ---------------------------------------------------------


def acceleration_pieces(design: dict[str, Any], limits: dict[str, float]) -> list[tuple[float, float, float, float]]:
    """(start, end, a0, jerk) per arc: the acceleration a0 + jerk (t - start) on [start, end), built from the
    design's arcs alone (levels in physical units, or in units of the limit when all are within [-1, 1])."""
    arcs = design["arcs"]
    quantities = {arc.get("quantity") for arc in arcs}
    held = "jerk" if "jerk" in quantities else "acceleration"
    unit = limits["max_jerk" if held == "jerk" else "max_acceleration"]
    scale = unit if max(abs(float(arc["level"])) for arc in arcs) <= 1 + 1e-9 and unit != 1 else 1.0
    pieces = []
    acc = 0.0
    for arc in arcs:
        t0, h, level = float(arc["start_s"]), float(arc["duration_s"]), float(arc["level"]) * scale
        if held == "jerk":
            pieces.append((t0, t0 + h, acc, level))
            acc += level * h
        else:
            pieces.append((t0, t0 + h, level, 0.0))
    return pieces


def arc_checks(move: Move, answer: dict[str, Any], limits: dict[str, float], label: str) -> float | None:
    """Residual amplitude (fraction of the move) of the arcs at the nominal mode, by quadrature; also end
    state, limits, timing consistency. Returns the residual fraction (None without arcs)."""
    design = answer["design"]
    metrics = answer["metrics"]
    tag = f"{label} {move.name}"
    if design.get("lower_bound_s") is not None and design["lower_bound_s"] > design["duration_s"] * (1 + 1e-12):
        defect(f"{tag}: lower_bound_s {design['lower_bound_s']:.6f} > duration_s {design['duration_s']:.6f}")
    for name, peak in (("max_velocity", "peak_velocity"), ("max_acceleration", "peak_acceleration"),
                       ("max_jerk", "peak_jerk")):  # fmt: skip
        if name in limits and metrics.get(peak) is not None and metrics[peak] > limits[name] * (1 + 1e-9):
            defect(f"{tag}: {peak} {metrics[peak]:.9g} > {name} {limits[name]:g}")
    if not answer.get("limits_met", True):
        defect(f"{tag}: limits_met false {answer.get('limit_violations')}")
    if abs(metrics["motion_time_s"] - design["duration_s"]) > 1e-9 * max(1.0, design["duration_s"]):
        defect(f"{tag}: motion_time_s {metrics['motion_time_s']} != design.duration_s {design['duration_s']}")
    if design.get("refined") is False:
        defect(f"{tag}: not refined, the grid optimum returned ({design.get('refinement')})")
    robustness = design.get("robustness") or {}
    worst, cap = robustness.get("worst_percentage_vibration"), robustness.get("max_percentage_vibration")
    if worst is not None and cap is not None and worst > cap * (1 + 1e-9):
        defect(f"{tag}: worst_percentage_vibration {worst:.9g} > max_percentage_vibration {cap:g}")
    if not design.get("arcs"):
        defect(f"{tag}: no design.arcs")
        return None
    same = sum(1 for x, y in itertools.pairwise(design["arcs"]) if math.isclose(x["level"], y["level"], rel_tol=1e-9))
    if same:
        defect(f"{tag}: {same} pairs of consecutive arcs share a level (not merged)")
    pieces = acceleration_pieces(design, limits)
    end = pieces[-1][1]
    if abs(end - design["duration_s"]) > 1e-9 * max(1.0, end):
        defect(f"{tag}: arcs end at {end:.9f} != duration_s {design['duration_s']:.9f}")
    for (_, e0, _, _), (s1, _, _, _) in itertools.pairwise(pieces):
        if abs(e0 - s1) > 1e-9:
            defect(f"{tag}: arcs not contiguous ({e0} vs {s1})")
            break
    # end state by exact integration of the pieces
    p = vel = 0.0
    for t0, t1, a0, jk in pieces:
        h = t1 - t0
        p += vel * h + a0 * h * h / 2 + jk * h**3 / 6
        vel += a0 * h + jk * h * h / 2
        if abs(vel) > move.v * (1 + 1e-9):
            defect(f"{tag}: arc velocity {vel:.9g} > max_velocity {move.v}")
    if abs(p - move.d) > 1e-6 * abs(move.d) or abs(vel) > 1e-6 * move.v:
        defect(f"{tag}: arcs end at p = {p:.9g} (D = {move.d}), v = {vel:.3g}")
    # residual: e = load - motor obeys e'' + 2 zeta w e' + w^2 e = -a (mode plant); after T its envelope is
    # |int a(t) exp(-(sigma - i wd)(T - t)) dt| / wd.
    w = 2 * math.pi * move.hz
    sigma, wd = move.zeta * w, w * math.sqrt(1 - move.zeta**2)
    lam = complex(sigma, -wd)
    total = 0j
    for t0, t1, a0, jk in pieces:

        def f(t: float, t0: float = t0, a0: float = a0, jk: float = jk) -> complex:
            return (a0 + jk * (t - t0)) * cmath.exp(-lam * (end - t))

        re = quad(lambda t, f=f: f(t).real, t0, t1, limit=200, epsabs=1e-15)[0]
        im = quad(lambda t, f=f: f(t).imag, t0, t1, limit=200, epsabs=1e-15)[0]
        total += complex(re, im)
    return abs(total) / wd / abs(move.d)


def residual_at(pieces: list[tuple[float, float, float, float]], omega: float, zeta: float) -> float:
    """|int a(t) exp(-(sigma - i wd)(T - t)) dt| / wd: the free vibration's envelope after the command, load units."""
    end = pieces[-1][1]
    sigma, wd = zeta * omega, omega * math.sqrt(1 - zeta**2)
    lam = complex(sigma, -wd)
    total = 0j
    for t0, t1, a0, jk in pieces:
        h = t1 - t0
        # closed form of int_0^h (a0 + jk s) exp(lam s) ds, times exp(-lam (end - t0))
        e = cmath.exp(lam * h)
        base = (e - 1) / lam
        ramp = (h * e) / lam - (e - 1) / lam**2
        total += (a0 * base + jk * ramp) * cmath.exp(-lam * (end - t0))
    return abs(total) / wd


def independent_v(move: Move, pieces: list[tuple[float, float, float, float]], ratios: np.ndarray) -> np.ndarray:
    """V (%) at each true/nominal frequency ratio, from the arcs alone, against the rigid reference's envelope
    sum |delta a_k| exp(-sigma (T - t_k)) / (omega omega_d) (docs/api.md, Percentage vibration)."""
    ramp = math.sqrt(move.d / move.a)
    if move.a * ramp > move.v:
        ramp = move.v / move.a
        cruise = move.d / move.v - ramp
        steps = [(0.0, move.a), (ramp, move.a), (ramp + cruise, move.a), (2 * ramp + cruise, move.a)]
    else:
        steps = [(0.0, move.a), (ramp, 2 * move.a), (2 * ramp, move.a)]
    t_ref = steps[-1][0]
    out = []
    for r in ratios:
        omega = r * 2 * math.pi * move.hz
        sigma, wd = move.zeta * omega, omega * math.sqrt(1 - move.zeta**2)
        envelope = sum(da * math.exp(-sigma * (t_ref - tk)) for tk, da in steps) / (omega * wd)
        out.append(100 * residual_at(pieces, omega, move.zeta) / envelope)
    return np.array(out)


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
