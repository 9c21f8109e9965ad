"""A base-excited mode's response to a piecewise-constant input whose switches fall anywhere between samples, exact at
the samples.

The mode: y'' + 2 zeta w y' + w^2 y = u, output a = w^2 y + 2 zeta w y' (the toolhead's acceleration for a commanded
acceleration u through a spring and damper; unit gain at rest). With x = (y, y'), x' = A x + B u and a sample period
T, the state at the samples obeys x[k+1] = Phi x[k] + v[k] (Phi = e^(AT)), where the interval (kT, (k+1)T] held at u
from its start and switching by d_j at tau_j adds

    v[k] = Gamma(T) u(kT) + sum_j d_j Gamma((k+1)T - tau_j),   Gamma(h) = int_0^h e^(Ar) B dr = A^-1 (e^(Ah) - I) B,

in closed form for 0 <= zeta < 1 (e^(Ah) = e^(-s h) (cos(w_d h) I + sin(w_d h) / w_d (A + s I)), s = zeta w). A
zero-order hold of the sampled input is the case of switches on the samples only.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.signal import lfilter

from models.errors import InvalidParameter

__all__ = ["base_excited_response", "step_state"]

Array = NDArray[np.float64]


def step_state(f_hz: float, zeta: float, h_s: Array) -> Array:
    """Gamma(h) (2, len(h)): the state (y, y') h after a unit step of u from rest (see the module)."""
    w = 2.0 * math.pi * f_hz
    s = zeta * w
    wd = w * math.sqrt(1.0 - zeta * zeta)
    decay = np.exp(-s * h_s)
    sin, cos = np.sin(wd * h_s), np.cos(wd * h_s)
    velocity = decay * sin / wd
    position = (1.0 - decay * (cos + s * sin / wd)) / (w * w)
    state: Array = np.vstack([position, velocity])
    return state


def base_excited_response(
    f_hz: float, zeta: float, rate_hz: float, switch_times_s: Array, levels: Array, samples: int
) -> Array:
    """a(k / rate_hz), k < samples, from rest, for u = levels[j] from switch_times_s[j] (increasing, the first 0) to
    the next switch (see the module)."""
    if not 0.0 <= zeta < 1.0:
        raise InvalidParameter("damping_ratio", zeta, "the held-input response is for 0 <= zeta < 1")
    period = 1.0 / rate_hz
    w = 2.0 * math.pi * f_hz
    grid = np.arange(samples) * period
    start = levels[np.searchsorted(switch_times_s, grid, side="right") - 1]
    drive = step_state(f_hz, zeta, np.array([period])) * start  # Gamma(T) u(kT), (2, samples)
    inside = switch_times_s[1:]
    interval = np.ceil(inside / period - 1e-12).astype(np.intp) - 1  # tau in (kT, (k+1)T]
    keep = (interval >= 0) & (interval < samples)
    jumps = np.diff(levels)[keep]
    offsets = (interval[keep] + 1) * period - inside[keep]
    corrections = step_state(f_hz, zeta, offsets) * jumps
    np.add.at(drive[0], interval[keep], corrections[0])
    np.add.at(drive[1], interval[keep], corrections[1])
    phi = _transition(f_hz, zeta, period)
    c = np.array([w * w, 2.0 * zeta * w])
    adj = np.array([[-phi[1, 1], phi[0, 1]], [phi[1, 0], -phi[0, 0]]])  # adj(-Phi)
    den = np.array([1.0, -np.trace(phi), float(np.linalg.det(phi))])
    out = np.zeros(samples)
    for j in range(2):  # y = C (zI - Phi)^-1 v = sum_j (C_j z + (C adj(-Phi))_j) / det(zI - Phi) v_j
        out += lfilter([0.0, c[j], float((c @ adj)[j])], den, drive[j])
    return out


def _transition(f_hz: float, zeta: float, h_s: float) -> Array:
    """Phi = e^(A h) in closed form."""
    w = 2.0 * math.pi * f_hz
    s = zeta * w
    wd = w * math.sqrt(1.0 - zeta * zeta)
    a = np.array([[0.0, 1.0], [-w * w, -2.0 * s]])
    phi: Array = math.exp(-s * h_s) * (math.cos(wd * h_s) * np.eye(2) + math.sin(wd * h_s) / wd * (a + s * np.eye(2)))
    return phi
