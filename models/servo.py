"""The drive in the loop: a cascaded servo (position P, velocity PI, current PI) driving the mechanics.

Continuous-time, linear between its saturations. The command (position r, with its velocity r' and
acceleration r'' as feed-forward) enters

    w_ref = kp_p (r - th_M) + r'                      (position loop, velocity feed-forward)
    T_ref = kp_v (w_ref - w_M) + ki_v int(w_ref - w_M) + J r''   (velocity PI, torque feed-forward)
    V     = kp_i (i_ref - i) + ki_i int(i_ref - i),  i_ref = T_ref / K_T   (current PI)
    L i'  = V - R i - K_E w_M,   T = K_T i            (the motor's winding)

and the torque drives the mechanics: on a two_inertia plant J_M w_M' = T - k (th_M - th_L) - c (w_M - w_L),
J_L w_L' = k (th_M - th_L) + c (w_M - w_L) (Cusimano Fig. 1, the load's reaction on the motor); on every other
kind the motor (``Motor.inertia_kgm2``) is driven alone and the load follows its position through the plant's
G(s) (a load too light to react). Without a current loop the torque is its reference. Without a position loop
the drive follows the command's velocity (a velocity-mode drive, Cusimano Fig. 20): w_ref = r', no position is a
state, and the positions are outputs given by their rates (``ClosedLoop.integrated``).

Every output y (motor position, velocity, acceleration, current, torque, voltage, load position, tracking error)
is linear in the state x and the command, y = c x + d_r r + d_v r' + d_a r''; from the command's position it is
H(s) = c (sI - A)^-1 (b_r + s b_v + s^2 b_a) + d_r + s d_v + s^2 d_a. With A = V diag(lambda) V^-1 this is

    H(s) = P0 + P1 s + P2 s^2 + sum_j rho_j / (s - lambda_j),
    rho_j = (c v_j)(w_j . (b_r + lambda_j b_v + lambda_j^2 b_a)),
    P0 = d_r + c b_v + c A b_a,  P1 = d_v + c b_a,  P2 = d_a   (sum_j v_j w_j = I, sum_j lambda_j v_j w_j = A),

the partial fractions that models.simulation needs, from the eigenvectors rather than from polynomial
coefficients (whose roots lose the closed loop's slow poles when its current loop is a thousand times faster).

Gains from bandwidths (rad/s = 2 pi bandwidth_hz): the current PI by internal model control (Harnefors & Nee
1998, "Model-based current control of AC machines using the internal model control method", IEEE Trans. Ind.
Appl. 34(1): kp = L w_i, ki = R w_i, the PI's zero cancelling the winding's pole R/L, a first-order loop of
bandwidth w_i); the velocity PI by the symmetric optimum (Kessler 1958; a = 2: kp = J w_v, ki = J w_v^2 / a, in
torque units, J the inertia the loop moves); the position loop kp_p = w_p.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from models.errors import InvalidParameter
from models.plant_base import Mode, StateSpace
from models.plants import Plant, TwoInertiaPlant

Array = NDArray[np.float64]
CArray = NDArray[np.complex128]
SYMMETRIC_OPTIMUM_A = 2.0  # Kessler's a: the velocity PI's corner ki / kp = w / a lies a times below its crossover
# As models.plants.TransferFunctionPlant: a pole with Re > this x |pole| is unstable, and so is a real one with
# Re >= -this x |pole| (an integrator left in the loop); an undamped pair (Re ~ 1e-16 |pole|) is a mode of an
# undamped load, as on an ideal motor.
STABLE_MARGIN = 1e-9
# The partial fractions must give H(s) back to this share of its terms' sizes at a test point (2 pi 1e4 rad/s
# current loops beside a 10 Hz mode: 3.5e-8, eigenvectors of condition 3e5; nearly repeated poles: of order 1).
PARTIAL_FRACTIONS_RTOL = 1e-6
REPEATED = (
    "the closed loop's poles are (nearly) repeated: its partial fractions are not accurate; change a bandwidth or a "
    "gain slightly"
)
OUTPUTS = (
    "motor_position",
    "motor_velocity",
    "motor_acceleration",
    "current_a",
    "torque_nm",
    "voltage_v",
    "load_position",
    "tracking_error",
)


@dataclass(frozen=True)
class Motor:
    """The motor's electrical data and limits; ``inertia_kgm2`` where the mechanics do not give J_M."""

    resistance_ohm: float
    inductance_h: float
    torque_constant_nm_per_a: float
    back_emf_v_s_per_rad: float | None = None  # K_E, default K_T (SI units: the same constant)
    max_torque_nm: float = math.inf
    max_voltage_v: float = math.inf
    inertia_kgm2: float | None = None

    @property
    def k_e(self) -> float:
        return self.torque_constant_nm_per_a if self.back_emf_v_s_per_rad is None else self.back_emf_v_s_per_rad


@dataclass(frozen=True)
class PI:
    """A PI controller: kp e + ki int(e)."""

    kp: float
    ki: float


@dataclass(frozen=True)
class Drive:
    """A cascade: position P (``position_kp_per_s``), velocity PI (torque per rad/s and per rad), current PI (volts
    per ampere and per ampere-second; None: the torque is its reference), feed-forward, the motor; continuous, or
    its position and velocity loops sampled every ``sample_period_s`` (models.servo_sampled)."""

    position_kp_per_s: float | None  # None: no position loop, the drive follows the command's velocity
    velocity: PI
    current: PI | None
    motor: Motor
    velocity_feedforward: bool = True
    acceleration_feedforward: bool = True
    sample_period_s: float | None = None  # the position and velocity loops' (models.servo_sampled); None: continuous


def current_pi(bandwidth_hz: float, motor: Motor) -> PI:
    """Internal model control of the winding (Harnefors & Nee 1998): kp = L w, ki = R w."""
    omega = 2.0 * math.pi * bandwidth_hz
    return PI(motor.inductance_h * omega, motor.resistance_ohm * omega)


def velocity_pi(bandwidth_hz: float, inertia_kgm2: float) -> PI:
    """Symmetric optimum (Kessler 1958) with a = SYMMETRIC_OPTIMUM_A: kp = J w, ki = J w^2 / a (torque units)."""
    omega = 2.0 * math.pi * bandwidth_hz
    return PI(inertia_kgm2 * omega, inertia_kgm2 * omega * omega / SYMMETRIC_OPTIMUM_A)


def moved_inertia(mechanics: Plant, motor: Motor) -> float:
    """The inertia the velocity loop moves: J_M + J_L on a two_inertia plant, else the motor's own."""
    if isinstance(mechanics, TwoInertiaPlant):
        return mechanics.motor_inertia_kgm2 + mechanics.load_inertia_kgm2
    if motor.inertia_kgm2 is None:
        raise InvalidParameter(
            "drive.motor.inertia_kgm2",
            None,
            f"is required with a {mechanics.kind} plant (it gives no motor inertia; a two_inertia plant does)",
        )
    return motor.inertia_kgm2


@dataclass(frozen=True)
class ModalOutput:
    """One output's H(s) = P0 + P1 s + P2 s^2 + sum_j residues_j / (s - poles_j) over every eigenvalue."""

    polynomial: tuple[float, float, float]
    residues: CArray


class _Rows:
    """Linear signals over the state x and the inputs (the command's r, r', r''; a sampled drive's held torque
    reference): (row over x, row over the inputs)."""

    def __init__(self, states: int, inputs: int = 3) -> None:
        self.states = states
        self.inputs = inputs

    def zero(self) -> tuple[Array, Array]:
        return np.zeros(self.states), np.zeros(self.inputs)

    def state(self, index: int) -> tuple[Array, Array]:
        x, u = self.zero()
        x[index] = 1.0
        return x, u

    def command(self, order: int) -> tuple[Array, Array]:
        x, u = self.zero()
        u[order] = 1.0
        return x, u


@np.errstate(all="ignore")  # (closed_loop refuses a matrix that is not finite)
def _comb(*terms: tuple[float, tuple[Array, Array]]) -> tuple[Array, Array]:
    """sum_k c_k signal_k."""
    x = sum((c * s[0] for c, s in terms), np.zeros_like(terms[0][1][0]))
    u = sum((c * s[1] for c, s in terms), np.zeros_like(terms[0][1][1]))
    return x, u


@dataclass(frozen=True)
class ClosedLoop:
    """x' = A x + B (r, r', r''), and each output's (c, d) rows (``OUTPUTS``); ``poles``: eig(A). An output in
    ``integrated`` is given by its rate (a velocity-mode drive has no position state): y' = c x + d (r, r', r'')
    with no r in it, so that y / r = (c (sI - A)^-1 (b_v + s b_a) + d_v + s d_a), the rows shifted one order."""

    a: Array
    b: Array
    outputs: dict[str, tuple[Array, Array]]
    integrated: frozenset[str] = frozenset()

    @cached_property
    def poles(self) -> CArray:
        return self.eigenbasis[0]

    def modes(self) -> tuple[Mode, ...]:
        """The closed loop's oscillatory poles (one of each pair), lowest natural frequency first."""
        upper = sorted((p for p in self.poles if p.imag > STABLE_MARGIN * abs(p)), key=abs)
        return tuple(Mode.from_pole(complex(p)) for p in upper)

    def rows(self, name: str) -> tuple[Array, Array, Array]:
        """(c, d, B) of output ``name`` as a function of the command's position (shifted where integrated)."""
        c, d = self.outputs[name]
        if name not in self.integrated:
            return c, d, self.b
        shift = np.zeros_like(self.b)
        shift[:, :2] = self.b[:, 1:]
        return c, np.array([d[1], d[2], 0.0]), shift

    @cached_property
    def eigenbasis(self) -> tuple[CArray, CArray, CArray]:
        """(lambda, V, V^-1) with A = V diag(lambda) V^-1."""
        values, vectors = np.linalg.eig(self.a)
        try:
            inverse = np.linalg.inv(vectors)
        except np.linalg.LinAlgError:  # a defective matrix: repeated poles with one eigenvector
            raise InvalidParameter("drive", "repeated poles", REPEATED) from None
        return values.astype(complex), vectors.astype(complex), inverse.astype(complex)

    def modal(self, name: str) -> ModalOutput:
        """H(s) of output ``name`` in partial fractions (module docstring)."""
        c, d, b = self.rows(name)
        lam, v, w = self.eigenbasis
        b_r, b_v, b_a = b[:, 0], b[:, 1], b[:, 2]
        drive = w @ b_r + lam * (w @ b_v) + lam * lam * (w @ b_a)
        c_v = c @ v
        residues = c_v * drive
        p0 = d[0] + c @ b_v + c @ self.a @ b_a
        output = ModalOutput((float(p0), float(d[1] + c @ b_a), float(d[2])), residues)
        self._check_partial_fractions(name, output, np.abs(c_v) * np.abs(drive))
        return output

    def _check_partial_fractions(self, name: str, output: ModalOutput, residue_sizes: Array) -> None:
        """Refuse partial fractions that do not reproduce H(s) at a point of the right half-plane (nearly repeated
        poles: eigenvectors nearly parallel), as models.plants does for a transfer function."""
        lam = self.eigenbasis[0]
        s = float(np.max(np.abs(lam))) * (0.5 + 0.5j)
        c, d, columns = self.rows(name)
        b = columns[:, 0] + s * columns[:, 1] + s * s * columns[:, 2]
        with np.errstate(all="ignore"):
            x = np.linalg.solve(s * np.eye(lam.size) - self.a, b)
            exact = c @ x + d[0] + s * d[1] + s * s * d[2]
            p0, p1, p2 = output.polynomial
            terms = output.residues / (s - lam)
            rebuilt = p0 + p1 * s + p2 * s * s + np.sum(terms)
            # the terms' sizes before their factors cancel (an output that is 0, the error of an exact feed-forward)
            size = float(np.sum(residue_sizes / np.abs(s - lam)) + np.sum(np.abs(c) * np.abs(x)))
            size += abs(p0) + abs(p1 * s) + abs(p2 * s * s)
        if not (np.isfinite(rebuilt) and abs(rebuilt - exact) <= PARTIAL_FRACTIONS_RTOL * max(size, 1e-300)):
            raise InvalidParameter("drive", name, REPEATED)


def closed_loop(mechanics: Plant, drive: Drive) -> ClosedLoop:
    """The continuous closed loop of ``drive`` on ``mechanics`` (module docstring); InvalidParameter naming the
    gains if it is not stable. Without a position loop (``position_kp_per_s`` None) the drive follows the command's
    velocity (Cusimano Fig. 20): no position is a state, and the positions are outputs given by their rates."""
    built = assemble(mechanics, drive)
    positions = drive.position_kp_per_s is not None
    integrated = frozenset() if positions else frozenset({"motor_position", "load_position", "tracking_error"})
    loop = ClosedLoop(built.a, built.b, built.outputs, integrated)
    _check_stable(loop, drive)
    return loop


@dataclass(frozen=True)
class Assembly:
    """x' = A x + B u and every output's (c, d) rows."""

    a: Array
    b: Array
    outputs: dict[str, tuple[Array, Array]]


def assemble(mechanics: Plant, drive: Drive, inputs: str = "command") -> Assembly:
    """The loop's matrices and rows, by what enters it:

    - "command": u = (r, r', r''), the loop of ``closed_loop``;
    - "held_torque": u = (r, r', r'', T_ref), the continuous part of a sampled drive (models.servo_sampled): the
      motor, its current loop and the mechanics, the torque reference an input (needs a position loop);
    - "limited": u = (r, r', r'', di, dV), the corrections a drive's limits add to its current reference and its
      voltage (models.servo_limits), which also feed each PI's integrator back (anti-windup by back-calculation),
      with the outputs ``current_reference`` and ``voltage_demand`` before them.

    InvalidParameter if a matrix is not finite."""
    held_torque, limited = inputs == "held_torque", inputs == "limited"
    motor = drive.motor
    two_inertia = isinstance(mechanics, TwoInertiaPlant)
    inertia = moved_inertia(mechanics, motor)
    load = None if two_inertia else mechanics.state_space()
    positions = drive.position_kp_per_s is not None
    n_load = 2 if two_inertia else (0 if load is None else load.a.shape[0])
    # states: [th_M,] w_M, the load's (th_L or th_M - th_L, w_L; or G's realisation), i, [int(e_v),] int(e_i)
    th_m = 0 if positions else -1
    w_m = th_m + 1
    first_load = w_m + 1
    index = first_load + n_load
    i_state = index if drive.current is not None else -1
    index += drive.current is not None
    xi_v = -1 if held_torque else index
    index += not held_torque
    xi_i = index if drive.current is not None else -1
    n = index + (drive.current is not None)
    rows = _Rows(n, {"command": 3, "held_torque": 4, "limited": 5}[inputs])
    a, b = np.zeros((n, n)), np.zeros((n, rows.inputs))

    def set_derivative(state: int, signal: tuple[Array, Array]) -> None:
        a[state], b[state] = signal

    motor_velocity = rows.state(w_m)
    if positions:
        assert drive.position_kp_per_s is not None
        e_p = _comb((1.0, rows.command(0)), (-1.0, rows.state(th_m)))
        w_ref = _comb((drive.position_kp_per_s, e_p), (float(drive.velocity_feedforward), rows.command(1)))
        set_derivative(th_m, motor_velocity)
        motor_position = rows.state(th_m)
    else:  # the velocity reference is the command's velocity; the positions are integrals (ClosedLoop.integrated)
        w_ref = rows.command(1)
        e_p = _comb((1.0, rows.command(1)), (-1.0, motor_velocity))
        motor_position = motor_velocity
    if held_torque:
        t_ref = rows.command(3)
    else:
        e_v = _comb((1.0, w_ref), (-1.0, motor_velocity))
        feedforward = inertia if drive.acceleration_feedforward else 0.0
        t_ref = _comb((drive.velocity.kp, e_v), (drive.velocity.ki, rows.state(xi_v)), (feedforward, rows.command(2)))
        k_t = motor.torque_constant_nm_per_a
        # at a limit the integral tracks the clamped torque back (models.servo_limits): + (T_sat - T_ref) / kp
        tracking = (k_t / drive.velocity.kp, rows.command(3)) if limited else (0.0, rows.zero())
        set_derivative(xi_v, _comb((1.0, e_v), tracking))
    k_t = motor.torque_constant_nm_per_a
    demanded = _comb((1.0 / k_t, t_ref))
    i_ref = _comb((1.0, demanded), (1.0, rows.command(3))) if limited else demanded
    demand = None
    if drive.current is not None:
        e_i = _comb((1.0, i_ref), (-1.0, rows.state(i_state)))
        demand = _comb((drive.current.kp, e_i), (drive.current.ki, rows.state(xi_i)))
        voltage = _comb((1.0, demand), (1.0, rows.command(4))) if limited else demand
        current = rows.state(i_state)
        back_emf = _comb((motor.k_e, motor_velocity))
        winding = _comb((1.0, voltage), (-motor.resistance_ohm, current), (-1.0, back_emf))
        set_derivative(i_state, _comb((1.0 / motor.inductance_h, winding)))
        tracking = (1.0 / drive.current.kp, rows.command(4)) if limited else (0.0, rows.zero())
        set_derivative(xi_i, _comb((1.0, e_i), tracking))
    else:
        current = i_ref
        voltage = _comb((motor.resistance_ohm, current), (motor.k_e, motor_velocity))  # the winding's steady need
    torque = _comb((k_t, current))
    if two_inertia:
        assert isinstance(mechanics, TwoInertiaPlant)
        motor_accel, load_position = _two_inertia(
            mechanics, rows, set_derivative, positions, th_m, w_m, first_load, torque
        )
    else:
        assert load is not None
        motor_accel = _comb((1.0 / inertia, torque))
        load_position = _kinematic_load(load, rows, set_derivative, th_m if positions else w_m, first_load)
    set_derivative(w_m, motor_accel)
    outputs = {
        "motor_position": motor_position,
        "motor_velocity": motor_velocity,
        "motor_acceleration": motor_accel,
        "current_a": current,
        "torque_nm": torque,
        "voltage_v": voltage,
        "load_position": load_position,
        "tracking_error": e_p,
    }
    if limited:
        outputs["current_reference"] = demanded
        outputs["voltage_demand"] = voltage if demand is None else demand
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise InvalidParameter(
            "drive",
            "not finite",
            "the gains, the motor's data and the plant span scales too far apart for double precision",
        )
    return Assembly(a, b, outputs)


Setter = Callable[[int, tuple[Array, Array]], None]


def _two_inertia(
    mechanics: TwoInertiaPlant,
    rows: _Rows,
    set_derivative: Setter,
    positions: bool,
    th_m: int,
    w_m: int,
    first: int,
    torque: tuple[Array, Array],
) -> tuple[tuple[Array, Array], tuple[Array, Array]]:
    """Cusimano Fig. 1's shaft (the load's reaction on the motor): the motor's acceleration, and the load's position
    (its rate where ``positions`` is False). States at ``first``: th_L (or the twist th_M - th_L), w_L."""
    k, c = mechanics.stiffness_nm_per_rad, mechanics.damping_nms_per_rad
    j_m, j_l = mechanics.motor_inertia_kgm2, mechanics.load_inertia_kgm2
    angle, w_l = first, first + 1
    slip = _comb((1.0, rows.state(w_m)), (-1.0, rows.state(w_l)))
    if positions:
        twist_angle = _comb((1.0, rows.state(th_m)), (-1.0, rows.state(angle)))
        set_derivative(angle, rows.state(w_l))
        load = rows.state(angle)
    else:
        twist_angle = rows.state(angle)
        set_derivative(angle, slip)
        load = rows.state(w_l)
    twist = _comb((k, twist_angle), (c, slip))
    set_derivative(w_l, _comb((1.0 / j_l, twist)))
    return _comb((1.0 / j_m, torque), (-1.0 / j_m, twist)), load


def _kinematic_load(
    load: StateSpace, rows: _Rows, set_derivative: Setter, driver: int, first: int
) -> tuple[Array, Array]:
    """A load too light to react, following the motor through G(s): its realisation driven by state ``driver`` (the
    motor's position, or its velocity, which gives the load's velocity); that output."""
    count = load.a.shape[0]
    z = slice(first, first + count)
    for row in range(count):  # a loop over the realisation's few states
        x = np.zeros(rows.states)
        x[z] = load.a[row]
        x[driver] += float(load.b[row, 0])
        set_derivative(first + row, (x, np.zeros(rows.inputs)))
    x = np.zeros(rows.states)
    x[z] = load.c[0]
    x[driver] += float(load.d[0, 0])
    return x, np.zeros(rows.inputs)


def unstable(poles: CArray) -> bool:
    """A pole right of the imaginary axis, or a real one on it (an integrator), to STABLE_MARGIN (module top)."""
    size = STABLE_MARGIN * np.abs(poles)
    oscillatory = np.abs(poles.imag) > size
    return bool(np.any((poles.real > size) | (~oscillatory & (poles.real >= -size))))


def _check_stable(loop: ClosedLoop, drive: Drive) -> None:
    poles = loop.poles
    if not unstable(poles):
        return
    position = "none" if drive.position_kp_per_s is None else f"{drive.position_kp_per_s:g} 1/s"
    gains = f"position kp {position}, velocity kp {drive.velocity.kp:g} ki {drive.velocity.ki:g}"
    if drive.current is not None:
        gains += f", current kp {drive.current.kp:g} ki {drive.current.ki:g}"
    worst = sorted(poles, key=lambda p: -p.real)[:4]
    listed = ", ".join(f"{p.real:.4g}{p.imag:+.4g}j ({abs(p) / (2 * math.pi):.3g} Hz)" for p in worst)
    raise InvalidParameter(
        "drive",
        gains,
        f"the closed loop with these gains is unstable: its rightmost poles are {listed} 1/s (every real part must "
        "be negative): lower the bandwidths or gains",
    )
