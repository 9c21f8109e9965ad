"""A continuous drive at its limits: its current reference and voltage clamped, its integrators kept from winding up.

The drive limits its current reference to +-max_torque_nm / K_T and, with a current loop, the current PI's output to
+-max_voltage_v. While a limit holds, the PI whose output it clamps is kept from winding up by back-calculation
(Astrom & Hagglund, Advanced PID Control, ISA 2006, Sec. 3.5): its integrator also receives (u_sat - u) / kp,
which tracks the integral term back to the limit with the time constant T_t = T_i = kp / ki. (Conditional
integration, which stops the integrator, makes the right-hand side discontinuous: a demand that grazes the limit
then chatters across it and no integrator gets past it.) With the corrections di = sat(i_ref) - i_ref and
dV = sat(V) - V as inputs (models.servo.assemble "limited") the loop is x' = A x + B (r, r', r'') + b_i di +
b_V dV, continuous and piecewise linear; it is integrated by scipy's LSODA at rtol 1e-10, restarted wherever the
command's acceleration or a lower derivative jumps, the command's derivatives evaluated exactly in between. A
velocity-mode drive's positions are integrated beside it from their rates.

Metrics. In the eigenbasis A = V diag(lambda) V^-1, a polynomial command has the particular modal state
q_p = (w b_v) r + (w b_a)(r' + lambda r) - alpha sum_m r^(m) / lambda^(m+1), alpha = w (b_r + lambda b_v +
lambda^2 b_a); h = V^-1 x - q_p is the free state, and an output is its quasi-static motion plus
Re sum_j (c v_j) kappa_j h_j (kappa = 1, or 1 / lambda for an integrated position). Once the command has ended
and, from a sample on, |steady value| + sum_j |c v_j h_j| stays within each limit, the loop can never reach a
limit again: from that sample (``free_from``) the load is the linear loop's free response, and models.metrics
measures it as any other. Where the drive is still at a limit when the command ends, the simulation goes on past
the end (the command continuing its last motion) until that holds, within MAX_EXTENSIONS."""

from __future__ import annotations

import bisect
import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from models.commands import PiecewiseCommand
from models.modal_data import FreeResponse, ModalForm, partial_fraction_taylor
from models.plants import Plant
from models.servo import OUTPUTS, ClosedLoop, Drive, assemble
from models.simulation import Response

Array = NDArray[np.float64]
CArray = NDArray[np.complex128]
RTOL = 1e-10
ATOL_RELATIVE = 1e-12  # LSODA's absolute tolerance, of the move (``_tolerances``)
MAX_EVALUATIONS = 100_000  # right-hand sides per simulation: its work cap (about 1.5 s on the 2-core machine)
EXTENSION_SAMPLES = 200  # samples per extension past the command's end
MAX_EXTENSIONS = 20
CERTIFY_MARGIN = 1e-9  # the bound must stay this share inside each limit
ROUND_OFF = 1e-9  # an acceleration (or higher) at the end below this share of its peak is round-off
_REAL_POLE_TOLERANCE = 1e-12


class WorkCapExceeded(Exception):
    """No answer within the work cap (the caller keeps the linear prediction and says why): more than
    MAX_EVALUATIONS right-hand sides, a free response not provably within the limits after MAX_EXTENSIONS, or a
    command that ends accelerating (it never returns to a steady state)."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


@dataclass(frozen=True)
class LimitedRun:
    """The outputs at the breakpoints of ``command`` (the request's, extended past its end where needed), the
    load's Response and the sample its free response is measured from."""

    command: PiecewiseCommand
    values: dict[str, Array]
    load: Response
    free_from: int


@dataclass(frozen=True)
class _Machine:
    a: Array
    b: Array
    rows: dict[str, tuple[Array, Array]]
    integrated: tuple[str, ...]
    limits: tuple[float, float]  # current reference (A), voltage (V)
    lam: CArray
    vectors: CArray
    inverse: CArray

    def signals(self, x: Array, c: Array) -> tuple[Array, Array, Array, Array]:  # (scalars for one column)
        """The current reference and the voltage before their clamps, and the corrections di, dV (vectorised over
        columns)."""
        i_max, v_max = self.limits
        ci, di_c = self.rows["current_reference"]
        demanded_i = ci @ x + di_c[:3] @ c
        di = np.clip(demanded_i, -i_max, i_max) - demanded_i
        cv, dv_c = self.rows["voltage_demand"]
        demanded_v = cv @ x + dv_c[:3] @ c + dv_c[3] * di
        dv = np.clip(demanded_v, -v_max, v_max) - demanded_v
        return demanded_i, demanded_v, di, dv

    @cached_property
    def modal_input(self) -> tuple[CArray, CArray]:
        """w b (each pole's input from r, r', r'') and alpha = w (b_r + lambda b_v + lambda^2 b_a)."""
        lam = self.lam
        wb = self.inverse @ self.b[:, :3]
        return wb, wb[:, 0] + lam * wb[:, 1] + lam * lam * wb[:, 2]

    def particular(self, derivatives: Array) -> CArray:
        """q_p at each column of p, p', ... (module docstring)."""
        lam = self.lam
        wb, alpha = self.modal_input
        r = derivatives
        orders = np.zeros((3, r.shape[1]))
        orders[: min(3, r.shape[0])] = r[:3]
        q: CArray = wb[:, 1:2] * orders[0] + wb[:, 2:3] * (orders[1] + lam[:, None] * orders[0])
        for m in range(r.shape[0]):  # a loop over orders
            q = q - (alpha / lam ** (m + 1))[:, None] * r[m]
        return q


def _machine(mechanics: Plant, drive: Drive, loop: ClosedLoop) -> _Machine:
    built = assemble(mechanics, drive, "limited")
    motor = drive.motor
    i_max = motor.max_torque_nm / motor.torque_constant_nm_per_a
    v_max = motor.max_voltage_v if drive.current is not None else math.inf  # no voltage loop to clamp without one
    lam, vectors, inverse = loop.eigenbasis
    integrated = tuple(name for name in OUTPUTS if name in loop.integrated)
    return _Machine(built.a, built.b, built.outputs, integrated, (i_max, v_max), lam, vectors, inverse)


def _rates(
    machine: _Machine, command: PiecewiseCommand, first: int, counter: list[int]
) -> Callable[[float, Array], Array]:
    """The right-hand side at t: z = (x, the integrated positions), z' = A_z z + B_z c + b_i di + b_V dV with c the
    command's (r, r', r'') on its piece (a table of each piece's coefficients: one product per call)."""
    a, b = machine.a, machine.b
    n = a.shape[0]
    rates = [machine.rows[name] for name in machine.integrated]
    a_z = np.zeros((n + len(rates), n + len(rates)))
    a_z[:n, :n] = a
    b_z = np.vstack([b, *[d[None, :] for _, d in rates]])
    for j, (row, _) in enumerate(rates):  # a loop over the integrated positions (at most three)
        a_z[n + j, :n] = row
    b_c, b_i, b_v = b_z[:, :3].copy(), b_z[:, 3].copy(), b_z[:, 4].copy()
    rows = np.vstack([machine.rows["current_reference"][0], machine.rows["voltage_demand"][0]])
    rows_c = np.vstack([machine.rows["current_reference"][1][:3], machine.rows["voltage_demand"][1][:3]])
    v_from_i = float(machine.rows["voltage_demand"][1][3])
    i_max, v_max = machine.limits
    time = command.time_s[first:].tolist()  # the pieces from ``first`` on: those integrated
    degree = command.degree
    # coefficients[k, m, j]: p^(m)(t_k + tau) = sum_j coefficients[k, m, j] tau^j, m < 3
    coefficients = np.zeros((len(time), 3, degree + 1))
    for m in range(min(3, degree + 1)):  # a loop over orders
        for j in range(degree + 1 - m):
            coefficients[:, m, j] = command.derivatives[m + j, first:] / math.factorial(j)
    exponents = np.arange(degree + 1)

    def rhs(t: float, z: Array) -> Array:
        counter[0] += 1
        if counter[0] > MAX_EVALUATIONS:
            raise WorkCapExceeded(f"the simulation at the drive's limits needs more than {MAX_EVALUATIONS} steps")
        k = min(max(bisect.bisect_right(time, t) - 1, 0), len(time) - 1)
        c = coefficients[k] @ ((t - time[k]) ** exponents)
        s_i, s_v = rows @ z[:n] + rows_c @ c
        di = min(max(s_i, -i_max), i_max) - s_i
        s_v += v_from_i * di
        dv = min(max(s_v, -v_max), v_max) - s_v
        out: Array = a_z @ z + b_c @ c
        if di != 0.0:
            out += di * b_i
        if dv != 0.0:
            out += dv * b_v
        return out

    return rhs


def _tolerances(command: PiecewiseCommand) -> float:
    """LSODA's absolute tolerance: ATOL_RELATIVE of the move (the command's largest excursion, or its largest
    position), so that a move of any size is integrated alike (the loop is linear between its limits)."""
    position = command.derivatives[0]
    size = max(float(np.max(np.abs(position - position[0]))), command.max_abs(0))
    return ATOL_RELATIVE * size if size > 0.0 else ATOL_RELATIVE


def _integrate(
    machine: _Machine, command: PiecewiseCommand, start: Array, first: int, counter: list[int], atol: float
) -> Array:
    """The state at every breakpoint from ``first`` on (columns), from ``start`` at breakpoint ``first``."""
    rhs = _rates(machine, command, first, counter)
    time = command.time_s
    jumps = command.jumps()[:3]
    restarts = [first, *(int(k) for k in np.flatnonzero(np.any(jumps[:, first + 1 :] != 0.0, axis=0)) + first + 1)]
    if restarts[-1] != time.size - 1:
        restarts.append(time.size - 1)
    states = np.empty((start.size, time.size - first))
    states[:, 0] = start
    for lo, hi in itertools.pairwise(restarts):  # a loop over the command's jumps (a few)
        sol = solve_ivp(
            rhs, (time[lo], time[hi]), states[:, lo - first], "LSODA", time[lo : hi + 1], rtol=RTOL, atol=atol
        )
        if not sol.success:
            raise WorkCapExceeded(f"the simulation at the drive's limits failed: {sol.message}")
        states[:, lo - first : hi - first + 1] = sol.y
    return states


def _certified(machine: _Machine, x: Array, c: Array, h: CArray) -> NDArray[np.bool_]:
    """Where the linear free response from each column provably stays within both limits (module docstring)."""
    ok = np.ones(x.shape[1], dtype=bool)
    demanded_i, demanded_v, _, _ = machine.signals(x, c)
    for name, limit in zip(("current_reference", "voltage_demand"), machine.limits, strict=True):
        if not math.isfinite(limit):
            continue
        row = machine.rows[name][0]
        modal = np.abs(row @ machine.vectors)
        free = modal @ np.abs(h)
        steady = (demanded_i if name == "current_reference" else demanded_v) - np.real((row @ machine.vectors) @ h)
        ok &= np.abs(steady) + free <= limit * (1.0 - CERTIFY_MARGIN)
    return ok


def _extended(command: PiecewiseCommand, span_s: float) -> PiecewiseCommand:
    """``command`` with EXTENSION_SAMPLES breakpoints more over ``span_s`` past its last, its last motion going on."""
    last = float(command.time_s[-1])
    more = last + span_s * np.arange(1, EXTENSION_SAMPLES + 1) / EXTENSION_SAMPLES
    values = command.evaluate_at_instants(more, orders=command.degree + 1)
    return PiecewiseCommand(
        np.concatenate([command.time_s, more]),
        np.concatenate([command.derivatives, values], axis=1),
        command.continuous_orders,
        command.motion_before,
    )


def simulate_limited(
    mechanics: Plant, drive: Drive, command: PiecewiseCommand, loop: ClosedLoop, load_modal: ModalForm, plant: Plant
) -> LimitedRun:
    """``command`` through the drive with its limits (module docstring); ``load_modal``: the linear loop's load
    output (its Taylor coefficients), ``plant``: the load Response's. WorkCapExceeded where it cannot answer."""
    machine = _machine(mechanics, drive, loop)
    n = machine.a.shape[0]
    before = np.array([[command.before(m)] for m in range(command.degree + 1)])
    x0 = np.real(machine.vectors @ machine.particular(before))[:, 0]
    start = np.concatenate([x0, [_quasi_static(loop, name, before[:, 0]) for name in machine.integrated]])
    end = command.end_index()
    if any(abs(command.derivatives[m, end]) > ROUND_OFF * command.max_abs(m) for m in range(2, command.degree + 1)):
        raise WorkCapExceeded("the command ends accelerating: the drive never returns to a steady state")
    counter = [0]
    atol = _tolerances(command)
    states = _integrate(machine, command, start, 0, counter, atol)
    span = float(command.time_s[-1] - command.time_s[0]) or 1.0
    for extensions in range(MAX_EXTENSIONS + 1):  # a loop over extensions past the end (usually none)
        c = _orders(command.derivatives, 0)
        h = machine.inverse @ states[:n] - machine.particular(command.derivatives)
        ok = _certified(machine, states[:n], c, h)
        ok[:end] = False
        found = np.flatnonzero(ok)
        if found.size:
            break
        if extensions == MAX_EXTENSIONS:
            raise WorkCapExceeded(
                f"the drive is still at a limit {MAX_EXTENSIONS} times the command's duration after its end"
            )
        command = _extended(command, span)
        more = _integrate(machine, command, states[:, -1], states.shape[1] - 1, counter, atol)
        states = np.concatenate([states, more[:, 1:]], axis=1)
    x = states[:n]
    demanded_i, demanded_v, di, dv = machine.signals(x, c)
    values = {}
    for name in OUTPUTS:  # a loop over outputs
        if name in machine.integrated:
            values[name] = states[n + machine.integrated.index(name)]
            continue
        row, d = machine.rows[name]
        values[name] = row @ x + d[:3] @ c + d[3] * di + d[4] * dv
    if drive.current is None:  # the torque is the clamped reference: K_T (T_max / K_T) is T_max up to round-off
        limit = drive.motor.max_torque_nm
        values["torque_nm"] = np.clip(values["torque_nm"], -limit, limit)
    motion = _load_motion(machine, x, command.derivatives, (demanded_i, demanded_v, di, dv))
    load = _load(machine, loop, command, (values["load_position"], *motion), h, load_modal, plant, int(found[0]))
    return LimitedRun(command, values, load, int(found[0]))


def _orders(derivatives: Array, first: int) -> Array:
    """Rows first .. first + 2 of the command's derivatives (zero above its degree)."""
    out = np.zeros((3, derivatives.shape[1]))
    rows = derivatives[first : first + 3]
    out[: rows.shape[0]] = rows
    return out


def _load_motion(
    machine: _Machine, x: Array, derivatives: Array, signals: tuple[Array, Array, Array, Array]
) -> tuple[Array, Array]:
    """The load's velocity and acceleration at the samples, exact: its rate y' = e x + f u (the position row's
    rate, or a velocity-mode drive's rate row), and y'' = e x' + f_c c' (the load is not driven by the clamps'
    corrections directly: f's last two entries are 0 by the loop's structure)."""
    a, b = machine.a, machine.b
    _, _, di, dv = signals
    c, rate_c = _orders(derivatives, 0), _orders(derivatives, 1)
    row, d = machine.rows["load_position"]
    e, f = (row, d) if "load_position" in machine.integrated else (row @ a, row @ b)
    dx = a @ x + b[:, :3] @ c + np.outer(b[:, 3], di) + np.outer(b[:, 4], dv)
    velocity = e @ x + f[:3] @ c + f[3] * di + f[4] * dv
    return velocity, e @ dx + f[:3] @ rate_c


def _quasi_static(loop: ClosedLoop, name: str, before: Array) -> float:
    """An integrated output's value at rest in the motion before the command, sum_m g_m p^(m)(t_0-)."""
    output = loop.modal(name)
    return float(partial_fraction_taylor(output.polynomial, output.residues, loop.poles, before.size) @ before)


def _load(
    machine: _Machine,
    loop: ClosedLoop,
    command: PiecewiseCommand,
    motion: tuple[Array, Array, Array],
    h: CArray,
    load_modal: ModalForm,
    plant: Plant,
    free_from: int,
) -> Response:
    """The load as a models.simulation.Response: residues (c v_j) kappa_j, free states h_j, per-pole Taylor terms
    -alpha_j / lambda_j^(m+1) (module docstring). A velocity-mode drive's load position is outside its loop: the
    position its limit cost is never recovered, a constant offset from ``free_from`` on that no pole of the loop
    carries. It is kept as a pole at s = 0 (residue the offset, free state 1, no Taylor terms), which the metrics
    count in the load's position band, not as vibration."""
    lam = machine.lam
    row = machine.rows["load_position"][0]
    kappa = 1.0 / lam if "load_position" in machine.integrated else np.ones_like(lam)
    residues = (row @ machine.vectors) * kappa
    alpha = machine.modal_input[1]
    orders = np.arange(command.degree + 1)
    pole_taylor = -alpha[:, None] / lam[:, None] ** (orders[None, :] + 1)
    flat = np.abs(lam.imag) <= _REAL_POLE_TOLERANCE * np.abs(lam)
    keep = flat | (lam.imag > 0.0)
    modal = ModalForm(
        load_modal.taylor,
        np.where(flat, lam.real + 0j, lam)[keep],
        np.where(flat, residues.real + 0j, residues)[keep],
        np.where(flat[keep], 1.0, 2.0),
        pole_taylor[keep],
    )
    free = tuple(FreeResponse(values=v) for v in h[keep])
    if "load_position" in machine.integrated:
        position = motion[0]
        count = command.degree + 1
        rebuilt = modal.taylor[:count] @ command.derivatives[:count, free_from]
        rebuilt += float(np.real(np.sum(modal.weights * modal.residues * h[keep, free_from])))
        offset = float(position[free_from] - rebuilt)
        modal = ModalForm(
            modal.taylor,
            np.append(modal.poles, 0.0 + 0.0j),
            np.append(modal.residues, offset + 0.0j),
            np.append(modal.weights, 1.0),
            np.vstack([pole_taylor[keep], np.zeros((1, count))]),
        )
        free = (*free, FreeResponse(values=np.ones(position.size, dtype=complex)))
    return Response(plant, command, modal, *motion, free)
