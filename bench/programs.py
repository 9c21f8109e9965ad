"""Benchmark: machine programs (issue 28), in-process, one BLAS thread.

1. The pick-and-place cycle of app.examples.programs (8 stops, X at 14 Hz, Y at 22 Hz changing by +-15 % with X's
   position): every stop's residual on every axis, by an independent simulation of the true, position-dependent
   plant (a fourth-order Magnus integrator on the load's own equation, with this script's own interpolation of
   the table: nothing of optim.programs' integration); every limit on the exact commands; the cycle time against
   Ruckig's synchronized rigid optimum shaped by ZVD (at least 8 % shorter asked) and by ZV at each stop's true
   frequency (never longer asked, move by move), both computed in the same run.
2. The straight line of the other example against the single-axis design on its path parameter with the projected
   limits (the plant built here from the modes' quadratics): the largest difference of the axes' commands.
3. A 20-move, 3-axis program's time in one process and in two (``vibfree.program(..., processes=2)``) against the
   same moves' single-axis designs alone, in the same run; with a seed, that seed's program only
   (``python bench/programs.py speed 29``).

    python bench/programs.py
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from app.examples.programs import EXAMPLES, PICK_AND_PLACE  # noqa: E402
from app.schemas.programs import ProgramIn  # noqa: E402
from app.services import programs as service  # noqa: E402
from app.settings import Settings  # noqa: E402
from models.commands import PiecewiseCommand  # noqa: E402
from models.plants import TransferFunctionPlant  # noqa: E402
from optim.families.time_optimal.options import TimeOptimalOptions  # noqa: E402
from optim.problem import Limits, Problem  # noqa: E402
from optim.programs.compare import recipe_moves, true_zv  # noqa: E402
from optim.programs.moves import path_plant  # noqa: E402
from optim.registry import FAMILIES  # noqa: E402
from optim.synthesis import synthesize  # noqa: E402
from runtime.executor import InlineExecutor  # noqa: E402
from vibfree.api import _run  # noqa: E402

SETTINGS = Settings()
HERE = InlineExecutor()


def solve(request: dict[str, Any]) -> tuple[dict[str, Any], Any, float]:
    body = ProgramIn.model_validate(request)
    started = time.perf_counter()
    answer, result = _run(service.answer(body, SETTINGS, HERE))
    return answer, result, time.perf_counter() - started


def table_mode(axis: dict[str, Any]) -> Any:
    """x -> (w, zeta) by this script's own linear interpolation of the request's table (or the constant plant)."""
    if axis.get("plant_table") is None:
        plant = axis["plant"]
        w, z = 2 * math.pi * plant["natural_frequency_hz"], plant.get("damping_ratio", 0.0)
        return None, lambda _c: (w, z)
    points = axis["plant_table"]["points"]
    at = np.array([p["at"] for p in points])
    hz = np.array([p["plant"]["natural_frequency_hz"] for p in points])
    zeta = np.array([p["plant"].get("damping_ratio", 0.0) for p in points])
    return axis["plant_table"]["coordinate"], lambda c: (
        2 * math.pi * float(np.interp(c, at, hz)),
        float(np.interp(c, at, zeta)),
    )


def magnus_states(
    p: PiecewiseCommand, c: Any, mode: Any, ends: list[float], per_period: int = 2000
) -> list[np.ndarray]:
    """(y, y') of the load at each instant of ``ends``, from rest at 0: y'' = -2 zeta w (y' - p') - w^2 (y - p),
    w and zeta where the coordinate ``c`` is (None: constant), by the fourth-order Magnus integrator on the
    augmented state (y, y', 1) with ``per_period`` steps a period of the fastest mode (Blanes, Casas, Oteo and Ros
    2009, eq. 4.11: Omega = h / 2 (A1 + A2) + sqrt(3) h^2 / 12 [A2, A1] at the two Gauss points). A method of
    its own (no adaptive step, no Runge-Kutta), with its error estimated by halving the step."""
    from scipy.linalg import expm

    def matrices(t: np.ndarray) -> np.ndarray:
        place = np.zeros_like(t) if c is None else c.evaluate(0, t)
        wz = np.array([mode(float(x)) for x in place])
        w, z = wz[:, 0], wz[:, 1]
        out = np.zeros((t.size, 3, 3))
        out[:, 0, 1] = 1.0
        out[:, 1, 0] = -w * w
        out[:, 1, 1] = -2 * z * w
        out[:, 1, 2] = w * w * p.evaluate(0, t) + 2 * z * w * p.evaluate(1, t)
        return out

    fastest = max(mode(float(x))[0] for x in np.linspace(-1.0, 2.0, 301)) if c is not None else mode(0.0)[0]
    x = np.array([p.evaluate(0, [0.0])[0], 0.0, 1.0])
    out, start = [], 0.0
    for end in ends:
        n = max(1, math.ceil((end - start) * fastest / (2 * math.pi) * per_period))
        h = (end - start) / n
        t = start + h * np.arange(n)
        a1 = matrices(t + h * (0.5 - math.sqrt(3) / 6))
        a2 = matrices(t + h * (0.5 + math.sqrt(3) / 6))
        steps = expm(0.5 * h * (a1 + a2) + math.sqrt(3) / 12 * h * h * (a2 @ a1 - a1 @ a2))
        for e in steps:
            x = e @ x
        out.append(x[:2].copy())
        start = end
    return out


def independent_residuals(request: dict[str, Any], result: Any, per_period: int = 2000) -> np.ndarray:
    """Each stop's residual over the axis's move (rows: moves, columns: axes): the free vibration's amplitude at
    the stop's end, sqrt(e^2 + ((e' + zeta w e) / w_d)^2) with e = y - p, from ``magnus_states``."""
    commands = {a.name: a.command for a in result.axes}
    ends = [m.start_s + m.design.duration_s for m in result.moves]
    out = np.zeros((len(result.moves), len(request["axes"])))
    for n, axis in enumerate(request["axes"]):
        coordinate, mode = table_mode(axis)
        p = commands[axis["name"]]
        c = commands[coordinate] if coordinate is not None else None
        for k, (end, y) in enumerate(zip(ends, magnus_states(p, c, mode, ends, per_period), strict=True)):
            e = y[0] - p.evaluate(0, [end])[0]
            rate = y[1] - p.evaluate(1, [end])[0]
            w, z = mode(float(c.evaluate(0, [end])[0]) if c is not None else 0.0)
            amplitude = math.hypot(e, (rate + z * w * e) / (w * math.sqrt(1 - z * z)))
            before = request["start"] if k == 0 else request["moves"][k - 1]["target"]
            move = abs(request["moves"][k]["target"][axis["name"]] - before[axis["name"]])
            out[k, n] = amplitude / move if move else 0.0
    return out


def limits_held(request: dict[str, Any], result: Any) -> float:
    """The largest peak over its limit of any axis's exact command (velocity, acceleration, jerk)."""
    worst = 0.0
    for axis, cycle in zip(request["axes"], result.axes, strict=True):
        for m, name in ((1, "max_velocity"), (2, "max_acceleration"), (3, "max_jerk")):
            if name in axis["limits"]:
                worst = max(worst, cycle.command.max_abs(m) / axis["limits"][name])
    return worst


def pick_and_place() -> None:
    answer, result, seconds = solve(PICK_AND_PLACE)
    residual = independent_residuals(PICK_AND_PLACE, result)
    rows = {r["method"]: r for r in answer["comparison"]}
    zv = recipe_moves(result.program, true_zv(result.program, 0))
    per_move = [m.design.duration_s / z.duration_s for m, z in zip(result.moves, zv, strict=True)]
    own = max(a["stop_residual_fraction"] or 0 for m in answer["moves"] for a in m["axes"].values())
    print("pick-and-place (8 stops, Y's mode +-15 % with X):")
    print(f"  solved in {seconds:.2f} s; cycle {answer['cycle_time_s']:.4f} s")
    print(
        f"  largest stop residual, independent Magnus-4 integration of the true plant: {residual.max():.2e} of the move"
    )
    print(f"  (1e-6 asked); the answer's own (DOP853): {own:.2e}")
    print(f"  largest peak over its limit, minus 1: {limits_held(PICK_AND_PLACE, result) - 1:.1e} (<= 1e-9 asked)")
    for name in ("ruckig_zv", "ruckig_zvd", "klipper_mzv", "klipper_ei"):
        r = rows[name]
        shorter = 100 * (1 - 1 / r["cycle_time_ratio"])
        print(
            f"  {name:12s} cycle {r['cycle_time_s']:.4f} s = {r['cycle_time_ratio']:.4f} x the program's "
            f"(program {shorter:.1f} % shorter); its worst stop {r['max_stop_residual_fraction']:.2e}"
        )
    worst, best = max(per_move), min(per_move)
    print(f"  move by move, program / ZV-shaped Ruckig at the true frequency: max {worst:.4f}, min {best:.4f}")


def straight_line() -> None:
    request = EXAMPLES["straight_line"]["value"]
    _, result, _ = solve(request)
    x, y = (a["plant"] for a in request["axes"])
    length = math.hypot(0.3, 0.1)
    u = (0.3 / length, 0.1 / length)
    lx, ly = (a["limits"] for a in request["axes"])
    limits = Limits(
        min(lx["max_velocity"] / u[0], ly["max_velocity"] / u[1]),
        min(lx["max_acceleration"] / u[0], ly["max_acceleration"] / u[1]),
    )
    quadratics = [
        [
            1.0,
            2 * p["damping_ratio"] * 2 * math.pi * p["natural_frequency_hz"],
            (2 * math.pi * p["natural_frequency_hz"]) ** 2,
        ]
        for p in (x, y)
    ]
    plant = TransferFunctionPlant((quadratics[0][2] * quadratics[1][2],), tuple(np.polymul(*quadratics)))
    alone = synthesize(
        FAMILIES["time_optimal"], Problem(plant, length, limits=limits), TimeOptimalOptions()
    ).design.command
    move = result.moves[0].design
    t = np.linspace(0, move.duration_s, 2001)
    worst = max(
        float(np.max(np.abs(a.command.evaluate_at_instants(t, 4)[m] - u[i] * alone.evaluate_at_instants(t, 4)[m])))
        / max(1.0, float(np.max(np.abs(u[i] * alone.evaluate_at_instants(t, 4)[m]))))
        for i, a in enumerate(move.axes)
        for m in range(4)
    )
    print(f"straight line vs the single-axis design on its path parameter: largest difference {worst:.1e} (1e-9 asked)")


def twenty_moves(seed: int = 28) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    axes = [
        {
            "name": "x",
            "plant": {"kind": "mode", "natural_frequency_hz": 14.0, "damping_ratio": 0.03},
            "limits": {"max_velocity": 1.5, "max_acceleration": 15.0, "max_jerk": 1500.0},
        },
        {
            "name": "y",
            "plant": {"kind": "mode", "natural_frequency_hz": 22.0, "damping_ratio": 0.02},
            "limits": {"max_velocity": 1.5, "max_acceleration": 12.0, "max_jerk": 1200.0},
        },
        {
            "name": "z",
            "plant": {"kind": "mode", "natural_frequency_hz": 35.0, "damping_ratio": 0.05},
            "limits": {"max_velocity": 0.8, "max_acceleration": 10.0, "max_jerk": 1000.0},
        },
    ]
    coordination = ("synchronized", "independent", "straight_line")
    moves = [
        {
            "target": dict(zip("xyz", (float(v) for v in rng.uniform(0, [0.5, 0.3, 0.1])), strict=True)),
            "coordination": coordination[k % 3],
            "dwell_s": 0.02,
        }
        for k in range(20)
    ]
    return {"axes": axes, "start": {"x": 0.0, "y": 0.0, "z": 0.0}, "moves": moves, "compare": False}


def alone_problems(request: dict[str, Any], result: Any) -> list[Problem]:
    """The program's designs as single problems: each moving axis's move on its plant and limits, or a straight
    line's path (its plant: every moving axis's modes; its projected limits)."""
    out = []
    for k, move in enumerate(result.moves):
        design = move.design
        if design.path is not None:
            path = design.path
            plant = path_plant([a.plant for a in design.axes if a.command is not None])
            out.append(
                Problem(plant, path.length, limits=Limits(path.max_velocity, path.max_acceleration, path.max_jerk))
            )
            continue
        before = request["start"] if k == 0 else request["moves"][k - 1]["target"]
        for axis, spec in zip(design.axes, request["axes"], strict=True):
            if axis.command is not None:
                lim = spec["limits"]
                delta = request["moves"][k]["target"][spec["name"]] - before[spec["name"]]
                limits = Limits(lim.get("max_velocity"), lim.get("max_acceleration"), lim.get("max_jerk"))
                out.append(Problem(axis.plant, delta, limits=limits))
    return out


def speed(seed: int = 28) -> None:
    import vibfree

    request = twenty_moves(seed)
    solve(request)  # the first call builds the kernels
    _, result, seconds = solve(request)
    vibfree.program(request, processes=2)  # the workers start
    started = time.perf_counter()
    vibfree.program(request, processes=2)
    two = time.perf_counter() - started
    problems = alone_problems(request, result)
    started = time.perf_counter()
    for problem in problems:
        synthesize(FAMILIES["time_optimal"], problem, TimeOptimalOptions())
    alone = time.perf_counter() - started
    print(
        f"20 moves, 3 axes (seed {seed}): {seconds:.2f} s in one process, {two:.2f} s in two (2 s asked); its "
        f"{len(problems)} designs alone {alone:.2f} s: {seconds / alone:.2f} x"
    )


if __name__ == "__main__":
    if sys.argv[1:2] == ["speed"]:
        speed(*(int(a) for a in sys.argv[2:3]))
    else:
        pick_and_place()
        straight_line()
        speed()
