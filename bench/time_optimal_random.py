"""Benchmark: the time-optimal family on seeded random moves against the recipes anyone can build (issue 25).

In-process (``vibfree.synthesize``), side by side on each move:

- Ruckig's rigid time-optimal move within the same velocity, acceleration and jerk limits (the rigid optimum, an
  exact lower bound on any command): ``duration / rigid`` must be >= 1;
- the same move shaped by a ZV shaper per mode (its duration is Ruckig's plus half a damped period per mode,
  Singer and Seering 1990; exactly feasible, zero residual): ``duration / ZV-Ruckig`` must be <= 1 (not applicable
  with a torque limit: the shaped move's torque is not bounded by the rigid move's);
- the residual at the end of the returned arcs by an independent quadrature (scipy.integrate.quad) of the
  acceleration against each mode, a fraction of the move: must be below 1e-6;
- refusals: a non-200 answer where the ZV-shaped Ruckig move exists is a defect;
- on every LP_EVERY-th move without a torque limit, the minimum of an independent 800-step LP
  (bench/lp_reference.py, bisection to 1e-6): ``duration / LP`` (the issue's target: at most 1.0005);
- on every move without a torque limit, that LP at LP_SLACK below the answer's duration: a command found there
  (the answer more than 0.05 % longer than the LP's minimum) is a defect (one LP a move, 0.1-4 s).

Moves: modes from near-rigid (2 kHz) to 5 Hz (log-uniform), damping 0 to 0.2, displacement 0.01 to 2, with
and without velocity and jerk limits; one mode (70 %), two modes (a transfer function, 15 %), a two-inertia
plant under a torque limit (15 %). ``python bench/time_optimal_random.py [count] [seed]`` (default 200, 25).
"""

from __future__ import annotations

import math
import statistics
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from vibfree.cli import one_blas_thread  # noqa: E402

one_blas_thread()  # as the service's workers (docs/deployment.md), before numpy loads BLAS

import numpy as np  # noqa: E402
from scipy.integrate import quad  # noqa: E402

from bench.lp_reference import GridMove  # noqa: E402
from models.rigid_motion import rigid_move  # noqa: E402
from vibfree import VibfreeError, synthesize  # noqa: E402

RESIDUAL_BOUND = 1e-6  # of the move
LP_EVERY = 5
LP_STEPS = 800
LP_SLACK = 5e-4  # the tolerance against the 800-step LP


def _log_uniform(rng: np.random.Generator, low: float, high: float) -> float:
    return float(math.exp(rng.uniform(math.log(low), math.log(high))))


def random_move(rng: np.random.Generator) -> tuple[dict[str, Any], list[tuple[float, float]], bool]:
    """(request, modes as (w rad/s, zeta), torque-limited)."""
    kind = rng.uniform()
    d, a = _log_uniform(rng, 0.01, 2.0), _log_uniform(rng, 1.0, 50.0)
    limits: dict[str, float] = {"max_acceleration": a}
    if rng.uniform() < 0.5:
        limits["max_velocity"] = float(rng.uniform(0.3, 1.0) * math.sqrt(d * a))
    if rng.uniform() < 0.5:
        limits["max_jerk"] = float(a / rng.uniform(0.005, 0.1))
    hz, zeta = _log_uniform(rng, 5.0, 2000.0), float(rng.uniform(0.0, 0.2))
    w = 2 * math.pi * hz
    if kind < 0.7:
        plant: dict[str, Any] = {"kind": "mode", "natural_frequency_hz": hz, "damping_ratio": zeta}
        return {"plant": plant, "displacement": d, "limits": limits}, [(w, zeta)], False
    if kind < 0.85:
        w2, zeta2 = w * rng.uniform(1.5, 4.0), float(rng.uniform(0.0, 0.2))
        num = np.polymul([2 * zeta * w, w * w], [2 * zeta2 * w2, w2 * w2])
        den = np.polymul([1.0, 2 * zeta * w, w * w], [1.0, 2 * zeta2 * w2, w2 * w2])
        plant = {"kind": "transfer_function", "numerator": num.tolist(), "denominator": den.tolist()}
        return {"plant": plant, "displacement": d, "limits": limits}, [(w, zeta), (w2, zeta2)], False
    jm, jl = 0.01, 0.01 * rng.uniform(0.25, 4.0)
    stiffness = w * w * jl  # the load's mode on the motor's position: sqrt(k / J_L) (Cusimano eq. 1)
    plant = {
        "kind": "two_inertia",
        "motor_inertia_kgm2": jm,
        "load_inertia_kgm2": jl,
        "stiffness_nm_per_rad": stiffness,
    }
    limits = {"max_torque_nm": a * (jm + jl), **{k: v for k, v in limits.items() if k != "max_acceleration"}}
    return {"plant": plant, "displacement": d, "limits": limits}, [(w, 0.0)], True


def zv_ruckig_s(request: dict[str, Any], modes: list[tuple[float, float]]) -> tuple[float, float]:
    """(Ruckig's rigid minimum, the ZV-shaped move's duration: plus half a damped period per mode)."""
    lim = request["limits"]
    accel = lim.get("max_acceleration")
    if accel is None:  # a torque limit: the rigid machine's acceleration M / (J_M + J_L)
        plant = request["plant"]
        accel = lim["max_torque_nm"] / (plant["motor_inertia_kgm2"] + plant["load_inertia_kgm2"])
    rigid = rigid_move(request["displacement"], True, lim.get("max_velocity"), accel, lim.get("max_jerk")).duration_s
    return rigid, rigid + sum(math.pi / (w * math.sqrt(1 - z * z)) for w, z in modes)


def residual_fraction(design: dict[str, Any], modes: list[tuple[float, float]], move: float) -> float:
    """max over modes of |integral of a(t) e^(lambda (T - t)) dt| / (w^2 move): the load's residual amplitude left
    by the acceleration a(t) of the returned arcs (its size for a mode of unit static gain), by QUADPACK's
    oscillatory quadrature (QAWO) per arc: cos(w_d (T - t)) and sin(w_d (T - t)) split on cos(w_d t), sin(w_d t)."""
    arcs = design["arcs"]
    jerk = arcs[0]["quantity"] == "jerk"
    end = design["duration_s"]
    worst = 0.0
    for w, zeta in modes:
        sigma, wd = zeta * w, w * math.sqrt(1 - zeta * zeta)
        c_big, s_big, acc = 0.0, 0.0, 0.0
        for arc in arcs:
            t0, h, level = arc["start_s"], arc["duration_s"], arc["level"]
            a0 = acc

            def g(t: float, t0: float = t0, a0: float = a0, level: float = level, sigma: float = sigma) -> float:
                return (a0 + level * (t - t0) if jerk else level) * math.exp(-sigma * (end - t))

            c_big += quad(g, t0, t0 + h, weight="cos", wvar=wd, limit=400)[0]
            s_big += quad(g, t0, t0 + h, weight="sin", wvar=wd, limit=400)[0]
            acc = a0 + level * h if jerk else acc
        cos_t, sin_t = math.cos(wd * end), math.sin(wd * end)
        total = complex(cos_t * c_big + sin_t * s_big, sin_t * c_big - cos_t * s_big)
        worst = max(worst, abs(total) / (w * w) / move)
    return worst


def main(count: int = 200, seed: int = 25) -> int:
    rng = np.random.default_rng(seed)
    over_zv, over_rigid, seconds, methods = [], [], [], {}
    over_lp: list[tuple[float, int]] = []
    defects: list[str] = []
    for k in range(count):
        request, modes, torque = random_move(rng)
        rigid_s, zv_s = zv_ruckig_s(request, modes)
        start = time.perf_counter()
        try:
            design = synthesize("time_optimal", request).answer["design"]
        except VibfreeError as exc:
            defects.append(f"#{k} refused ({exc}): {request}")
            continue
        seconds.append(time.perf_counter() - start)
        duration = design["duration_s"]
        methods[design["method"]] = methods.get(design["method"], 0) + 1
        over_rigid.append(duration / rigid_s)
        if duration < rigid_s * (1 - 1e-9):
            defects.append(f"#{k} shorter than Ruckig's rigid minimum ({duration} < {rigid_s}): {request}")
        if not torque:
            over_zv.append(duration / zv_s)
            if duration > zv_s * (1 + 1e-9):
                defects.append(f"#{k} longer than ZV-shaped Ruckig ({duration} > {zv_s}): {request}")
        if design["lower_bound_s"] < rigid_s * (1 - 1e-9) and not torque:
            defects.append(f"#{k} lower_bound_s {design['lower_bound_s']} below the rigid minimum {rigid_s}")
        if not torque:
            poles = tuple(complex(-z * w, w * math.sqrt(1 - z * z)) for w, z in modes)
            lim = request["limits"]
            grid_move = GridMove(
                request["displacement"], poles, lim.get("max_velocity"), lim["max_acceleration"], lim.get("max_jerk")
            )
            if grid_move.feasible(duration * (1 - LP_SLACK), LP_STEPS):
                defects.append(f"#{k} more than {LP_SLACK:.2%} longer than the {LP_STEPS}-step LP: {request}")
            if k % LP_EVERY == 0:
                lp_s = grid_move.minimum_s(rigid_s, duration * 1.001, LP_STEPS)
                if lp_s is not None:
                    over_lp.append((duration / lp_s, k))
        residual = residual_fraction(design, modes, request["displacement"])
        if residual > RESIDUAL_BOUND:
            defects.append(f"#{k} residual {residual:.3g} of the move: {request}")
    zv = np.array(over_zv)
    print(f"{count} moves (seed {seed}), {len(seconds)} designed; methods {methods}")
    print(f"duration / ZV-shaped Ruckig (no torque limit, {zv.size}): max {zv.max():.6f}, median {np.median(zv):.6f}, "
          f"shorter on {int(np.sum(zv < 1 - 1e-9))}")  # fmt: skip
    print(f"duration / Ruckig's rigid minimum: min {min(over_rigid):.6f}, median {statistics.median(over_rigid):.6f}")
    print(f"seconds a design: p50 {statistics.median(seconds):.3f}, max {max(seconds):.3f}")
    if over_lp:
        ratios = sorted(over_lp, reverse=True)
        median = statistics.median(r for r, _ in ratios)
        over = sum(r > 1.0005 for r, _ in ratios)
        print(f"duration / {LP_STEPS}-step LP ({len(ratios)} moves): max {ratios[0][0]:.5f} (#{ratios[0][1]}), ")
        print(f"  median {median:.5f}, over 1.0005 on {over}")
    print(f"defects: {len(defects)}")
    for line in defects:
        print("  " + line[:400])
    return 1 if defects else 0


if __name__ == "__main__":
    sys.exit(main(*(int(a) for a in sys.argv[1:3])))
