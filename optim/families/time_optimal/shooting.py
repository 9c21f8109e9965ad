"""Pontryagin's conditions of a bang train solved with its switching times: a square Newton where SLSQP was needed.

A rest-to-rest command whose every arc is bang (the held derivative at +-its limit) is minimum-time when a
switching function sigma(s) = phi(T - s) = k(T - s) - theta . basis(T - s) (optim.families.time_optimal.certify)
vanishes at each switch and has the arcs' signs between. With n arcs and the end conditions (the end state and
the cancelled residuals: E = w + 1 equations for theta's w unknowns), the n - 1 switches give exactly the n + w
equations of the n durations and theta together. A structure with more arcs than end conditions (a notch added by
a repair: the optimum's +-+-+-+ of a short held-jerk move, 7 arcs for 5 end conditions) is then solved by Newton
on that square system instead of SLSQP on the durations alone; the caller keeps it only if the certificate proves
it (the signs between the switches, which these equations do not hold).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from optim.families.time_optimal.certify import certificate_applies, kernel, phi_parts
from optim.families.time_optimal.refine import end_conditions
from optim.families.time_optimal.types import Arc, Spec

Array = NDArray[np.float64]
ITERATIONS = 12  # Newton steps at most: a start near the solution converges quadratically well within them
HALVINGS = 4  # a step is halved at most this often until the residual falls and no duration turns negative
CONVERGED = 1e-12  # the scaled residual of a solved system (the refinement's)


def shoot(spec: Spec, durations: list[float], levels: list[float]) -> tuple[Arc, ...] | None:
    """The bang train of ``levels`` whose durations and multipliers meet the end conditions and vanish sigma at
    every switch, by damped Newton from ``durations``; None where it does not apply (a rest; no more arcs than end
    conditions, whose durations alone are refine.newton's square system; a band, a move in motion) or does not
    converge."""
    n = len(durations)
    if not certificate_applies(spec) or any(abs(v) != 1.0 for v in levels):
        return None
    end = end_conditions(spec, durations, levels)
    d = np.asarray(durations, dtype=float)
    g_end, _ = end(d)
    width = g_end.size - 1  # theta's unknowns: one fewer than the end conditions
    if n - 1 <= width:
        return None  # a square end system already (Newton on the durations alone: refine.newton)
    scale = float(kernel(spec.order, np.array([d.sum()]))[0])  # k(T): the switching function's size
    after = np.arange(n)[None, :] >= np.arange(1, n)[:, None]  # d(T - s_k)/d d_j: the arcs from switch k on
    size = g_end.size + n - 1  # = n + width: square

    def system(d: Array, theta: Array) -> tuple[Array, Array]:
        g_end, j_end = end(d)
        tau = np.cumsum(d[::-1])[::-1][1:]  # T - s_k at the switches k = 1 .. n - 1
        k, basis = phi_parts(spec, tau)
        k_slope, basis_slope = phi_parts(spec, tau, 1)
        g = np.empty(size)
        g[: g_end.size] = g_end
        g[g_end.size :] = (k - basis @ theta) / scale
        jac = np.zeros((size, size))
        jac[: g_end.size, :n] = j_end
        jac[g_end.size :, :n] = ((k_slope - basis_slope @ theta) / scale)[:, None] * after
        jac[g_end.size :, n:] = basis / -scale
        return g, jac

    k0, basis0 = phi_parts(spec, np.cumsum(d[::-1])[::-1][1:])
    if basis0.shape[1] != width:  # (the certificate's multipliers are one fewer than the end conditions)
        return None
    columns = np.max(np.abs(basis0), axis=0) + 1e-300
    theta = np.linalg.lstsq(basis0 / columns, k0, rcond=None)[0] / columns  # the start's best multipliers
    g, jac = system(d, theta)
    for _ in range(ITERATIONS):
        residual = float(np.max(np.abs(g)))
        if residual < CONVERGED:
            break
        norms = np.max(np.abs(jac), axis=0) + 1e-300  # theta's columns are of other sizes than the durations'
        try:
            step = np.linalg.solve(jac / norms, g) / norms
        except np.linalg.LinAlgError:  # a singular system: the structure has no isolated solution here
            return None
        for _ in range(HALVINGS):
            trial_d, trial_theta = d - step[:n], theta - step[n:]
            if np.all(trial_d > 0.0):
                trial_g, trial_jac = system(trial_d, trial_theta)
                if float(np.max(np.abs(trial_g))) < residual:
                    break
            step = 0.5 * step
        else:
            return None
        d, theta, g, jac = trial_d, trial_theta, trial_g, trial_jac
    if float(np.max(np.abs(g))) >= CONVERGED:
        return None
    starts = np.concatenate(([0.0], np.cumsum(d)[:-1]))
    rows = zip(starts.tolist(), d.tolist(), (np.asarray(levels) * spec.scale).tolist(), strict=True)
    return tuple(Arc(s, length, level) for s, length, level in rows)
