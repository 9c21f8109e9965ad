"""The CasADi problem of the pseudo-polynomial family, built once per shape (Incerti, Secs. IV-V).

The vibration left when the move ends is, for every oscillatory pole lambda_j of the load's
transfer function, the free state (see models.simulation)

    h_j(T) = 1/lambda_j^2 int_0^T exp(lambda_j (T - tau)) phi''(tau) dtau
           = -Phi / (T lambda_j^2) sum_i gamma_i (gamma_i - 1) C_i int_0^1 u^(gamma_i - 2) exp(lambda_j T u) du,

the modal form of Incerti's F and G (eqs. 27-30), with the coefficients C_i of eq. (22). After u = v^2
the integral is 2 int_0^1 v^(2 gamma_i - 3) exp(z v^2) dv, z = lambda_j T, and it is computed by product
integration (``product_integration.product_weights``): v^(2 gamma_i - 3), the only factor that depends on the
exponents, is interpolated at 96 fixed Chebyshev nodes, and the kernel exp(z v^2) times each Lagrange basis
polynomial is integrated in numpy by composite Gauss-Legendre with panels scaled with |z|. The weights are parameters
of the problem, so its size does not grow with the number of periods T / (2 pi / |lambda|) (a plain
Gauss-Legendre rule needs about |z| nodes: the old rule capped moves at 76 periods). Measured against
composite Gauss-Legendre with a panel per radian for |z| = 31, 500 and 3000 and gamma in 3..80:
(gamma - 1) |error| below 5e-14 (``tests/optim``). The deflection
alpha_j = Re(w r h) and its rate alpha_j' = Re(w r lambda h) give the energy
E = sum_j m_j/2 (alpha_j'^2 + w_j^2 alpha_j^2), which is eq. (26) for the belt platform (m = J) and the
two-inertia plant (m = J_L), and the same quantity per unit inertia for plants without physical
parameters.

Bounds: every exponent in [max(3, n + 0.05), 80] (above n for the end conditions, at least 3 so
the jerk stays bounded at T) and consecutive exponents at least 0.05 apart (eq. 22 stays well
conditioned). Limits are imposed on a grid of T/200 plus points clustered near T, 0.01 % tighter
than asked; between grid points the law can still overshoot, so every design is checked afterwards on
what the pipeline checks and re-solved with tightened limits where needed (``solve.solve_within``).

Each problem is built once per (order, plant kind, number of modes, active limits, caps) with the
plant's parameters, displacement, duration, initial exponents and limits as named CasADi parameters
(``parameters.parameter_vector``), and kept in this process's cache: the service builds them in its worker processes
(``warm_up``). The plant enters through its symbolic form (models.plants.Plant.symbolic) for the
second-order kinds (mode, two_inertia, belt_platform), whose mode is a closed-form expression of the
parameters; for higher-order plants (rigid_flexible, transfer functions), whose poles have no closed
form, the poles and residues computed from the same transfer function are the parameters.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from models.plants import Plant
from models.pseudo_polynomial import boundary_matrix, derivative_terms
from optim.families.pseudo_polynomial.product_integration import INTERPOLATION_NODES, chebyshev_nodes
from optim.families.pseudo_polynomial.types import FloatArray, Limits
from optim.solver import SolveCaps, ipopt_options, parameter_layout
from runtime.cache import LruCache

__all__ = [
    "CONSTRAINT_INTERVALS",
    "LIMIT_MARGIN",
    "MAX_EXPONENT",
    "MAX_MODES",
    "MIN_SEPARATION",
    "PROBE_ITERATIONS",
    "PROBLEM_CACHE_MIB",
    "QUICK_ITERATIONS",
    "SEARCH_ITERATIONS",
    "SYMBOLIC_KINDS",
    "build_mib",
    "limit_grid_u",
    "lower_bound",
    "warm_up",
]

MAX_MODES = 3  # oscillatory modes handled; the problem's size grows with modes x nodes x exponents
CONSTRAINT_INTERVALS = 100  # limits are imposed at T/100 spacing, then checked on the samples
MIN_SEPARATION = 0.05  # consecutive exponents at least this far apart: Z stays invertible, C finite
MAX_EXPONENT = 80.0
QUICK_ITERATIONS = 150  # the first try: a reachable closest zero converges in tens of iterations
PROBE_ITERATIONS = 25  # a duration probe (warm-started from a neighbour; a capped zero-energy iterate is polished)
SEARCH_ITERATIONS = 250  # each minimum-energy start; its best feasible iterate is kept
LIMIT_MARGIN = 1e-4  # limits are imposed 0.01 % tighter than asked, absorbing the grid


@dataclass
class CompiledLaw:
    probe: Any  # nlpsol: closest zero-energy design, very few iterations (duration search)
    quick: Any  # nlpsol: closest zero-energy design, few iterations (the first try)
    closest: Any  # nlpsol: closest zero-energy design
    minimum: Any  # nlpsol: minimum-energy design, few iterations per start
    evaluate: Any  # Function (gamma, p) -> (energy, residual amplitude, free states)
    violation: Any  # Function (gamma, p) -> largest breach of the limits and separation (<= 0: feasible)
    g_bounds: tuple[FloatArray, FloatArray, FloatArray, FloatArray]  # lbg/ubg closest, lbg/ubg minimum
    layout: dict[str, slice]
    parameter_count: int


def build_mib(order: int, modes: int, active: tuple[bool, bool, bool, bool]) -> float:
    """Estimated memory of one built problem (its four IPOPT solvers and two Functions), MiB:
    12 + 0.003 (n + 1)^2 (rows + 66 modes), rows = 110 per kinematic limit (``limit_grid_u``), 200 for the torque.

    Every limit row and every mode's product integration (96 nodes) is an expression of all n + 1 exponents
    through C = Z^-1 e (eq. 22), and its Jacobian and Hessian rows are too, hence (n + 1)^2. Fitted to builds in
    one process (bench-style, /proc/self/status): 20 consecutive builds of orders 4-6 with 3 modes and 1-3
    limits grew the RSS by 10.6 + 0.0027 (n + 1)^2 (rows + 66 modes) MiB each (max error 1.6 MiB), the address
    space by 0-4 MiB more; a fresh process's first build of each shape (orders 1-6, 1 or 3 modes, 0, 3 or 4
    limits) fits within 6 MiB. The torque rows (a recurrence along the grid) cost more than a kinematic limit's:
    +22 MiB for 101 rows at order 6. The largest problem a request can ask for (order 6 with all four limits,
    or 3 modes and three limits) is estimated at 100 MiB: measured 93 MiB resident, 88 MiB of address space."""
    rows = 110 * sum(active[:3]) + (200 if active[3] else 0)
    return 12.0 + 0.003 * (order + 1) ** 2 * (rows + 66 * modes)


# The built problems a worker keeps, in estimated MiB (``build_mib``). Counted alone (64 problems), a worker that
# met many shapes kept them all: 21 distinct ones of orders 4-6 with 3 modes held 1149 MiB resident, 1599 MiB of
# address space, past the 1024 MiB worker cap (VIBFREE_WORKER_MEMORY_MB), where CasADi throws std::bad_alloc
# (the fuzz bench's 363-sensitivity-point request; sensitivity points never enter the NLP, and its own problem,
# order 4 with limits, is at most 57 MiB). Within 192 MiB the warm-up's problems (orders 2-4 without limits for the
# three second-order kinds: 138 MiB estimated) stay until a larger problem needs their room; the least recently
# used go first, evicted before a build, so the problems a worker keeps never exceed the budget. Measured through
# the app (one worker, multi-threaded BLAS: 894 MiB of address space warm): seven distinct order 4-6 requests
# with 3-4 limits each, 2 of 7 answered before (then std::bad_alloc at 1023 MiB, and every new shape after it),
# 6 of 7 with a 256 MiB budget (1011-1022 MiB), all within 969 MiB with 192 until a fuzz-settings timeout.
PROBLEM_CACHE_MIB = 192.0


def _weight(key: tuple[object, ...]) -> float:
    order, modes, active = key[0], key[1], key[2]
    assert isinstance(order, int) and isinstance(modes, int) and isinstance(active, tuple)
    return build_mib(order, modes, active)


SOLVER_CACHE: LruCache[tuple[object, ...], CompiledLaw] = LruCache(
    "pseudo_polynomial", weigh=_weight, budget=PROBLEM_CACHE_MIB
)


def _complex_mul(a: tuple[Any, Any], b: tuple[Any, Any]) -> tuple[Any, Any]:
    return a[0] * b[0] - a[1] * b[1], a[0] * b[1] + a[1] * b[0]


def limit_grid_u() -> FloatArray:
    """u = 1 - t/T where the limits are imposed: a uniform grid and a geometric cluster near T."""
    uniform = 1.0 - np.arange(CONSTRAINT_INTERVALS) / CONSTRAINT_INTERVALS
    near_end = (1.0 / CONSTRAINT_INTERVALS) * 10.0 ** (-np.arange(1, 11))  # down to 1e-12
    return np.concatenate([uniform, near_end])


def lower_bound(order: int) -> float:
    """Smallest exponent allowed: above n so the end conditions hold (eqs. 17-20), and at least 3
    so the jerk stays bounded at t = T."""
    return max(3.0, order + 0.05)


def _build(
    order: int, modes: int, active: tuple[bool, bool, bool, bool], caps: SolveCaps, plant: Plant | None
) -> CompiledLaw:
    """The problems of one shape. With ``plant`` (a second-order kind) the plant enters through its
    symbolic form (``Plant.symbolic``): its parameters are the problem's parameters and the mode,
    residue, energy inertia and torque coefficients are expressions of them. Otherwise (plants of
    higher order, whose poles have no closed form) the modal data are parameters."""
    import casadi as ca

    n1 = order + 1
    gamma = ca.SX.sym("gamma", n1)
    symbolic = plant.symbolic() if plant is not None else None
    if symbolic is not None:
        plant_blocks = [("plant", symbolic.parameters.numel())]
    else:
        plant_blocks = [
            ("sigma", modes),
            ("wd", modes),
            ("wr_re", modes),
            ("wr_im", modes),
            ("mass", modes),
            ("torque", 3),
        ]
    nodes = INTERPOLATION_NODES
    names = [
        ("phi", 1),
        ("T", 1),
        ("gamma0", n1),
        *plant_blocks,
        ("quad_re", modes * nodes),
        ("quad_im", modes * nodes),
        ("scale", modes),
        ("energy_ref", 1),
        ("inv_limit", 4),
    ]
    layout, start = parameter_layout(names)
    p = ca.SX.sym("p", start)

    def par(name: str) -> Any:
        return p[layout[name]]

    phi, T, gamma0, scale, inv_limit = par("phi"), par("T"), par("gamma0"), par("scale"), par("inv_limit")
    if symbolic is not None:
        sigma_s, wd_s, r_re, r_im = symbolic.second_order_mode()
        inertia = symbolic.denominator[0]  # a2: J for belt_platform, J_L for two_inertia, 1 for a mode
        torque_exprs = [
            symbolic.symbol(n) if n in symbolic.parameter_names else ca.SX(0.0)
            for n in ("motor_inertia_kgm2", "stiffness_nm_per_rad", "damping_nms_per_rad")
        ]
        mapping = ca.Function(
            "plant_mode", [symbolic.parameters], [sigma_s, wd_s, 2 * r_re, 2 * r_im, inertia, ca.vertcat(*torque_exprs)]
        )
        sigma, wd, wr_re, wr_im, mass, torque_par = mapping(par("plant"))
    else:
        sigma, wd, wr_re, wr_im, mass = (par(k) for k in ("sigma", "wd", "wr_re", "wr_im", "mass"))
        torque_par = par("torque")

    z_matrix = ca.SX(n1, n1)
    for k, row in enumerate(boundary_matrix([gamma[i] for i in range(n1)])):
        for i, entry in enumerate(row):
            z_matrix[k, i] = entry
    rhs = ca.DM.zeros(n1)
    rhs[0] = 1.0
    coefs = ca.solve(z_matrix, rhs)  # eq. (22)

    # Free states h_j(T) by product integration (module docstring): S = 2 sum_k W_k v_k^(2 gamma - 3).
    log_v = ca.DM(np.log(chebyshev_nodes(nodes)))
    quad_re, quad_im = par("quad_re"), par("quad_im")
    powers = [ca.exp((2.0 * gamma[i] - 3.0) * log_v) for i in range(n1)]  # v^(2 gamma - 3)
    energy = 0
    residual = 0
    free = []
    for j in range(modes):
        w_re, w_im = quad_re[j * nodes : (j + 1) * nodes], quad_im[j * nodes : (j + 1) * nodes]
        s_re: Any = 0
        s_im: Any = 0
        for i in range(n1):
            scale_i = 2.0 * gamma[i] * (gamma[i] - 1.0) * coefs[i]
            s_re += scale_i * ca.dot(w_re, powers[i])
            s_im += scale_i * ca.dot(w_im, powers[i])
        lam = (-sigma[j], wd[j])
        lam2 = _complex_mul(lam, lam)
        norm = lam2[0] ** 2 + lam2[1] ** 2
        factor = -phi / T
        h_re = factor * (s_re * lam2[0] + s_im * lam2[1]) / norm  # factor * S / lambda^2
        h_im = factor * (s_im * lam2[0] - s_re * lam2[1]) / norm
        free += [h_re / scale[j], h_im / scale[j]]
        alpha = _complex_mul((wr_re[j], wr_im[j]), (h_re, h_im))
        rate = _complex_mul(_complex_mul((wr_re[j], wr_im[j]), lam), (h_re, h_im))
        omega2 = sigma[j] ** 2 + wd[j] ** 2
        energy += 0.5 * mass[j] * (rate[0] ** 2 + omega2 * alpha[0] ** 2)
        residual += ca.sqrt(alpha[0] ** 2 + alpha[1] ** 2)

    # Limits on the grid t = T s, s in [0, 1): phi^(k) = (-1)^(k+1) Phi/T^k sum_i P C u^(gamma - k) (eq. 18),
    # plus points ever closer to T, where u^(gamma - 3) changes fast when gamma is just above 3.
    log_u = ca.DM(np.log(limit_grid_u()))
    kinematic = []
    for k in (1, 2, 3):
        if not active[k - 1]:
            continue
        total = 0
        for weight, power in derivative_terms([gamma[i] for i in range(n1)], [coefs[i] for i in range(n1)], k):
            total += weight * ca.exp(power * log_u)
        kinematic.append((-1.0) ** (k + 1) * phi / T**k * total * inv_limit[k - 1] * (1.0 + LIMIT_MARGIN))
    if active[3]:
        torque_rows = _torque_rows(ca, gamma, coefs, phi, T, sigma[0], wd[0], torque_par)
        kinematic.append(torque_rows * inv_limit[3] * (1.0 + LIMIT_MARGIN))
    limit_rows = ca.vertcat(*kinematic) if kinematic else ca.SX(0, 1)
    separation = ca.vertcat(*[gamma[i + 1] - gamma[i] for i in range(order)])

    m_limits, m_sep, m_free = limit_rows.numel(), separation.numel(), len(free)
    g_closest = ca.vertcat(ca.vertcat(*free), limit_rows, separation)
    g_minimum = ca.vertcat(limit_rows, separation)
    lbg_c = np.concatenate([np.zeros(m_free), -np.ones(m_limits), np.full(m_sep, MIN_SEPARATION)])
    ubg_c = np.concatenate([np.zeros(m_free), np.ones(m_limits), np.full(m_sep, np.inf)])
    lbg_m = np.concatenate([-np.ones(m_limits), np.full(m_sep, MIN_SEPARATION)])
    ubg_m = np.concatenate([np.ones(m_limits), np.full(m_sep, np.inf)])

    options = ipopt_options(caps, **{"ipopt.tol": 1e-12, "ipopt.constr_viol_tol": 1e-12, "ipopt.acceptable_iter": 0})
    closest_nlp = {"x": gamma, "p": p, "f": 0.5 * ca.sumsqr(gamma - gamma0), "g": g_closest}
    closest = ca.nlpsol("pp_closest", "ipopt", closest_nlp, options)
    quick_caps = replace(caps, max_iterations=min(caps.max_iterations, QUICK_ITERATIONS))
    quick = ca.nlpsol("pp_quick", "ipopt", closest_nlp, {**options, **ipopt_options(quick_caps)})
    probe_caps = replace(caps, max_iterations=min(caps.max_iterations, PROBE_ITERATIONS))
    probe = ca.nlpsol("pp_probe", "ipopt", closest_nlp, {**options, **ipopt_options(probe_caps)})
    search_caps = replace(caps, max_iterations=min(caps.max_iterations, SEARCH_ITERATIONS))
    minimum = ca.nlpsol(
        "pp_minimum",
        "ipopt",
        {"x": gamma, "p": p, "f": energy / par("energy_ref"), "g": g_minimum},
        {**options, **ipopt_options(search_caps), "ipopt.acceptable_tol": 1e-9, "ipopt.acceptable_iter": 10},
    )
    evaluate = ca.Function("pp_evaluate", [gamma, p], [energy, residual, ca.vertcat(*free)])
    breach = ca.vertcat(ca.fabs(limit_rows) - 1.0, MIN_SEPARATION - separation)
    violation = ca.Function("pp_violation", [gamma, p], [ca.mmax(breach) if breach.numel() else ca.SX(-1.0)])
    return CompiledLaw(probe, quick, closest, minimum, evaluate, violation, (lbg_c, ubg_c, lbg_m, ubg_m), layout, start)


def _torque_rows(ca: Any, gamma: Any, coefs: Any, phi: Any, T: Any, sigma: Any, wd: Any, torque_par: Any) -> Any:
    """Motor torque J_M phi'' - k alpha - c alpha' of a two-inertia plant on the constraint grid.

    alpha'' + 2 zeta w alpha' + w^2 alpha = -phi'' (Cusimano eq. 4) is advanced exactly between grid
    points with phi'' held linearly, in modal form x' = lambda x + phi'' with lambda = -sigma + i w_d:
    alpha = -2 Re(x / (2 i w_d)) = -Im(x)/w_d and alpha' = -Im(lambda x)/w_d.
    """
    j_m, k, c = torque_par[0], torque_par[1], torque_par[2]
    n1 = gamma.numel()
    s_grid = np.arange(CONSTRAINT_INTERVALS + 1) / CONSTRAINT_INTERVALS
    log_u = ca.DM(np.log(np.maximum(1.0 - s_grid, 1e-300)))
    acc = 0
    for weight, power in derivative_terms([gamma[i] for i in range(n1)], [coefs[i] for i in range(n1)], 2):
        acc += weight * ca.exp(power * log_u)
    acc = -phi / T**2 * acc
    acc = ca.vertcat(acc[:-1], 0.0)  # phi''(T) = 0 for every exponent > 2
    dt = T / CONSTRAINT_INTERVALS
    lam = (-sigma, wd)
    e_re = ca.exp(-sigma * dt) * ca.cos(wd * dt)
    e_im = ca.exp(-sigma * dt) * ca.sin(wd * dt)
    # b1 = (E - 1 - lambda dt)/(lambda^2 dt), b0 = (E - 1)/lambda - b1 (first-order hold, exact)
    lam2 = _complex_mul(lam, lam)
    norm2 = lam2[0] ** 2 + lam2[1] ** 2
    num1 = (e_re - 1.0 + sigma * dt, e_im - wd * dt)
    b1 = (
        (num1[0] * lam2[0] + num1[1] * lam2[1]) / (norm2 * dt),
        (num1[1] * lam2[0] - num1[0] * lam2[1]) / (norm2 * dt),
    )
    norm1 = sigma**2 + wd**2
    num0 = (e_re - 1.0, e_im)
    q = ((num0[0] * lam[0] + num0[1] * lam[1]) / norm1, (num0[1] * lam[0] - num0[0] * lam[1]) / norm1)
    b0 = (q[0] - b1[0], q[1] - b1[1])
    x_re, x_im = 0, 0
    rows = []
    for step in range(CONSTRAINT_INTERVALS + 1):
        if step > 0:
            ex = _complex_mul((e_re, e_im), (x_re, x_im))
            x_re = ex[0] + b0[0] * acc[step - 1] + b1[0] * acc[step]
            x_im = ex[1] + b0[1] * acc[step - 1] + b1[1] * acc[step]
        alpha = -x_im / wd
        lx = _complex_mul(lam, (x_re, x_im))
        rate = -lx[1] / wd
        rows.append(j_m * acc[step] - k * alpha - c * rate)
    return ca.vertcat(*rows)


SYMBOLIC_KINDS = ("mode", "two_inertia", "belt_platform")  # second order: the mode has a closed form


def compiled_problem(
    order: int,
    modes: int,
    active: tuple[bool, bool, bool, bool],
    caps: SolveCaps,
    plant: Plant | None = None,
) -> CompiledLaw:
    """The cached problems: per plant kind for the symbolic kinds, per number of modes otherwise."""
    symbolic = plant if plant is not None and plant.kind in SYMBOLIC_KINDS else None
    key = (order, modes, active, caps, symbolic.symbolic_key() if symbolic is not None else None)
    return SOLVER_CACHE.get(key, lambda: _build(order, modes, active, caps, symbolic))


def active_limits(limits: Limits) -> tuple[bool, bool, bool, bool]:
    return (
        limits.max_velocity is not None,
        limits.max_acceleration is not None,
        limits.max_jerk is not None,
        limits.max_torque_nm is not None,
    )


def warm_up(caps: SolveCaps | None = None) -> None:
    """Build the common problems (orders 2-4, short moves, no limits, each second-order kind) in a
    new worker."""
    from models.plants import example_plants

    for plant in example_plants().values():
        if plant.kind in SYMBOLIC_KINDS:
            for order in (2, 3, 4):
                compiled_problem(order, 1, (False,) * 4, caps or SolveCaps(), plant)
