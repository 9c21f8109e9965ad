"""An axis's plant over a coordinate: a table of plants, interpolated linearly in each parameter (a payload's
inertia, a belt's stiffness, a mode's frequency and damping ratio), and the band of natural frequencies a move
passes through.

The kinds a table may hold are those whose load follows the motor through one spring and damper, so that the
plant whose parameters change with the coordinate has one meaning (the deflection e = load - motor obeys
e'' + 2 zeta(t) w(t) e' + w(t)^2 e = -motor'': models.varying_mode): ``mode`` and ``two_inertia``.
"""

from __future__ import annotations

import bisect
import dataclasses
import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from models.plants import Mode, Plant, make_plant
from optim.programs.types import PlantTable


def plant_at(table: PlantTable, at: float) -> Plant:
    """The plant at coordinate ``at`` (within the table's range): every parameter linear between the two
    neighbouring points (the point itself at a point)."""
    points = table.points
    if not table.low <= at <= table.high:
        raise ValueError(f"{at} is outside the table's range [{table.low}, {table.high}]")
    j = min(max(bisect.bisect_right([p.at for p in points], at) - 1, 0), len(points) - 2)
    a, b = points[j], points[j + 1]
    weight = (at - a.at) / (b.at - a.at)
    if weight == 0.0:
        return a.plant
    if weight == 1.0:
        return b.plant
    params = {}
    for f in dataclasses.fields(a.plant):
        x, y = getattr(a.plant, f.name), getattr(b.plant, f.name)
        params[f.name] = (1.0 - weight) * x + weight * y if isinstance(x, float | int) else x
    return make_plant(a.plant.kind, **params)


def mode_at(table: PlantTable, at: float) -> Mode:
    return plant_at(table, at).modes()[0]


def frequency_range_hz(table: PlantTable, low: float, high: float) -> tuple[float, float]:
    """The least and greatest natural frequency over coordinates [low, high]: at its ends and the table points
    inside (between two points the frequency is monotone: linear for ``mode``, sqrt of a ratio of two linear
    functions for ``two_inertia``)."""
    ats = [low, high, *(p.at for p in table.points if low < p.at < high)]
    freqs = [mode_at(table, a).natural_frequency_hz for a in ats]
    return min(freqs), max(freqs)


def frequency_spread(table: PlantTable, low: float, high: float) -> float:
    """max / min natural frequency over [low, high], minus 1 (0: the mode does not change)."""
    lo, hi = frequency_range_hz(table, low, high)
    return hi / lo - 1.0 if lo > 0 else math.inf


def _columns(table: PlantTable) -> tuple[str, tuple[str, ...]]:
    """The table's kind and the parameters its mode is made of (interpolated linearly, as plant_at does)."""
    kind = table.points[0].plant.kind
    if kind == "mode":
        return kind, ("natural_frequency_hz", "damping_ratio")
    return kind, ("stiffness_nm_per_rad", "damping_nms_per_rad", "load_inertia_kgm2")


def modes_at(table: PlantTable, coordinates: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(w rad/s, zeta) of ``plant_at(table, c)``'s mode at every one of ``coordinates``, at once (``mode_function``'s
    formulas on arrays: the samples of a cycle)."""
    kind, names = _columns(table)
    ats = [p.at for p in table.points]
    x = [np.interp(coordinates, ats, [float(getattr(p.plant, n)) for p in table.points]) for n in names]
    if kind == "mode":
        return 2.0 * math.pi * x[0], x[1]
    omega = np.sqrt(x[0] / x[2])
    return omega, x[1] / (2.0 * x[2] * omega)


def mode_function(table: PlantTable) -> Callable[[float], tuple[float, float]]:
    """c -> (w rad/s, zeta) of ``plant_at(table, c)``'s mode, in plain float arithmetic (the varying mode's
    integration calls it at every step): the parameters interpolated as plant_at does, then the kind's formula
    (``mode``: w = 2 pi f; ``two_inertia``: w = sqrt(k / J_L), zeta = c / (2 J_L w), Cusimano eqs. 1 and 3)."""
    ats = [p.at for p in table.points]
    kind, names = _columns(table)
    values = [[float(getattr(p.plant, n)) for p in table.points] for n in names]

    def at(c: float) -> tuple[float, float]:
        j = min(max(bisect.bisect_right(ats, c) - 1, 0), len(ats) - 2)
        weight = (c - ats[j]) / (ats[j + 1] - ats[j])
        x = [(1.0 - weight) * v[j] + weight * v[j + 1] for v in values]
        if kind == "mode":
            return 2.0 * math.pi * x[0], x[1]
        omega = math.sqrt(x[0] / x[2])
        return omega, x[1] / (2.0 * x[2] * omega)

    return at
