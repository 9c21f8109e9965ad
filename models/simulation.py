"""Exact, vectorised response of a plant to a piecewise-polynomial motor command.

Method. Write the load transfer function (motor position -> load position) in partial fractions,
G(s) = D + sum_j r_j / (s - lambda_j), so that y = D p + sum_j r_j x_j with x_j' = lambda_j x_j + p.
While the command p is a polynomial, x_j has the particular solution
x_j,p = -sum_m p^(m) / lambda_j^(m+1), and the load follows the quasi-static motion
y_p = sum_m g_m p^(m), where g_m are the Taylor coefficients of G at s = 0. What is left,
h_j = x_j - x_j,p, is a free response: it decays as exp(lambda_j t) and jumps by
sum_m [p^(m)] / lambda_j^(m+1) wherever a derivative of the command jumps. So

    y(t_k) = sum_m g_m p^(m)(t_k) + Re sum_j w_j r_j h_j(t_k),
    h_j(t_k) = exp(lambda_j (t_k - t_{k-1})) h_j(t_{k-1}) + jump_j(t_k),

which is exact for piecewise-polynomial commands and needs only one first-order recurrence per
pole: ``scipy.signal.lfilter`` on a uniform grid, a log-depth associative scan otherwise (no
Python loop over samples). At the end of the command, h_j is the state of the load's free
oscillation, from which the residual envelope, energy and settling time follow in closed form.

On a uniform grid where a single derivative order jumps after t_0 (every first- or zero-order hold of
samples), the drive of a complex pole is a J_k with one complex a = lambda^-(m+1) and real J, so
h = a (1 - conj(z) q^-1) s with s = J / ((1 - z q^-1)(1 - conj(z) q^-1)): one real second-order
``lfilter`` (2.4 times cheaper than the complex one) gives h_k = a (s_k - conj(z) s_(k-1)) and every
output as alpha s_k - beta s_(k-1). Its direct form rounds the pole's angle by about eps / Im(z) per
step (Oppenheim & Schafer, Discrete-Time Signal Processing, 3rd ed., Sec. 6.8-6.9); where the estimated
round-off over the mode's memory exceeds 1e-12 of the motion, the complex recurrence runs instead.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import lfilter, lfiltic

from models.commands import PiecewiseCommand
from models.modal_data import FreeResponse as FreeResponse  # (re-exported: the simulation's types)
from models.modal_data import ModalForm as ModalForm
from models.plants import Plant
from models.simulation_checks import (
    PAIR_ROUNDOFF_RELATIVE,
    check_conditioning,
    check_finite,
    pair_roundoff,
    quasi_static_size,
)

_REAL_POLE_TOLERANCE = 1e-12


def taylor_coefficients(num: ArrayLike, den: ArrayLike, count: int) -> NDArray[np.float64]:
    """First ``count`` Taylor coefficients of num(s)/den(s) at s = 0 (series division)."""
    n_asc = np.zeros(count)
    tail = np.asarray(num, dtype=float)[::-1][:count]
    n_asc[: tail.size] = tail
    d_asc = np.asarray(den, dtype=float)[::-1]
    g = np.zeros(count)
    for m in range(count):  # a loop over series terms (a handful), not samples
        acc = n_asc[m]
        for i in range(1, min(m, d_asc.size - 1) + 1):
            acc -= d_asc[i] * g[m - i]
        g[m] = acc / d_asc[0]
    return g


def modal_form(num: NDArray[np.float64], den: NDArray[np.float64], taylor_count: int) -> ModalForm:
    """Partial fractions of a proper transfer function with simple poles off the origin."""
    poles = np.roots(den).astype(complex)
    keep = poles.imag >= -_REAL_POLE_TOLERANCE * np.abs(poles)
    poles = poles[keep]
    real = np.abs(poles.imag) <= _REAL_POLE_TOLERANCE * np.abs(poles)
    poles = np.where(real, poles.real + 0j, poles)
    # A pole on the imaginary axis may come out with a round-off real part of either sign.
    poles = np.where(poles.real > 0.0, 1j * poles.imag, poles)
    # numpy's stubs type polyval at complex points as real: the annotations say what they are.
    at_num: NDArray[np.complex128] = np.polyval(num, poles)
    at_derivative: NDArray[np.complex128] = np.polyval(np.polyder(den), poles)
    residues = at_num / at_derivative
    residues = np.where(real, residues.real + 0j, residues)
    weights = np.where(real, 1.0, 2.0)
    return ModalForm(taylor_coefficients(num, den, taylor_count), poles, residues, weights)


def first_order_scan(
    decay: NDArray[np.complex128], drive: NDArray[np.complex128], uniform: bool
) -> NDArray[np.complex128]:
    """h_0 = drive_0, h_k = decay_{k-1} h_{k-1} + drive_k, vectorised.

    ``decay`` has one entry per step (len(drive) - 1). On a uniform grid this is one
    ``lfilter`` call; otherwise a Hillis-Steele scan with log2(N) vectorised passes. Every
    |decay| <= 1, so the scan's products only shrink and cannot overflow.
    """
    if uniform:
        filtered: NDArray[np.complex128] = lfilter([1.0], [1.0, -decay[0]], drive)
        return filtered
    a = np.concatenate(([0.0 + 0j], decay))
    h = drive.astype(complex, copy=True)
    shift = 1
    while shift < h.size:
        h[shift:] = h[shift:] + a[shift:] * h[:-shift]
        a[shift:] = a[shift:] * a[:-shift]
        shift *= 2
    return h


def _real_pair_history(q: complex, decay: complex) -> tuple[float, float]:
    """Real (s_{-1}, s_{-2}) with s_{-1} - conj(decay) s_{-2} = q (needs Im decay != 0)."""
    before2 = q.imag / decay.imag
    return q.real + decay.real * before2, before2


@dataclass(frozen=True)
class Response:
    """The load's motion at the command's breakpoints (right-hand values) and its free state."""

    plant: Plant
    command: PiecewiseCommand
    modal: ModalForm
    load_position: NDArray[np.float64]
    load_velocity: NDArray[np.float64]
    load_acceleration: NDArray[np.float64]
    free: tuple[FreeResponse, ...]  # one per pole of ``modal``

    @property
    def time_s(self) -> NDArray[np.float64]:
        return self.command.time_s

    @cached_property
    def free_state(self) -> NDArray[np.complex128]:
        """h_j at every breakpoint, shape (poles, samples) (built on first use)."""
        state = np.zeros((len(self.free), self.time_s.size), dtype=complex)
        for j, pole_free in enumerate(self.free):  # a loop over poles
            state[j] = pole_free.full()
        return state

    def free_state_at(self, index: int) -> NDArray[np.complex128]:
        """h_j at one breakpoint."""
        return np.array([f.at(index) for f in self.free], dtype=complex)

    @property
    def has_deflection(self) -> bool:
        return self.plant.command_input == "position"

    @property
    def deflection(self) -> NDArray[np.float64] | None:
        """Load position minus its rigid-transmission value G(0) p (Incerti's alpha)."""
        if not self.has_deflection:
            return None
        return self.load_position - self.plant.dc_gain * self.command.derivative(0)

    @property
    def deflection_rate(self) -> NDArray[np.float64] | None:
        if not self.has_deflection:
            return None
        return self.load_velocity - self.plant.dc_gain * self.command.derivative(1)

    @property
    def motor_torque_nm(self) -> NDArray[np.float64] | None:
        """J_M th_M'' + J_L th_L'' where the plant defines both inertias."""
        inertias = self.plant.torque_inertias()
        if inertias is None:
            return None
        j_m, j_l = inertias
        return j_m * self.command.derivative(2) + j_l * self.load_acceleration

    def free_amplitudes(self, index: int, derivative: int = 0) -> NDArray[np.float64]:
        """|w_j r_j lambda_j^d h_j|: amplitude of each pole's free response at a breakpoint."""
        m = self.modal
        amplitudes: NDArray[np.float64] = np.abs(
            m.weights * m.residues * m.poles**derivative * self.free_state_at(index)
        )
        return amplitudes


def _single_order_free(
    pole: complex, decay: complex, jumps: NDArray[np.float64], order: int, start: complex
) -> FreeResponse:
    """h_k = z h_{k-1} + a J_k (k >= 1), h_0 = start + a J_0 with a = pole^-(order + 1): one real
    ``lfilter`` (first order for a real pole, second order for a complex one)."""
    gain = complex(pole ** -(order + 1))
    if decay.imag == 0.0:
        zi = np.array([start.real / gain.real])  # y_0 = J_0 + zi_0
        s: NDArray[np.float64] = lfilter([1.0], [1.0, -decay.real], jumps, zi=zi)[0]
        return FreeResponse(s=s, s_before=0.0, gain=gain, decay=0.0 + 0.0j)
    a = np.array([1.0, -2.0 * decay.real, abs(decay) ** 2])
    # A virtual h_{-1} = start / (z a) before the first sample makes z h_{-1} the part of d_0 not in J_0.
    before1, before2 = _real_pair_history(start / (decay * gain), decay)
    zi = lfiltic([1.0], a, [before1, before2])
    s = lfilter([1.0], a, jumps, zi=zi)[0]
    return FreeResponse(s=s, s_before=before1, gain=gain, decay=decay)


def simulate(plant: Plant, command: PiecewiseCommand, modal: ModalForm | None = None) -> Response:
    """The exact response of ``plant`` to ``command`` (see the module docstring); ``modal``: its transfer function
    in partial fractions where the caller has it more precisely than from polynomial coefficients (the closed loop
    of models.servo, from its eigenvectors), with at least ``command.degree + 1`` Taylor coefficients."""
    degree = command.degree
    modal = plant_modal_form(plant, degree + 1) if modal is None else modal
    jumps = command.jumps()
    uniform = command.is_uniform
    first = jumps[:, 0]
    # Orders that may jump after t_0: their jumps drive the recurrence at every sample.
    # One such order is taken as active without looking (all-zero jumps give the same, exact, answer).
    may_jump = range(command.continuous_orders, degree + 1)
    active = list(may_jump) if len(may_jump) == 1 else [m for m in may_jump if np.any(jumps[m, 1:])]
    weighted = modal.weights * modal.residues
    samples = command.time_s.size
    step = float(command.steps_s[0]) if uniform else 0.0
    static_size = quasi_static_size(command, modal)
    free: list[FreeResponse] = []
    for pole, w in zip(modal.poles, weighted, strict=True):  # a loop over poles, not samples
        p = complex(pole)
        start = complex(sum(first[m] * p ** -(m + 1) for m in range(degree + 1) if first[m] != 0.0))
        if not active and start == 0.0:
            free.append(FreeResponse(values=np.zeros(samples, dtype=complex)))
            continue
        pole_free = None
        if uniform and len(active) == 1:
            m = active[0]
            decay = complex(np.exp(p * step))
            rest = start - first[m] * p ** -(m + 1)  # d_0 without the active order, carried by zi
            pole_free = _single_order_free(p, decay, jumps[m], m, rest)
            if decay.imag != 0.0 and pair_roundoff(pole_free, w, samples) > (PAIR_ROUNDOFF_RELATIVE * static_size):
                pole_free = None  # the real form would lose accuracy: the complex recurrence instead
        free.append(pole_free or _complex_free(p, command, jumps, active, start, uniform))
    position, velocity, acceleration = _load_motion(command, modal, free)
    response = Response(plant, command, modal, position, velocity, acceleration, tuple(free))
    check_finite(command, modal, response.free, (position, velocity, acceleration))
    check_conditioning(command, modal, response.free, position, static_size)
    return response


def another_output(response: Response, modal: ModalForm) -> Response:
    """Another output of the system ``response`` simulated, written with the same poles in the same order (other
    residues and Taylor coefficients: models.servo's closed loop, one per signal): the free responses h_j depend
    on the pole and the command only, so they are reused. Where the real second-order form of a pole would lose
    accuracy for this output (``_pair_roundoff`` against its own size), it is simulated afresh."""
    if not np.array_equal(modal.poles, response.modal.poles):
        raise ValueError("another_output needs the same poles in the same order")
    command = response.command
    static_size = quasi_static_size(command, modal)
    weighted = modal.weights * modal.residues
    samples = command.time_s.size
    for w, pole_free in zip(weighted, response.free, strict=True):  # a loop over poles
        if (
            pole_free.s is not None
            and pole_free.decay.imag != 0.0
            and pair_roundoff(pole_free, complex(w), samples) > (PAIR_ROUNDOFF_RELATIVE * static_size)
        ):
            return simulate(response.plant, command, modal)
    position, velocity, acceleration = _load_motion(command, modal, list(response.free))
    other = Response(response.plant, command, modal, position, velocity, acceleration, response.free)
    check_finite(command, modal, other.free, (position, velocity, acceleration))
    check_conditioning(command, modal, other.free, position, static_size)
    return other


def _load_motion(
    command: PiecewiseCommand, modal: ModalForm, free: list[FreeResponse]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Load position, velocity and acceleration: sum_m g_m p^(m+k) + Re sum_j w_j r_j p_j^k h_j (k = 0, 1, 2).

    Sums in place through one scratch row (no temporaries of the samples' size; no matrix product, which
    BLAS would spread over threads). A pole held as a real sequence s adds alpha s_k - beta s_(k-1)."""
    degree = command.degree
    g = modal.taylor
    der = command.derivatives
    samples = der.shape[1]
    scratch = np.empty(samples)
    # Quasi-static motion sum_m g_m p^(m+k); None where it is zero (the first pole then writes the row).
    outputs = [_weighted_rows(g[: max(degree + 1 - k, 0)], der[k:], scratch) for k in range(3)]
    weighted = modal.weights * modal.residues
    for j, f in enumerate(free):  # a loop over poles
        for k in range(3):
            c = complex(weighted[j] * modal.poles[j] ** k)
            if f.s is None:
                assert f.values is not None
                part = c.real * f.values.real - c.imag * f.values.imag  # Re(c h), no complex product
                previous = outputs[k]
                outputs[k] = part if previous is None else previous + part
                continue
            alpha, beta = f.combination(c)
            out = outputs[k]
            if out is None:
                out = outputs[k] = np.multiply(f.s, alpha)
            else:
                np.multiply(f.s, alpha, out=scratch)
                out += scratch
            if beta != 0.0:
                np.multiply(f.s[:-1], beta, out=scratch[1:])
                out[1:] -= scratch[1:]
                out[0] -= beta * f.s_before
    position, velocity, acceleration = (np.zeros(samples) if out is None else out for out in outputs)
    return position, velocity, acceleration


def _weighted_rows(
    coefficients: NDArray[np.float64], rows: NDArray[np.float64], scratch: NDArray[np.float64]
) -> NDArray[np.float64] | None:
    """sum_i coefficients[i] rows[i] as a new array (None when every coefficient is zero), by in-place
    multiply-adds that skip zero coefficients (a vector-matrix product of few rows is slower)."""
    out: NDArray[np.float64] | None = None
    for c, row in zip(coefficients, rows, strict=True):  # a loop over derivative orders
        if c == 0.0:
            continue
        if out is None:
            out = row * c
        else:
            np.multiply(row, c, out=scratch)
            out += scratch
    return out


def plant_modal_form(plant: Plant, taylor_count: int) -> ModalForm:
    """``modal_form`` of the plant's load transfer function, computed once per plant and count."""
    cache: dict[int, ModalForm] = plant.modal_forms
    if taylor_count not in cache:
        num, den = plant.load_transfer_function()
        modal = modal_form(num, den, taylor_count)
        for array in (modal.taylor, modal.poles, modal.residues, modal.weights):
            array.setflags(write=False)  # shared by every simulation of this plant
        cache[taylor_count] = modal
    return cache[taylor_count]


def _complex_free(
    pole: complex,
    command: PiecewiseCommand,
    jumps: NDArray[np.float64],
    active: list[int],
    start: complex,
    uniform: bool,
) -> FreeResponse:
    """h_k = z_k h_{k-1} + sum_m J_m[k] / pole^(m+1): the complex first-order recurrence."""
    drive = np.zeros(command.time_s.size, dtype=complex)
    for m in active:  # a loop over derivative orders
        drive[1:] += jumps[m, 1:] * pole ** -(m + 1)
    drive[0] = start
    steps = command.steps_s
    decay = np.exp(pole * (steps[:1] if uniform else steps))
    return FreeResponse(values=first_order_scan(decay, drive, uniform))
