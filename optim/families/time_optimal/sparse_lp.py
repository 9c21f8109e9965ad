"""A sparse LP of the time-optimal search: held values then scaled states, its dynamics, outputs and band polygons."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from optim.families.time_optimal.state_chain import StateChain, discretise

Array = NDArray[np.float64]
CArray = NDArray[np.complex128]
POLYGON_SIDES = 16


@dataclass
class SparseLp:
    """A sparse LP in x (N held values) then z_0..z_N (scaled states)."""

    steps: int
    states: int
    extra: int = 0  # variables after the states (|x_k| of the weighted L1 objective)
    cut_count: int = 0  # then (Re F, Im F) / bound of each band point
    lower: Array = field(init=False)
    upper: Array = field(init=False)
    eq: list[sp.coo_matrix] = field(default_factory=list)
    eq_rhs: list[Array] = field(default_factory=list)
    ub: list[sp.coo_matrix] = field(default_factory=list)
    ub_rhs: list[Array] = field(default_factory=list)

    def __post_init__(self) -> None:
        size = self.steps + (self.steps + 1) * self.states + self.extra + 2 * self.cut_count
        self.cost = np.zeros(size)
        self.lower = np.full(size, -np.inf)
        self.upper = np.full(size, np.inf)

    def state(self, k: int | NDArray[np.integer[Any]], i: int | NDArray[np.integer[Any]]) -> NDArray[np.intp]:
        """The variable index of state i at node k (arrays broadcast)."""
        out: NDArray[np.intp] = np.asarray(self.steps + np.asarray(k) * self.states + np.asarray(i), dtype=np.intp)
        return out

    def dense_x_rows(self, rows: Array) -> sp.coo_matrix:
        pad = sp.coo_matrix((rows.shape[0], self.lower.size - self.steps))
        return sp.hstack([sp.coo_matrix(rows), pad]).tocoo()

    def weighted_l1(self, weights: Array) -> None:
        """Minimise sum_k weights_k |x_k| (a feasibility LP returns any vertex, often chattering): another
        vertex, with another arc structure for the refinement to start from."""
        n, first = self.steps, self.lower.size - self.extra - 2 * self.cut_count
        k = np.arange(n)
        w = first + k
        for sign in (1.0, -1.0):
            m = sp.coo_matrix(
                (np.concatenate([sign * np.ones(n), -np.ones(n)]), (np.concatenate([k, k]), np.concatenate([k, w]))),
                shape=(n, self.lower.size),
            )
            self.add_ub(m, np.zeros(n))
        self.lower[w] = 0.0
        self.cost[w] = weights

    def band(self, weights: CArray, bounds: Array, inscribed: bool) -> None:
        """|weights_p . x| <= bounds_p for each band point: (Re, Im) / bound as two variables (two dense rows),
        then the 16-gon on them (sparse): inscribed in the unit circle (the bound holds) or circumscribed
        (a relaxation)."""
        first = self.lower.size - 2 * weights.shape[0]
        eq, polygon, rhs = band_rows(weights, bounds, inscribed, first, self.lower.size)
        self.add_eq(eq, np.zeros(eq.shape[0]))
        self.add_ub(polygon, rhs)

    def add_eq(self, m: sp.coo_matrix, rhs: Array) -> None:
        self.eq.append(m)
        self.eq_rhs.append(np.asarray(rhs, dtype=float))

    def add_ub(self, m: sp.coo_matrix, rhs: Array) -> None:
        self.ub.append(m)
        self.ub_rhs.append(np.asarray(rhs, dtype=float))

    def dynamics(self, c: StateChain, h: float, unit: float) -> None:
        """z_(k+1) - Phi z_k - Gamma U x_k = 0, in scaled states (row i divided by scale_i)."""
        phi, gamma = discretise(c, h)
        n, s = self.states, c.scale
        phi_s = phi * s[None, :] / s[:, None]
        gamma_s = gamma * unit / s
        k = np.arange(self.steps)
        rows, cols, vals = [], [], []
        for i in range(n):
            r = k * n + i
            rows.append(r)
            cols.append(self.state(k + 1, i))
            vals.append(np.ones(k.size))
            for j in range(n):
                if phi_s[i, j] != 0.0:
                    rows.append(r)
                    cols.append(self.state(k, j))
                    vals.append(np.full(k.size, -phi_s[i, j]))
            if gamma_s[i] != 0.0:
                rows.append(r)
                cols.append(k)
                vals.append(np.full(k.size, -gamma_s[i]))
        m = sp.coo_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
            shape=(self.steps * n, self.lower.size),
        )
        self.add_eq(m, np.zeros(self.steps * n))

    def output_rows(
        self, c: StateChain, row: Array, d: float, h: float, unit: float, points: tuple[float, ...]
    ) -> sp.coo_matrix:
        """Rows of row . z(t_k + theta h) + d u_k for each step and theta (scaled states)."""
        mats = []
        k = np.arange(self.steps)
        for theta in points:
            phi, gamma = discretise(c, theta * h) if theta > 0 else (np.eye(self.states), np.zeros(self.states))
            cz = (row @ phi) * c.scale
            du = float(row @ gamma) * unit + d * unit
            rows = [k] * (self.states + 1)
            cols = [self.state(k, j) for j in range(self.states)] + [k]
            vals = [np.full(k.size, cz[j]) for j in range(self.states)] + [np.full(k.size, du)]
            mats.append(
                sp.coo_matrix(
                    (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                    shape=(self.steps, self.lower.size),
                )
            )
        return sp.vstack(mats).tocoo()


def band_rows(
    weights: CArray, bounds: Array, inscribed: bool, first: int, columns: int
) -> tuple[sp.coo_matrix, sp.coo_matrix, Array]:
    """SparseLp.band's rows for band points whose (Re, Im) / bound variables are columns ``first`` on (all the
    real parts, then the imaginary ones) of ``columns``: the equalities that define them (right-hand side 0), the
    16-gon's rows and their right-hand side."""
    count = weights.shape[0]
    steps = weights.shape[1]
    scaled = weights / bounds[:, None]
    parts = np.vstack([scaled.real, scaled.imag])
    scale = np.max(np.abs(parts), axis=1)
    scale[scale == 0.0] = 1.0
    # each row: the steps' weights, then its own variable's -1 (over the row's scale)
    values = np.hstack([parts / scale[:, None], (-1.0 / scale)[:, None]])
    columns_of = np.hstack([np.tile(np.arange(steps), (2 * count, 1)), (first + np.arange(2 * count))[:, None]])
    starts = np.arange(2 * count + 1) * (steps + 1)
    eq = sp.csr_matrix((values.ravel(), columns_of.ravel(), starts), shape=(2 * count, columns)).tocoo()
    theta = 2 * math.pi * np.arange(POLYGON_SIDES) / POLYGON_SIDES
    factor = math.cos(math.pi / POLYGON_SIDES) if inscribed else 1.0
    p = np.arange(count)
    rows = (p[:, None] * POLYGON_SIDES + np.arange(POLYGON_SIDES)[None, :]).ravel()
    re_cols = np.repeat(first + p, POLYGON_SIDES)
    im_cols = np.repeat(first + count + p, POLYGON_SIDES)
    cos, sin = np.tile(np.cos(theta), count), np.tile(np.sin(theta), count)
    polygon = sp.coo_matrix(
        (np.concatenate([cos, sin]), (np.concatenate([rows, rows]), np.concatenate([re_cols, im_cols]))),
        shape=(count * POLYGON_SIDES, columns),
    )
    return eq, polygon, np.full(count * POLYGON_SIDES, factor)
