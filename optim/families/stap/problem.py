"""The CasADi/IPOPT problem over (t_a, t_j), built once per shape (Cusimano 2022, eqs. 11-20, 41).

Variables alpha = t_a / t_a0 and the dimensionless jerk time t^_j = t_j / t_a of eq. (12) in
[t^_j,lo, 1/2], so t_j <= t_a/2 is a bound and t_a - t_j >= t_a/2 never vanishes. For each pole
lambda the free state is the factorised form of models.stap, and |exp(lambda t) - 1|^2 =
(1 - exp(sigma t))^2 + 4 exp(sigma t) sin^2(omega t / 2) is written without cancellation.
Objectives (``kind``):

- ``sum`` (objective ``residual``): the sum over the plant's modes of (residual / move)^2;
- ``max`` (``worst_case``): the largest (residual / move)^2 over a grid of poles (epigraph);
- ``time`` (``residual_and_time``): t_a subject to (residual / move)^2 <= 1 on that grid (the
  squares normalised by the tolerance).

Constraints: v <= a_Max (t_a - t_j) (eqs. 11, 20), and with torque modes |J_M a_m + J_L a_l| <= M
(1 - 1e-4) on a grid over [0, t_a] and the free oscillation's torque envelope after t_a. Everything
that varies between requests is a named block of the parameter vector (``optim.solver.
parameter_layout``): ``ta0``, ``v``, ``inv_a``, ``pts`` (pre, Re, Im of each pole), ``tq`` (the
torque modes) and ``jj`` (inertias and 1/M). The residual of a rest-to-rest move is the ramp's times
|exp(lambda D/v) - 1|, a constant for each pole, so the same problem serves it. Problems are cached
per shape in the worker (``warm_up`` builds the common ones).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from models.errors import InvalidParameter
from models.plants import Mode, Plant
from models.simulation import ModalForm, modal_form
from models.stap import ComplexArray, FloatArray, Stap
from optim.families.stap.types import StapRequest
from optim.solver import SolveCaps, ipopt_options, parameter_layout
from runtime.cache import LruCache

if TYPE_CHECKING:
    import casadi as ca

TORQUE_POINTS_PER_PERIOD = 16
TORQUE_MARGIN = 1e-4  # the torque limit is imposed 0.01 % tighter, absorbing the time grid
TORQUE_GRID_SIZES = (64, 128, 256, 512, 1024)
OPTIONS = {"ipopt.tol": 1e-10, "ipopt.acceptable_tol": 1e-8, "ipopt.hessian_approximation": "limited-memory"}


@dataclass
class CompiledProblem:
    """One problem shape: its nlpsol, an evaluator and the bounds of g; ``layout`` names the blocks of p."""

    solver: ca.Function  # nlpsol (x0, p, lbx, ubx, lbg, ubg) -> x, f, g, ...
    evaluate: ca.Function  # (x, p) -> (f, g, residual squares per point)
    lbg: FloatArray
    ubg: FloatArray
    layout: dict[str, slice]
    parameter_count: int
    variables: int
    torque_rows: slice = field(
        default_factory=lambda: slice(0, 0)
    )  # rows of g bounding the torque on the grid (|.| <= 1 - margin)
    envelope_rows: slice = field(
        default_factory=lambda: slice(0, 0)
    )  # rows bounding the squared torque envelope after t_a


ProblemKey = tuple[str, int, int, int, SolveCaps]  # kind, points, torque modes, torque grid, caps
SOLVER_CACHE: LruCache[ProblemKey, CompiledProblem] = LruCache("stap")


def build_problem(kind: str, points: int, torque_modes: int, torque_grid: int, caps: SolveCaps) -> CompiledProblem:
    """The problem for ``kind`` (sum, max or time) over ``points`` poles with ``torque_modes`` torque
    modes checked at ``torque_grid`` instants (none when 0)."""
    import casadi as ca

    # One point: (residual / move)^2 = pre j^2 |exp(lambda (t_a - t_j)) - 1|^2 |exp(lambda t_j) - 1|^2.
    x2 = ca.SX.sym("x2", 2)  # t_a (s), t^_j
    v = ca.SX.sym("v")
    pt = ca.SX.sym("pt", 3)  # pre, Re(lambda), Im(lambda)
    t_a, t_hat = x2[0], x2[1]
    t_j = t_hat * t_a
    t_r = t_a - t_j
    jerk = v / (t_j * t_r)  # eq. (16)

    def gap2(sigma: ca.SX, omega: ca.SX, t: ca.SX) -> ca.SX:
        """|exp((sigma + i omega) t) - 1|^2 without cancellation."""
        es = ca.exp(sigma * t)
        return (1.0 - es) ** 2 + 4.0 * es * ca.sin(0.5 * omega * t) ** 2

    point = ca.Function("point", [x2, v, pt], [pt[0] * jerk**2 * gap2(pt[1], pt[2], t_r) * gap2(pt[1], pt[2], t_j)])

    names = [("ta0", 1), ("v", 1), ("inv_a", 1), ("pts", 3 * points), ("tq", 4 * torque_modes), ("jj", 3)]
    layout, start = parameter_layout(names)
    p = ca.MX.sym("p", start)
    n_x = 3 if kind == "max" else 2
    x = ca.MX.sym("x", n_x)
    ta0, speed, inv_a = p[layout["ta0"]], p[layout["v"]], p[layout["inv_a"]]
    ta = x[0] * ta0
    xs = ca.vertcat(ta, x[1])
    pts = ca.reshape(p[layout["pts"]], 3, points)
    squares = point.map(points)(xs, speed, pts)  # 1 x points
    g = [(speed * inv_a - ta * (1.0 - x[1])) / ta0]  # v <= a_Max (t_a - t_j), eqs. 11 and 20
    lbg, ubg = [-np.inf], [0.0]
    if kind == "sum":
        f = ca.sum2(squares)
    elif kind == "max":
        f = x[2]
        g.append(ca.transpose(squares) - x[2])
        lbg += [-np.inf] * points
        ubg += [0.0] * points
    else:  # time: the squares are normalised by the tolerance
        f = x[0]
        g.append(ca.transpose(squares) - 1.0)
        lbg += [-np.inf] * points
        ubg += [0.0] * points
    if torque_modes:
        s = ca.SX.sym("s")
        mode = ca.SX.sym("mode", 4)  # Re(lambda), Im(lambda), Re(q), Im(q) with q = 2 r / lambda^2
        jj = ca.SX.sym("jj", 3)  # J_M + J_L, J_L, 1 / M
        tau = s * t_a

        def ramp(t: ca.SX) -> ca.SX:
            return ca.fmax(t, 0.0)

        a_m = jerk * (ramp(tau) - ramp(tau - t_j) - ramp(tau - t_r))
        s_re: ca.SX | int = 0
        s_im: ca.SX | int = 0
        for sign, t_k in ((1.0, 0.0), (-1.0, t_j), (-1.0, t_r), (1.0, t_a)):  # the four jerk jumps
            age = ca.fmax(tau - t_k, 0.0)
            on = ca.if_else(tau - t_k >= 0.0, sign, 0.0)
            decay = ca.exp(mode[0] * age)
            s_re += on * decay * ca.cos(mode[1] * age)
            s_im += on * decay * ca.sin(mode[1] * age)
        torque = (jj[0] * a_m + jj[1] * jerk * (mode[2] * s_re - mode[3] * s_im)) * jj[2]
        torque_at = ca.Function("torque", [x2, v, s, mode, jj], [torque])
        envelope2 = (
            (jj[1] * jerk * jj[2]) ** 2
            * (mode[2] ** 2 + mode[3] ** 2)
            * gap2(mode[0], mode[1], t_r)
            * gap2(mode[0], mode[1], t_j)
        )
        after = ca.Function("after", [x2, v, mode, jj], [envelope2])
        grid = ca.DM(np.linspace(0.0, 1.0, torque_grid)).T
        modes = ca.reshape(p[layout["tq"]], 4, torque_modes)
        jj_p = p[layout["jj"]]
        mapped = torque_at.map(torque_grid)
        first_torque_row = len(lbg)
        for m in range(torque_modes):  # a loop over a few modes, not samples
            g.append(ca.transpose(mapped(xs, speed, grid, modes[:, m], jj_p)))
            lbg += [-(1.0 - TORQUE_MARGIN)] * torque_grid
            ubg += [1.0 - TORQUE_MARGIN] * torque_grid
        torque_rows = slice(first_torque_row, len(lbg))
        envelope_rows = slice(len(lbg), len(lbg) + torque_modes)
        g.append(ca.transpose(after.map(torque_modes)(xs, speed, modes, jj_p)))
        lbg += [-np.inf] * torque_modes
        ubg += [(1.0 - TORQUE_MARGIN) ** 2] * torque_modes
    g_all = ca.vertcat(*g)
    nlp = {"x": x, "p": p, "f": f, "g": g_all}
    solver = ca.nlpsol("stap", "ipopt", nlp, ipopt_options(caps, **OPTIONS))
    evaluate = ca.Function("evaluate", [x, p], [f, g_all, squares])
    rows = (torque_rows, envelope_rows) if torque_modes else (slice(0, 0), slice(0, 0))
    return CompiledProblem(solver, evaluate, np.array(lbg), np.array(ubg), layout, start, n_x, *rows)


def compiled_problem(kind: str, points: int, torque_modes: int, torque_grid: int, caps: SolveCaps) -> CompiledProblem:
    """The cached problem of this shape, built on first use (least recently used dropped: ``runtime.cache``)."""
    key: ProblemKey = (kind, points, torque_modes, torque_grid, caps)
    return SOLVER_CACHE.get(key, lambda: build_problem(kind, points, torque_modes, torque_grid, caps))


def warm_up(caps: SolveCaps | None = None) -> None:
    """Build the common problems in a new worker: the nominal residual of a one-mode plant and the
    worst case over the default band (21 frequencies, one damping ratio), without torque limit."""
    caps = caps or SolveCaps()
    compiled_problem("sum", 1, 0, 0, caps)
    compiled_problem("max", 21, 0, 0, caps)


def oscillatory_modes(plant: Plant) -> ModalForm:
    """The oscillatory poles and residues of the plant's load response (models.simulation)."""
    num, den = plant.load_transfer_function()
    modal = modal_form(num, den, 1)
    keep = modal.oscillatory
    return ModalForm(modal.taylor, modal.poles[keep], modal.residues[keep], modal.weights[keep])


def mode_form(omega: FloatArray, zeta: FloatArray) -> tuple[ComplexArray, ComplexArray]:
    """Upper poles and residues of (2 zeta w s + w^2)/(s^2 + 2 zeta w s + w^2) (as models.sensitivity)."""
    poles = omega * (-zeta + 1j * np.sqrt(1.0 - zeta * zeta))
    return poles, (2 * zeta * omega * poles + omega * omega) / (2 * poles + 2 * zeta * omega)


@dataclass(frozen=True)
class ResidualPoints:
    """The poles where the residual is measured, with their factors."""

    poles: ComplexArray
    factor: FloatArray  # |residual / move| = factor * |h(t_a)|, h the ramp's free state (models.stap)


def residual_points(
    poles: ComplexArray, residues: ComplexArray, speed: float, distance: float | None, gain: float = 1.0
) -> ResidualPoints:
    """Each pole's factor: |2 r lambda^m (exp(lambda D/v) - 1)| / the load's move, m = 1 for
    rest-to-velocity (the velocity residual over |G(0)| v), 0 for rest-to-rest (position over
    |G(0)| D); ``gain`` = |G(0)| (1 for the unit-gain modes of the band grid)."""
    if distance is None:
        factor = np.abs(2.0 * residues * poles) / (gain * speed)
    else:
        factor = np.abs(2.0 * residues * np.expm1(poles * distance / speed)) / (gain * distance)
    return ResidualPoints(poles, factor)


def amplitudes(points: ResidualPoints, speed: float, t_a: float, t_j: float) -> FloatArray:
    """|residual / move| at each point for the STAP (t_a, t_j) (models.stap.Stap.free_state)."""
    return points.factor * np.abs(Stap(speed, t_a, t_j).free_state(points.poles))


def band_poles(request: StapRequest, mode: Mode) -> tuple[ComplexArray, ComplexArray] | None:
    """The (poles, residues) of the robust grid (mode form, f_n/f_n,e x damping ratios), or None when
    it is the plant's own mode (u = 0 and no damping ratios given)."""
    u = request.frequency_uncertainty
    if u <= 0.0 and request.band_damping_ratios is None:
        return None
    ratios = np.linspace(1.0 - u, 1.0 + u, request.frequency_points) if u > 0.0 else np.array([1.0])
    zetas = np.asarray(request.band_damping_ratios or (mode.damping_ratio,), dtype=float)
    rho, zeta = np.meshgrid(ratios, zetas)
    return mode_form(mode.natural_frequency_rad_s * rho.ravel(), zeta.ravel())


def torque_grid_size(periods: float) -> int:
    """The torque grid over [0, t_a]: the smallest size with 16 points per period of the fastest mode."""
    for size in TORQUE_GRID_SIZES:
        if size >= TORQUE_POINTS_PER_PERIOD * periods + 16:
            return size
    raise InvalidParameter(
        "method",
        "optimized",
        f"with max_torque_nm the optimiser checks the torque at {TORQUE_POINTS_PER_PERIOD} points per period; "
        f"t_a may span {periods:.0f} periods, more than the "
        f"{(TORQUE_GRID_SIZES[-1] - 16) / TORQUE_POINTS_PER_PERIOD:.0f} it supports "
        "(use method 'closed_form', whose torque rule is eqs. 57-59)",
    )
