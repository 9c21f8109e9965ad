"""Damped sinusoids fitted by variable projection (Golub and Pereyra 1973), their covariance and (f_n, zeta)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

__all__ = ["MAX_EVALUATIONS_PER_PARAMETER", "damped_basis", "fit_covariance", "fit_damped_sinusoids", "mode_statistics"]

# the fit's evaluations (each with its Jacobian) per nonlinear parameter: knock records converge in at most 12.3
# (bench/identify_coverage.py's first 60, 396 fits; median 2.5); a fit of a forced motion as modes drifted on for 100
# (16 s on 8192 samples)
MAX_EVALUATIONS_PER_PARAMETER = 25


def damped_basis(t: NDArray[np.float64], params: NDArray[np.float64]) -> NDArray[np.float64]:
    """Columns e^(-s_k t) cos w_k t, e^(-s_k t) sin w_k t for each mode, then 1."""
    s, w = params[0::2], params[1::2]
    env = np.exp(np.clip(-np.outer(t, s), -700.0, 700.0))
    phase = np.outer(t, w)
    columns = np.empty((t.size, 2 * s.size + 1))
    columns[:, 0:-1:2] = env * np.cos(phase)
    columns[:, 1:-1:2] = env * np.sin(phase)
    columns[:, -1] = 1.0
    return columns


def _projected_jacobian(
    t: NDArray[np.float64], basis: NDArray[np.float64], coef: NDArray[np.float64], params: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(samples, signals, parameters): d model / d (s_k, w_k) with the linear coefficients held, projected
    orthogonally to the basis (Kaufman's variable-projection Jacobian; exact for the covariance)."""
    q, _ = np.linalg.qr(basis)
    cos_k, sin_k = basis[:, 0:-1:2], basis[:, 1:-1:2]  # (n, modes)
    a, b = coef[0:-1:2, :], coef[1:-1:2, :]  # (modes, signals)
    tt = t[:, None, None]
    jac = np.empty((t.size, coef.shape[1], params.size))
    jac[:, :, 0::2] = -tt * (cos_k[:, None, :] * a.T[None] + sin_k[:, None, :] * b.T[None])
    jac[:, :, 1::2] = tt * (-sin_k[:, None, :] * a.T[None] + cos_k[:, None, :] * b.T[None])
    flat = jac.reshape(t.size, -1)
    flat -= q @ (q.T @ flat)
    return flat.reshape(jac.shape)


def _projected_fit(
    t: NDArray[np.float64],
    y: NDArray[np.float64],
    x0: NDArray[np.float64],
    lower: NDArray[np.float64],
    upper: NDArray[np.float64],
) -> NDArray[np.float64]:
    """least_squares over the nonlinear parameters (s_k, w_k), the linear coefficients solved exactly."""

    def solve(params: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        basis = damped_basis(t, params)
        coef = np.asarray(np.linalg.lstsq(basis, y.T, rcond=None)[0], dtype=np.float64)
        return basis, coef

    def residual(params: NDArray[np.float64]) -> NDArray[np.float64]:
        basis, coef = solve(params)
        misfit: NDArray[np.float64] = (basis @ coef - y.T).ravel()
        return misfit

    def jacobian(params: NDArray[np.float64]) -> NDArray[np.float64]:
        basis, coef = solve(params)
        return _projected_jacobian(t, basis, coef, params).reshape(-1, params.size)

    fit = least_squares(
        residual,
        x0=np.clip(x0, lower, upper),
        jac=jacobian,
        bounds=(lower, upper),
        x_scale=np.abs(x0) + 1e-3 * np.max(np.abs(x0)),
        method="trf",
        xtol=1e-12,
        ftol=1e-12,
        gtol=1e-12,
        max_nfev=MAX_EVALUATIONS_PER_PARAMETER * x0.size,
    )
    if fit.status == 0:  # (the evaluations ran out: no optimum, so no interval either)
        raise FloatingPointError(f"no convergence in {fit.nfev} evaluations")
    return np.asarray(fit.x, dtype=float)


def fit_covariance(
    t: NDArray[np.float64], y: NDArray[np.float64], params: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], float, int]:
    """(linear coefficients (basis, signals), covariance of (s_k, w_k), pooled residual variance, dof)."""
    basis = damped_basis(t, params)
    coef = np.asarray(np.linalg.lstsq(basis, y.T, rcond=None)[0], dtype=np.float64)
    res = basis @ coef - y.T
    signals = y.shape[0]
    dof = max(1, y.size - params.size - signals * basis.shape[1])
    variance = float(np.sum(res**2)) / dof
    jac = _projected_jacobian(t, basis, coef, params).reshape(-1, params.size)
    fisher = jac.T @ jac
    try:
        cov = np.linalg.inv(fisher) * variance
    except np.linalg.LinAlgError:
        cov = np.full((params.size, params.size), np.inf)
    return coef, cov, variance, dof


def mode_statistics(s: float, w: float, cov2: NDArray[np.float64]) -> tuple[float, float, float, float]:
    """(f_n Hz, zeta, std f_n Hz, std zeta) from (s, w) and their 2x2 covariance, by the delta method."""
    wn = math.hypot(s, w)
    zeta = s / wn
    grad_wn = np.array([s / wn, w / wn])
    grad_zeta = np.array([w * w / wn**3, -s * w / wn**3])
    var_wn = float(grad_wn @ cov2 @ grad_wn)
    var_zeta = float(grad_zeta @ cov2 @ grad_zeta)
    std_fn = math.sqrt(var_wn) / (2 * math.pi) if var_wn >= 0 and math.isfinite(var_wn) else math.inf
    std_zeta = math.sqrt(var_zeta) if var_zeta >= 0 and math.isfinite(var_zeta) else math.inf
    return wn / (2 * math.pi), zeta, std_fn, std_zeta


def fit_damped_sinusoids(
    t: NDArray[np.float64], y: NDArray[np.float64], peaks: list[tuple[float, float]], nyquist: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The fit's (s_k, w_k) and the signals' weights (1 / residual std of a first, unweighted fit)."""
    x0 = np.empty(2 * len(peaks))
    for k, (f, zeta) in enumerate(peaks):
        wn = 2 * math.pi * f
        x0[2 * k] = zeta * wn
        x0[2 * k + 1] = wn * math.sqrt(1 - zeta * zeta)
    w0 = x0[1::2]
    lower = np.empty_like(x0)
    upper = np.empty_like(x0)
    # a growing envelope is allowed (and reported), but at most e^20 over the window: no overflow
    lower[0::2], upper[0::2] = -np.minimum(0.05 * w0, 20.0 / max(float(t[-1]), 1e-300)), 2.0 * w0
    lower[1::2], upper[1::2] = 0.5 * w0, np.minimum(1.5 * w0, 2 * math.pi * nyquist)
    params = _projected_fit(t, y, x0, lower, upper)
    basis = damped_basis(t, params)
    coef = np.asarray(np.linalg.lstsq(basis, y.T, rcond=None)[0], dtype=np.float64)
    std = np.std(basis @ coef - y.T, axis=0)
    weights = 1.0 / np.where(std > 0, std, 1.0)
    if y.shape[0] > 1:
        params = _projected_fit(t, y * weights[:, None], params, lower, upper)
    return params, weights
