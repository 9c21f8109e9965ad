"""A sampled drive: the position and velocity loops run digitally every T_s, the rest stays continuous.

At t_k = k T_s the controller reads the motor's position th_k and velocity w_k (an encoder and a velocity
estimate at the sample; a backward difference of the position would add half a sample of lag) and the command
r_k, r'_k, r''_k, and computes (models.servo's laws, the integral by the backward rectangle rule)

    e_v = kp_p (r_k - th_k) + r'_k - w_k,   xi_(k+1) = xi_k + T_s e_v,
    T_ref,k = kp_v e_v + ki_v xi_(k+1) + J r''_k,

which reaches the current loop one sample later (one sample of computation delay) and is held over
[t_(k+1), t_(k+2)) (zero-order hold). The motor, its current loop (continuous: it runs far faster than the
motion loops) and the mechanics are discretised exactly over one sample, [x_(k+1); u] = expm(T_s [A B; 0 0])
[x_k; u] (Franklin, Powell & Workman, Digital Control of Dynamic Systems, 3rd ed., Sec. 4.3.3), so that with
z = (x, xi, u) the loop is z_(k+1) = F z_k + G c_k, c_k = (r_k, r'_k, r''_k): exact at the samples for any
command, whose value, velocity and acceleration the controller samples.

Simulation: with F = V diag(mu) V^-1 each modal coordinate q_j = (V^-1 z)_j is a first-order recurrence
q_(k+1) = mu_j q_k + (V^-1 G c_k)_j (one ``lfilter``, no Python loop over samples). While the command is a
polynomial p, q_j has the particular solution sum_m gamma_jm p^(m)(t_k), gamma_jm the Taylor coefficients at
s = 0 of (V^-1 G)_j (1, s, s^2) / (e^(s T_s) - mu_j); h_j = q_j - that is the free response, which after the
command's end decays as mu_j^k = exp(s_j t), s_j = ln(mu_j) / T_s. An output y = c z + d c_k is then
sum_m g_m p^(m) + Re sum_j w_j r_j h_j with r_j = c v_j: a models.simulation.Response with the equivalent poles
s_j, measured by models.metrics like every other. Its values, settling and residual are those at the samples
(the load's motion between samples is not in them: a mode well below the Nyquist frequency moves little in a
sample).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import expm
from scipy.signal import lfilter

from models.commands import PiecewiseCommand
from models.errors import InvalidParameter
from models.modal_data import FreeResponse, ModalForm
from models.plant_base import Mode
from models.plants import Plant
from models.servo import REPEATED, Drive, assemble, moved_inertia, unstable
from models.simulation import Response

Array = NDArray[np.float64]
CArray = NDArray[np.complex128]
PREPARED_CACHE = 32
# V diag(mu) V^-1 must give F back to this share of its size (eigenvectors nearly parallel: repeated poles).
EIGEN_RTOL = 1e-9
_REAL_POLE_TOLERANCE = 1e-12
_TINY = 1e-300  # |mu| below this is a pole that is gone after one sample (ln would be -inf)


@dataclass(frozen=True)
class SampledLoop:
    """z_(k+1) = F z_k + G c_k and each output's rows (over z, over c) (module docstring), F's eigenpairs."""

    period_s: float
    f: Array
    g: Array
    outputs: dict[str, tuple[Array, Array]]
    mu: CArray
    vectors: CArray
    inverse: CArray

    @cached_property
    def modal_input(self) -> CArray:
        """V^-1 G: each pole's input from the command's r, r', r''."""
        product: CArray = self.inverse @ self.g
        return product

    @property
    def flat(self) -> NDArray[np.bool_]:
        """Real poles mu (a negative one rings at the Nyquist frequency, with no conjugate)."""
        real: NDArray[np.bool_] = np.abs(self.mu.imag) <= _REAL_POLE_TOLERANCE * np.abs(self.mu)
        return real

    @property
    def poles(self) -> CArray:
        """The equivalent continuous poles ln(mu) / T_s (a pole gone in one sample: very fast; a negative real
        one: Im = pi / T_s)."""
        size = np.maximum(np.abs(self.mu), _TINY)
        angle = np.where(self.flat, np.where(self.mu.real < 0.0, math.pi, 0.0), np.angle(self.mu))
        poles: CArray = (np.log(size) + 1j * angle) / self.period_s
        return poles

    def modes(self) -> tuple[Mode, ...]:
        """The loop's oscillatory poles (one of each pair) as modes, lowest natural frequency first."""
        upper = sorted(
            (p for p, m in zip(self.poles, self.mu, strict=True) if m.imag > _REAL_POLE_TOLERANCE * abs(m)), key=abs
        )
        return tuple(Mode.from_pole(complex(p)) for p in upper)


@functools.lru_cache(maxsize=PREPARED_CACHE)
def sampled_loop(mechanics: Plant, drive: Drive) -> SampledLoop:
    """The loop of ``drive`` sampled every ``drive.sample_period_s`` on ``mechanics`` (module docstring);
    InvalidParameter on ``drive`` if it has no position loop, is unstable, or its poles are (nearly) repeated."""
    period_s = drive.sample_period_s
    assert period_s is not None and period_s > 0.0
    if drive.position_kp_per_s is None:
        raise InvalidParameter(
            "drive.position_loop",
            None,
            "a sampled drive needs its position loop (a velocity-mode drive is modelled with continuous loops: "
            "sample_period_s null)",
        )
    built = assemble(mechanics, drive, "held_torque")
    a, b, rows = built.a, built.b, built.outputs
    _check_nyquist(a, period_s)
    n = a.shape[0]
    augmented = np.zeros((n + 1, n + 1))
    augmented[:n, :n], augmented[:n, n] = a, b[:, 3]
    step = expm(period_s * augmented)
    # z = (x, xi, u): the continuous part, the velocity PI's integral, the torque reference being applied
    xi, u = n, n + 1
    f, g = np.zeros((n + 2, n + 2)), np.zeros((n + 2, 3))
    f[:n, :n], f[:n, u] = step[:n, :n], step[:n, n]
    kp = drive.position_kp_per_s
    e_v_z, e_v_c = np.zeros(n + 2), np.array([kp, float(drive.velocity_feedforward), 0.0])
    e_v_z[0], e_v_z[1] = -kp, -1.0  # th_M and w_M are the first two states (models.servo.assemble)
    f[xi], g[xi] = period_s * e_v_z, period_s * e_v_c
    f[xi, xi] = 1.0
    kv, ki = drive.velocity.kp, drive.velocity.ki
    feedforward = moved_inertia(mechanics, drive.motor) if drive.acceleration_feedforward else 0.0
    f[u], g[u] = (kv + ki * period_s) * e_v_z, (kv + ki * period_s) * e_v_c + np.array([0.0, 0.0, feedforward])
    f[u, xi] += ki
    outputs = {name: (np.concatenate([c, [0.0, d[3]]]), d[:3].copy()) for name, (c, d) in rows.items()}
    # the load's velocity and acceleration within the held sample: (c A) x + (c b) u and (c A^2) x + (c A b) u
    c_load, b_u = rows["load_position"][0], b[:, 3]
    for name, row, held in (
        ("load_velocity", c_load @ a, c_load @ b_u),
        ("load_acceleration", c_load @ a @ a, c_load @ a @ b_u),
    ):
        outputs[name] = (np.concatenate([row, [0.0, float(held)]]), np.zeros(3))
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(g))):
        raise InvalidParameter("drive", "not finite", "the sampled loop's matrices are not finite")
    mu, vectors = np.linalg.eig(f)
    try:
        inverse = np.linalg.inv(vectors)
    except np.linalg.LinAlgError:
        raise InvalidParameter("drive", "repeated poles", REPEATED) from None
    rebuilt = (vectors * mu) @ inverse
    if not np.all(np.abs(rebuilt - f) <= EIGEN_RTOL * max(float(np.max(np.abs(f))), 1.0)):
        raise InvalidParameter("drive", "repeated poles", REPEATED)
    loop = SampledLoop(period_s, f, g, outputs, mu.astype(complex), vectors.astype(complex), inverse.astype(complex))
    _check_stable(loop, drive)
    return loop


def _check_nyquist(a: Array, period_s: float) -> None:
    """Refuse a machine with a mode at or above the Nyquist frequency 1 / (2 T_s): its samples alias it to a lower
    frequency, and no description at the samples says what the load does."""
    fastest = float(np.max(np.abs(np.linalg.eigvals(a).imag), initial=0.0))
    nyquist = math.pi / period_s
    if fastest >= nyquist:
        raise InvalidParameter(
            "drive.sample_period_s",
            period_s,
            f"the machine rings at {fastest / (2 * math.pi):.4g} Hz, at or above the sampling's Nyquist frequency "
            f"{nyquist / (2 * math.pi):.4g} Hz: its samples would alias it; give a shorter sample period",
        )


def _check_stable(loop: SampledLoop, drive: Drive) -> None:
    """As models.servo's check, on the equivalent poles: every |mu| < 1 (an undamped load's mode, on |mu| = 1
    to round-off, as on an ideal motor)."""
    if not unstable(loop.poles):
        return
    gains = (
        f"position kp {drive.position_kp_per_s:g} 1/s, velocity kp {drive.velocity.kp:g} ki {drive.velocity.ki:g}, "
        f"sampled every {loop.period_s:g} s"
    )
    worst = sorted(loop.mu, key=lambda m: -abs(m))[:4]
    listed = ", ".join(f"{m.real:.4g}{m.imag:+.4g}j (|z| {abs(m):.4g})" for m in worst)
    raise InvalidParameter(
        "drive",
        gains,
        f"the sampled closed loop with these gains is unstable: its largest poles are z = {listed} (every |z| "
        "must be below 1): lower the gains or the sample period",
    )


def _pole_taylor(loop: SampledLoop, count: int) -> CArray:
    """gamma_jm (module docstring): shape (poles, 3 inputs, count) before the inputs are combined."""
    mu, period = loop.mu, loop.period_s
    # 1 / (e^x - mu) = sum_n b_n x^n with e^x - mu = (1 - mu) + sum_(i>=1) x^i / i!  (series division)
    series = np.zeros((mu.size, count), dtype=complex)
    series[:, 0] = 1.0 / (1.0 - mu)
    for n in range(1, count):  # a loop over orders
        acc = np.zeros(mu.size, dtype=complex)
        for i in range(1, n + 1):
            acc += series[:, n - i] / math.factorial(i)
        series[:, n] = -acc / (1.0 - mu)
    series *= period ** np.arange(count)[None, :]  # in powers of s
    weights = loop.modal_input  # (poles, 3): the input of r, r', r''
    taylor = np.zeros((mu.size, count), dtype=complex)
    for order in range(3):  # s^order multiplies the input of the command's order-th derivative
        taylor[:, order:] += weights[:, order : order + 1] * series[:, : count - order]
    return taylor


@dataclass(frozen=True)
class SampledRun:
    """Every output at the samples t_k (module docstring), the load's Response and the modal data behind it."""

    time_s: Array
    values: dict[str, Array]
    load: Response


def sample_count(command: PiecewiseCommand, period_s: float) -> int:
    """Samples from the command's start to the first sample at or after its last breakpoint."""
    span = float(command.time_s[-1] - command.time_s[0])
    return math.ceil(span / period_s - 1e-9) + 1


def simulate_sampled(
    mechanics: Plant, drive: Drive, command: PiecewiseCommand, load_plant: Callable[[float], Plant]
) -> SampledRun:
    """``command`` through the sampled loop (module docstring); ``load_plant(g0)``: the load Response's plant of
    static gain g0 (the load's transfer function is the loop's, which has none in s)."""
    loop = sampled_loop(mechanics, drive)
    period_s = loop.period_s
    count = command.degree + 1
    grid: Array = float(command.time_s[0]) + period_s * np.arange(sample_count(command, period_s), dtype=np.float64)
    at = command.evaluate_at_instants(grid, orders=max(count, 3))  # p^(m)(t_k+), m = 0 .. max(degree, 2)
    inputs = at[:3]
    taylor = _pole_taylor(loop, count)
    before = np.array([command.before(m) for m in range(count)])
    drive_q = np.empty((loop.mu.size, grid.size), dtype=complex)
    drive_q[:, 0] = taylor @ before  # at rest in the motion before the command: h = 0 at t_0-
    drive_q[:, 1:] = loop.modal_input @ inputs[:, :-1]
    q = np.empty_like(drive_q)
    for j, mu in enumerate(loop.mu):  # a loop over poles
        q[j] = lfilter([1.0], [1.0, -mu], drive_q[j])
    free = q - taylor @ at[:count]
    values = {}
    for name, (c_z, c_c) in loop.outputs.items():  # a loop over outputs
        values[name] = np.real((c_z @ loop.vectors) @ q) + c_c @ inputs
    load = _load_response(loop, command, grid, at[:count], taylor, free, values, load_plant)
    return SampledRun(grid, values, load)


def _load_response(
    loop: SampledLoop,
    command: PiecewiseCommand,
    grid: Array,
    derivatives: Array,
    taylor: CArray,
    free: CArray,
    values: dict[str, Array],
    load_plant: Callable[[float], Plant],
) -> Response:
    """The load's samples as a models.simulation.Response (module docstring): the equivalent poles, residues
    r_j = c v_j, the free responses h_j, g_m = d_m + sum_j r_j gamma_jm."""
    c_z, c_c = loop.outputs["load_position"]
    residues = c_z @ loop.vectors
    g = np.real(residues @ taylor)
    g[: min(3, g.size)] += c_c[: min(3, g.size)]
    flat = loop.flat
    keep = flat | (loop.mu.imag > 0.0)  # one pole of each conjugate pair, and every real one
    modal = ModalForm(
        g,
        loop.poles[keep],
        np.where(flat, residues.real + 0j, residues)[keep],
        np.where(flat[keep], 1.0, 2.0),
        taylor[keep],
    )
    sampled = PiecewiseCommand(grid, derivatives, 0, command.motion_before)
    return Response(
        load_plant(float(g[0])),
        sampled,
        modal,
        values["load_position"],
        values["load_velocity"],
        values["load_acceleration"],
        tuple(FreeResponse(values=h) for h in free[keep]),
    )
