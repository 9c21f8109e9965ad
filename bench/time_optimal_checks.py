"""Independent checks of a time-optimal answer (bench/time_optimal.py): arcs, limits, residual and V by quadrature."""

from __future__ import annotations

import cmath
import itertools
import math
from typing import Any

import numpy as np
from scipy.integrate import quad

from bench.time_optimal_moves import Move, defect


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
