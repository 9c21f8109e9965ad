"""Product integration of the modal integrals (Incerti eqs. 27-30): Chebyshev interpolation, Gauss-Legendre panels."""

from __future__ import annotations

import functools
import math

import numpy as np
from numpy.typing import NDArray

from models.errors import InvalidParameter
from optim.families.pseudo_polynomial.types import FloatArray
from runtime.cache import ArrayCache

__all__ = ["INTERPOLATION_NODES", "MAX_PHASE_RAD", "chebyshev_nodes", "product_weights"]

INTERPOLATION_NODES = (
    96  # Chebyshev nodes of the product integration (optim.families.pseudo_polynomial.problem's docstring)
)
PANEL_NODES = 32  # Gauss-Legendre nodes per panel of the kernel's integration
PANEL_PHASE_RAD = 8.0  # each panel spans at most this much of |z| (the kernel turns <= 16 rad in it)
MAX_PHASE_RAD = 2 * math.pi * 5000  # 5000 periods: the kernel's integration stays below ~50 ms


def chebyshev_nodes(count: int = INTERPOLATION_NODES) -> FloatArray:
    """Chebyshev points of the first kind mapped to (0, 1): v_j = (1 - cos((2j + 1) pi / (2 count))) / 2."""
    return 0.5 * (1.0 - np.cos((2 * np.arange(count) + 1) * np.pi / (2 * count)))


def _check_phase(phase_rad: float) -> None:
    if phase_rad > MAX_PHASE_RAD:
        raise InvalidParameter(
            "duration_s",
            phase_rad,
            f"the move lasts {phase_rad / (2 * math.pi):.0f} periods of the plant's mode; pseudo-polynomial design "
            f"supports up to {MAX_PHASE_RAD / (2 * math.pi):.0f}",
        )


PANEL_CACHE_BYTES = 48 * 1024 * 1024  # a block of 512 panels is 12.6 MB (its Chebyshev table): ~4 blocks kept
_PANEL_RULES: ArrayCache[tuple[int, int, int, int], tuple[FloatArray, FloatArray, FloatArray]] = ArrayCache(
    PANEL_CACHE_BYTES
)


def _panel_rule(panels: int, first: int, stop: int, count: int) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Nodes, weights and T_k(2 v - 1), k < count, of panels first..stop-1 of ``panels`` equal ones on [0, 1].

    Cached by bytes (``PANEL_CACHE_BYTES``): the panel count follows |lambda T|, so every distinct plant or
    duration makes new tables, and an ``lru_cache(32)`` of them held up to 400 MB per worker (issue 15)."""
    return _PANEL_RULES.get((panels, first, stop, count), lambda: _build_panel_rule(panels, first, stop, count))


def _build_panel_rule(panels: int, first: int, stop: int, count: int) -> tuple[FloatArray, FloatArray, FloatArray]:
    x, w = np.polynomial.legendre.leggauss(PANEL_NODES)
    edges = np.arange(first, stop + 1) / panels
    a, b = edges[:-1, None], edges[1:, None]
    v = (a + 0.5 * (b - a) * (x + 1.0)).ravel()
    weight = (0.5 * (b - a) * w).ravel()
    chebyshev = np.cos(np.outer(np.arccos(np.clip(2.0 * v - 1.0, -1.0, 1.0)), np.arange(count)))
    return v, weight, chebyshev


@functools.lru_cache(maxsize=4)
def _nodal_basis(count: int) -> FloatArray:
    """(2/count) T_k(x_j) with the k = 0 column halved: Chebyshev moments -> nodal weights."""
    nodes_x = 2.0 * chebyshev_nodes(count) - 1.0
    basis = np.cos(np.outer(np.arccos(nodes_x), np.arange(count)))
    basis[:, 0] *= 0.5
    out: FloatArray = (2.0 / count) * basis
    return out


def product_weights(z: complex, count: int = INTERPOLATION_NODES) -> NDArray[np.complex128]:
    """W_j = int_0^1 l_j(v) exp(z v^2) dv for the Lagrange basis l_j at ``chebyshev_nodes(count)``, so that
    int_0^1 f(v) exp(z v^2) dv ~ sum_j W_j f(v_j) for any smooth f.

    l_j(v) = (2/count) sum'_k T_k(x_j) T_k(x) with x = 2 v - 1 (discrete orthogonality of the nodes; the
    k = 0 term halved), so W_j = (2/count) sum'_k T_k(x_j) m_k with the kernel's Chebyshev moments
    m_k = int_0^1 T_k(2 v - 1) exp(z v^2) dv, integrated by composite Gauss-Legendre: panels of at most
    ``PANEL_PHASE_RAD`` of |z| (and enough for the degree count - 1 of T_k), ``PANEL_NODES`` nodes each.
    """
    _check_phase(abs(z))
    panels = max(math.ceil(abs(z) / PANEL_PHASE_RAD), math.ceil(count / 8), 1)
    moments = np.zeros(count, dtype=complex)
    for first in range(0, panels, 512):  # blocks of panels bound the memory at long moves
        v, weight, chebyshev = _panel_rule(panels, first, min(first + 512, panels), count)
        kernel = weight * np.exp(z * v * v)
        moments += chebyshev.T @ kernel.real + 1j * (chebyshev.T @ kernel.imag)  # real BLAS products
    basis = _nodal_basis(count)
    weights: NDArray[np.complex128] = basis @ moments.real + 1j * (basis @ moments.imag)
    return weights
