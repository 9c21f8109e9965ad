"""A refined command's switching times made exactly stationary: Newton on the refinement's KKT conditions.

SLSQP stops when the duration no longer falls by its tolerance (optim.families.time_optimal.refine), but where the
structure has more durations than its end conditions and active bounds fix, the duration is flat in the free ones
at the optimum: its switching times are then exact only to about the square root of that tolerance (1e-5 of a
period on bench/programs.py's cruising moves), and the certificate's signs, checked to 1e-6 of sigma, fail next to
a switch a few times 1e-6 off (optim.families.time_optimal.certify). Newton on the conditions of a minimum of the
duration on the active set,

    1 - J(z)^T lambda = 0 (the duration's gradient in z = d / T0 is all ones),   g(z) = 0,

with the Hessian of the Lagrangian by central differences of J^T lambda (exact to about h^2: Newton still converges
to the exact root, only a little slower), brings them to round-off. The caller keeps the result only if its limits
check exactly and the certificate proves it (a proof of the global minimum: it is then never longer).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from optim.families.time_optimal.refine import _arcs, _Model
from optim.families.time_optimal.shaped import as_start
from optim.families.time_optimal.types import Arc, Spec

Array = NDArray[np.float64]
ON_BOUND = 1e-6  # a scaled inequality this close to its bound is held (SLSQP's points are within about this)
ITERATIONS = 8
STEP = 1e-7  # of z: the central differences' step for the Hessian
STATIONARY = 1e-12  # the scaled KKT residual of a stationary command


def stationary(spec: Spec, arcs: tuple[Arc, ...]) -> tuple[Arc, ...] | None:
    """``arcs`` (every level fixed) with durations at a stationary point of their total on the equalities and the
    bounds they ride, by Newton (see the module); None where a level is free, Newton does not converge, a duration
    turns negative, a bound breaks or a held bound's multiplier has the wrong sign (it should not be held)."""
    durations, levels, free = as_start(spec, arcs)
    if any(free) or len(durations) < 2:
        return None
    model = _Model(spec, durations, levels, free, [])
    z = model.z0.copy()
    held = _held_rows(model, z)
    n = z.size

    def system(at: Array) -> tuple[Array, Array]:
        eq, eq_jac = model._parts(at, "eq")
        ineq, ineq_jac = model._parts(at, "ineq")
        return np.concatenate([eq, ineq[held]]), np.vstack([eq_jac, ineq_jac[held]])

    g, jac = system(z)
    ones = np.ones(n)
    lam = np.linalg.lstsq(jac.T, ones, rcond=None)[0]
    for _ in range(ITERATIONS):
        residual = np.concatenate([ones - jac.T @ lam, g])
        if float(np.max(np.abs(residual))) < STATIONARY:
            break
        hessian = np.empty((n, n))
        for j in range(n):
            step = np.zeros(n)
            step[j] = STEP
            hessian[:, j] = -(system(z + step)[1].T @ lam - system(z - step)[1].T @ lam) / (2 * STEP)
        kkt = np.block([[hessian, -jac.T], [jac, np.zeros((jac.shape[0], jac.shape[0]))]])
        delta = np.linalg.lstsq(kkt, -residual, rcond=None)[0]
        z, lam = z + delta[:n], lam + delta[n:]
        if np.any(z < 0.0):
            return None
        g, jac = system(z)
    else:
        return None
    held_lam = lam[g.size - int(np.sum(held)) :]
    if np.any(held_lam < -STATIONARY) or np.any(model._parts(z, "ineq")[0] < -STATIONARY):
        return None
    return _arcs(spec, model, z)


def _held_rows(model: _Model, z: Array) -> NDArray[np.bool_]:
    """The inequalities within ON_BOUND of their bound at ``z``, less exact duplicates (a velocity peak row clamped
    to an arc's end is that end's row: two equal rows would make the KKT matrix singular)."""
    values, jac = model._parts(z, "ineq")
    held = np.abs(values) < ON_BOUND
    seen: list[Array] = []
    for k in np.flatnonzero(held):
        row = jac[k]
        if any(np.allclose(row, other, rtol=1e-12, atol=1e-12 * float(np.max(np.abs(row)))) for other in seen):
            held[k] = False
        else:
            seen.append(row)
    return held
