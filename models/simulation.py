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

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import lfilter, lfiltic

from models.commands import PiecewiseCommand
from models.errors import InvalidParameter
from models.plants import Plant

_REAL_POLE_TOLERANCE = 1e-12
_RELIABLE_RELATIVE = 1e-6  # largest round-off accepted, relative to the load's motion


@dataclass(frozen=True)
class ModalForm:
    """G(s) = sum_m taylor[m] s^m near 0, and sum over poles of weights * residues / (s - pole).

    One entry per real pole or per complex pair (the pole with Im > 0, weight 2).
    """

    taylor: NDArray[np.float64]
    poles: NDArray[np.complex128]
    residues: NDArray[np.complex128]
    weights: NDArray[np.float64]

    @property
    def oscillatory(self) -> NDArray[np.bool_]:
        pairs: NDArray[np.bool_] = self.weights == 2.0
        return pairs


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
class FreeResponse:
    """h_k of one pole at every breakpoint, stored as what computed it.

    Either ``values`` (h itself) or, for a complex pole on a uniform grid driven by one order of jumps,
    the real sequence s of the second-order recurrence s_k = 2 Re(z) s_{k-1} - |z|^2 s_{k-2} + u_k
    (``scipy.signal.lfilter`` on real numbers), from which h_k = gain (s_k - conj(z) s_{k-1}): the
    denominator (1 - z q^-1)(1 - conj(z) q^-1) is the complex first-order recurrence times its conjugate.
    """

    values: NDArray[np.complex128] | None = None
    s: NDArray[np.float64] | None = None
    s_before: float = 0.0  # s_{-1}
    gain: complex = 0.0
    decay: complex = 0.0  # z = exp(pole h)

    def combination(self, c: complex) -> tuple[float, float]:
        """(alpha, beta) with Re(c h_k) = alpha s_k - beta s_{k-1} (the s representation only)."""
        ca = c * self.gain
        return ca.real, (ca * self.decay.conjugate()).real

    def at(self, index: int) -> complex:
        if self.values is not None:
            return complex(self.values[index])
        assert self.s is not None
        previous = float(self.s[index - 1]) if index > 0 else self.s_before
        return self.gain * (float(self.s[index]) - self.decay.conjugate() * previous)

    def full(self) -> NDArray[np.complex128]:
        if self.values is not None:
            return self.values
        assert self.s is not None
        shifted = np.empty_like(self.s)
        shifted[0] = self.s_before
        shifted[1:] = self.s[:-1]
        h: NDArray[np.complex128] = self.gain * (self.s - self.decay.conjugate() * shifted)
        return h

    @cached_property
    def bound(self) -> float:
        """An upper bound of max_k |h_k|; for the s representation also the scale of its round-off."""
        if self.values is not None:
            return float(np.max(np.abs(self.values))) if self.values.size else 0.0
        assert self.s is not None
        largest = max(float(self.s.max()), -float(self.s.min()), abs(self.s_before))
        return abs(self.gain) * (1.0 + abs(self.decay)) * largest


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


# Largest round-off the real second-order form may add to a pole's free response, relative to the load's
# motion, before the complex first-order recurrence is used instead (see ``_pair_roundoff``).
_PAIR_ROUNDOFF_RELATIVE = 1e-12


def _pair_roundoff(free: FreeResponse, weighted: complex, samples: int) -> float:
    """Estimated round-off of the real second-order form in |w r h| (Oppenheim & Schafer, Discrete-Time
    Signal Processing, 3rd ed., Sec. 6.8-6.9: coefficient quantisation and round-off noise of direct forms).
    Rounding 2 Re(z) moves the pole's angle by eps / Im(z) per step, which the free response (of size
    about |a| max|s| |1 - z|) accumulates over its memory (the samples, or 1 / (1 - |z|) steps of decay);
    each step's rounding, eps |s|, adds a free response of |a| eps |s|, summed at random over the memory."""
    eps = float(np.finfo(float).eps)
    memory = min(float(samples), 1.0 / max(1.0 - abs(free.decay), eps))
    angle = abs(1.0 - free.decay) * memory / abs(free.decay.imag)
    return abs(weighted) * free.bound * eps * (angle + math.sqrt(memory) + 4.0)


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


def simulate(plant: Plant, command: PiecewiseCommand) -> Response:
    """The exact response of ``plant`` to ``command`` (see the module docstring)."""
    degree = command.degree
    modal = plant_modal_form(plant, degree + 1)
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
    quasi_static_size = _quasi_static_size(command, modal)
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
            if decay.imag != 0.0 and _pair_roundoff(pole_free, w, samples) > (
                _PAIR_ROUNDOFF_RELATIVE * quasi_static_size
            ):
                pole_free = None  # the real form would lose accuracy: the complex recurrence instead
        free.append(pole_free or _complex_free(p, command, jumps, active, start, uniform))
    position, velocity, acceleration = _load_motion(command, modal, free)
    response = Response(plant, command, modal, position, velocity, acceleration, tuple(free))
    _check_finite(response)
    _check_conditioning(command, modal, response.free, position, quasi_static_size)
    return response


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


def _check_finite(response: Response) -> None:
    """Refuse a load motion that overflows double precision. A bound on every output (the quasi-static
    sizes plus each pole's |c| max|h|) below 1e300 proves them finite without looking at the samples."""
    modal, cmd = response.modal, response.command
    weighted = np.abs(modal.weights * modal.residues)
    bounds = [f.bound for f in response.free]
    for k, (name, arr) in enumerate(
        (
            ("load position", response.load_position),
            ("load velocity", response.load_velocity),
            ("load acceleration", response.load_acceleration),
        )
    ):
        size = sum(abs(float(g)) * cmd.max_abs(m + k) for m, g in enumerate(modal.taylor) if g != 0.0)
        size += sum(float(w * abs(p) ** k) * b for w, p, b in zip(weighted, modal.poles, bounds, strict=True))
        if size < 1e300:
            continue
        if not (math.isfinite(float(arr.max())) and math.isfinite(float(arr.min()))):
            raise InvalidParameter("profile", "out of range", f"the {name} overflows double precision")


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


def _quasi_static_size(command: PiecewiseCommand, modal: ModalForm) -> float:
    """sum_m |g_m| max |p^(m)|: the size of the quasi-static motion, the scale of round-off bounds."""
    return sum(abs(float(g)) * command.max_abs(m) for m, g in enumerate(modal.taylor) if g != 0.0)


def _check_conditioning(
    command: PiecewiseCommand,
    modal: ModalForm,
    free: tuple[FreeResponse, ...],
    position: NDArray[np.float64],
    quasi_static_size: float,
) -> None:
    """Refuse a result that round-off could have spoilt.

    The load position is the sum of the quasi-static part sum_m g_m p^(m) (of size ``quasi_static_size``) and
    the free responses; when a mode is very slow next to how fast the command changes, both are huge
    (1/lambda^(m+1)) and cancel, and the sum keeps only eps times their size of accuracy.
    """
    eps = np.finfo(float).eps
    size = quasi_static_size + sum(
        abs(float(w)) * f.bound for w, f in zip(np.abs(modal.weights * modal.residues), free, strict=True)
    )
    scale = max(abs(modal.taylor[0]) * command.max_abs(0), 1e-300)
    if 16 * eps * size > _RELIABLE_RELATIVE * scale:  # only then the load's own extent decides
        scale = max(scale, float(position.max()), -float(position.min()))
    if 16 * eps * size > _RELIABLE_RELATIVE * scale:
        slowest = float(np.min(np.abs(modal.poles))) / (2 * np.pi)
        raise InvalidParameter(
            "plant",
            f"{slowest:.3g} Hz",
            f"the slowest pole ({slowest:.3g} Hz) is too slow for how fast this command changes: round-off would "
            f"reach {16 * eps * size / scale:.1e} of the motion; sample a slower command or check the plant",
        )
