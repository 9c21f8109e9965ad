"""Input-shaper design from a vibration mode, and the catalogue of shapers.

Shapers (all damping-aware; the conventional definitions of Singhose's papers and of Klipper's
``klippy/extras/shaper_defs.py``, which users compare with):

- ``zv``, ``zvd``, ``zvdd``, ``zvddd``, ... (``zv`` followed by k letters ``d``): V = 0 and its
  first k derivatives with respect to omega vanish at the mode (eqs. 4-5 for k = 1). Closed form,
  exact: A_i = C(k+1, i) K^i / (1 + K)^(k+1), t_i = i pi / omega_d, K = exp(-zeta pi/sqrt(1-zeta^2));
  eqs. (8)-(11) for k = 1 (Singer & Seering 1990), the ZV shaper convolved with itself k times
  for higher orders (Singhose 2009, Sec. 3).
- ``mzv``: Klipper's three impulses over 0.75 of the damped period, A proportional to
  (1 - 1/sqrt 2, (sqrt 2 - 1) K, (1 - 1/sqrt 2) K^2), t = (0, 0.375, 0.75) T_d with
  K = exp(-0.75 zeta pi / sqrt(1 - zeta^2)); V = 0 at the mode exactly. Closed form.
- ``ei``, ``2hump_ei``, ``3hump_ei``: the extra-insensitive shapers of Singhose, Seering & Singer
  (1994/1997) with m = 1, 2, 3 humps and m + 2 impulses. Defining conditions: the amplitudes sum
  to one; V has m humps (local maxima) of height V_tol and m + 1 zeros; the middle hump (m odd) or
  the middle zero (m even) is at the mode. That is 4m + 3 equations in as many unknowns (m + 2
  amplitudes, m + 1 times, and the free hump and zero frequencies). The literature gives exact
  closed forms only without damping (e.g. EI: A = ((1+V)/4, (1-V)/2, (1+V)/4) at 0, T/2, T) and
  polynomial *fits* in zeta for the damped case (the ones Klipper uses: within about 1e-3 in
  amplitude and 1e-2 of a period in time for zeta <= 0.1, and their V at the mode misses V_tol by
  up to 0.6 points of percentage at zeta = 0.2); here the conditions are solved exactly by
  root-finding (scipy ``root``), continued in zeta from the exact undamped solution. Beyond some
  damping (5 %: EI about 0.68, 2-hump 0.44, 3-hump 0.28) the last impulses merge and no solution
  exists; that is reported as infeasible.

The baselines under the acceleration limit (Sec. 4 of Chatlatanagulchai & Pongpanich) are in
``optim.families.input_shaped.shaper_baselines``; they are re-exported here.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import root

from models.errors import Infeasible, InvalidParameter
from models.plants import Mode
from models.shapers import ImpulseSequence, convolve, vibration_band, zv_family
from optim.families.input_shaped.shaper_baselines import (
    Baseline,
    BaselineChoice,
    BaselineKind,
    design_baseline,
    fastest_cruise_velocity,
    fastest_single_ramp_cruise,
    fastest_steps,
    modified_baseline,
    modified_ramp_time_s,
    multi_step_baseline,
    paper_two_step,
    single_ramp_baseline,
    single_ramp_time_s,
    step_baseline,
    window_sums,
)

__all__ = [
    "CATALOGUE_NAMES",
    "DEFAULT_VIBRATION_TOLERANCE",
    "EI_HUMPS",
    "MAX_COMMAND_S",
    "MAX_DERIVATIVE_ORDER",
    "Baseline",
    "BaselineChoice",
    "BaselineKind",
    "CatalogueEntry",
    "ShaperDesign",
    "catalogue",
    "design_baseline",
    "design_for_modes",
    "design_shaper",
    "ei_family",
    "ei_undamped",
    "fastest_cruise_velocity",
    "fastest_single_ramp_cruise",
    "fastest_steps",
    "modified_baseline",
    "modified_ramp_time_s",
    "multi_step_baseline",
    "mzv",
    "paper_two_step",
    "single_ramp_baseline",
    "single_ramp_time_s",
    "step_baseline",
    "window_sums",
    "zv_family",
]

FloatArray = NDArray[np.float64]

DEFAULT_VIBRATION_TOLERANCE = 0.05
MAX_DERIVATIVE_ORDER = 8  # zv followed by up to 8 letters d
EI_HUMPS = {"ei": 1, "2hump_ei": 2, "3hump_ei": 3}
_EI_LABELS = {1: "EI", 2: "2-hump EI", 3: "3-hump EI"}
CATALOGUE_NAMES = ("zv", "mzv", "zvd", "zvdd", "zvddd", "ei", "2hump_ei", "3hump_ei")
_ZV_PATTERN = re.compile(r"^zv(d*)$")
_CONDITIONS_TOLERANCE = 1e-10  # defining conditions are O(1) numbers: round-off is ~1e-15
_ZETA_STEP = 0.05  # continuation step in the damping ratio for the EI family
_ZETA_STEP_MIN = 1e-3
MAX_COMMAND_S = 1e6  # the longest shaped command the service simulates


@dataclass(frozen=True)
class ShaperDesign:
    """A shaper designed for one or more modes (convolved), with how it was obtained."""

    name: str
    modes: tuple[Mode, ...]
    impulses: ImpulseSequence
    vibration_tolerance: float | None
    method: str
    reference: str
    conditions_residual: float | None  # largest residual of the defining conditions, when solved

    @property
    def duration_periods(self) -> float:
        """Duration in damped periods of the first (design) mode."""
        return self.impulses.duration_s / self.modes[0].damped_period_s


def _check_name(name: str) -> str:
    name = str(name).strip().lower()
    match = _ZV_PATTERN.match(name)
    if match and len(match.group(1)) <= MAX_DERIVATIVE_ORDER:
        return name
    if name in EI_HUMPS or name == "mzv":
        return name
    raise InvalidParameter(
        "shaper",
        name,
        f"must be one of {', '.join(CATALOGUE_NAMES)} (or zv followed by up to {MAX_DERIVATIVE_ORDER} letters d)",
    )


def _check_tolerance(value: float) -> float:
    v = float(value)
    if not (math.isfinite(v) and 0.001 <= v <= 0.3):
        raise InvalidParameter("vibration_tolerance", v, "must lie in [0.001, 0.3]")
    return v


# ------------------------------------------------------------------------------------------
# Closed forms


def mzv(mode: Mode) -> ImpulseSequence:
    """Klipper's MZV: 3 impulses over 0.75 T_d; zero residual at the mode (exact with damping)."""
    zeta = mode.damping_ratio
    big_k = math.exp(-0.75 * zeta * math.pi / math.sqrt(1.0 - zeta * zeta))
    a1 = 1.0 - 1.0 / math.sqrt(2.0)
    amplitudes = np.array([a1, (math.sqrt(2.0) - 1.0) * big_k, a1 * big_k * big_k])
    times = np.array([0.0, 0.375, 0.75]) * mode.damped_period_s
    return ImpulseSequence(amplitudes / amplitudes.sum(), times)


def ei_undamped(humps: int, tolerance: float) -> FloatArray:
    """The exact undamped m-hump EI amplitudes (impulses T/2 apart), Singhose et al.:
    EI ((1+V)/4, (1-V)/2, (1+V)/4); 2-hump A1 = (3X^2 + 2X + 3V^2)/(16X),
    X = (V^2 (sqrt(1-V^2) + 1))^(1/3); 3-hump A1 = (1 + 3V + 2 sqrt(2V(V+1)))/16, A2 = (1-V)/4."""
    v = tolerance
    if humps == 1:
        return np.array([(1 + v) / 4, (1 - v) / 2, (1 + v) / 4])
    if humps == 2:
        x = (v * v * (math.sqrt(1 - v * v) + 1)) ** (1 / 3)
        a1 = (3 * x * x + 2 * x + 3 * v * v) / (16 * x)
        return np.array([a1, 0.5 - a1, 0.5 - a1, a1])
    a1 = (1 + 3 * v + 2 * math.sqrt(2 * v * (v + 1))) / 16
    a2 = (1 - v) / 4
    return np.array([a1, a2, 1 - 2 * (a1 + a2), a2, a1])


# ------------------------------------------------------------------------------------------
# The EI family by root-finding on its defining conditions


def _z_and_derivative(a: FloatArray, t: FloatArray, r: float, zeta: float) -> tuple[complex, complex]:
    """sum_i A_i exp(-zeta r (t_n - t_i)) exp(j r sqrt(1-zeta^2) t_i) and its r-derivative, with
    times in units of 1/omega_n and r = omega/omega_n: |.| is V of Sec. 3.1."""
    wd = math.sqrt(1.0 - zeta * zeta)
    terms = a * np.exp(-zeta * r * (t[-1] - t) + 1j * r * wd * t)
    return complex(terms.sum()), complex((terms * (-zeta * (t[-1] - t) + 1j * wd * t)).sum())


def _extrema(a: FloatArray, t: FloatArray, humps: int) -> tuple[FloatArray, FloatArray]:
    """Zeros and humps of the undamped V(r) around r = 1 (the starting point of the solve)."""
    r = np.linspace(0.2, 1.8, 16001)
    v = np.abs(np.exp(1j * np.outer(r, t)) @ a)
    inner = np.arange(1, r.size - 1)
    minima = inner[(v[inner] < v[inner - 1]) & (v[inner] <= v[inner + 1])]
    zeros = np.sort(r[minima[np.argsort(np.abs(r[minima] - 1.0))[: humps + 1]]])
    maxima = inner[(v[inner] > v[inner - 1]) & (v[inner] >= v[inner + 1])]
    tops = np.sort(r[maxima[(r[maxima] > zeros[0]) & (r[maxima] < zeros[-1])]])
    return zeros, tops


class _EIConditions:
    """Unknowns x = (A_1..A_n, t_2..t_n, free zero ratios, free hump ratios); 4m + 3 equations."""

    def __init__(self, humps: int, tolerance: float) -> None:
        self.humps = humps
        self.n = humps + 2
        self.tolerance = tolerance
        self.even = humps % 2 == 0  # the middle zero (m even) or hump (m odd) is at r = 1

    def unpack(self, x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        n, m = self.n, self.humps
        a = x[:n]
        t = np.concatenate(([0.0], x[n : 2 * n - 1]))
        rest = x[2 * n - 1 :]
        free_zeros = m + 1 - (1 if self.even else 0)
        zeros, tops = rest[:free_zeros], rest[free_zeros:]
        if self.even:
            zeros = np.sort(np.append(zeros, 1.0))
        else:
            tops = np.sort(np.append(tops, 1.0))
        return a, t, zeros, tops

    def pack(self, a: FloatArray, t: FloatArray, zeros: FloatArray, tops: FloatArray) -> FloatArray:
        free_zeros = [z for z in zeros if abs(z - 1.0) > 1e-6] if self.even else list(zeros)
        free_tops = list(tops) if self.even else [h for h in tops if abs(h - 1.0) > 1e-6]
        return np.concatenate([a, t[1:], free_zeros, free_tops])

    def residual(self, x: FloatArray, zeta: float) -> FloatArray:
        a, t, zeros, tops = self.unpack(x)
        equations = [a.sum() - 1.0]  # eq. (6)
        for r in zeros:  # V = 0: both parts of C + jS vanish
            z, _ = _z_and_derivative(a, t, r, zeta)
            equations += [z.real, z.imag]
        for r in tops:  # V^2 = V_tol^2 and d(V^2)/dr = 0 (a hump of height V_tol)
            z, dz = _z_and_derivative(a, t, r, zeta)
            equations += [abs(z) ** 2 - self.tolerance**2, 2.0 * (z.conjugate() * dz).real]
        return np.array(equations)

    def well_formed(self, x: FloatArray) -> bool:
        a, t, zeros, tops = self.unpack(x)
        ordered = np.sort(np.concatenate([zeros, tops]))
        alternating = np.all(np.isin(ordered[::2], zeros)) and ordered.size == 2 * self.humps + 1
        return bool(np.all(a > 0.0) and np.all(np.diff(t) > 0.0) and zeros[0] > 0.0 and alternating)


@lru_cache(maxsize=256)
def _ei_normalised(humps: int, zeta: float, tolerance: float) -> tuple[tuple[float, ...], tuple[float, ...], float]:
    """Amplitudes and times (units of 1/omega_n) of the m-hump EI shaper, and the largest residual
    of its defining conditions. Solved from the exact undamped solution, continued in zeta."""
    conditions = _EIConditions(humps, tolerance)
    a0 = ei_undamped(humps, tolerance)
    t0 = math.pi * np.arange(a0.size, dtype=np.float64)
    zeros, tops = _extrema(a0, t0, humps)
    x = conditions.pack(a0, t0, zeros, tops)
    reached, step = None, _ZETA_STEP
    while reached is None or reached < zeta:  # from zeta = 0 (polishing the zeros and humps found on
        # a grid) on, in steps of zeta halved where a solve fails
        target = 0.0 if reached is None else min(zeta, reached + step)
        # hybr may step to where exp(-zeta r (t_n - t_i)) overflows: such a step is a failed solve (its
        # residual is not finite, so it is not accepted), never an error
        with np.errstate(over="ignore", invalid="ignore"):
            solution = root(conditions.residual, x, args=(target,), method="hybr", options={"xtol": 1e-13})
            residual = float(np.max(np.abs(conditions.residual(solution.x, target))))
        if math.isfinite(residual) and residual <= _CONDITIONS_TOLERANCE and conditions.well_formed(solution.x):
            x, reached, worst, step = solution.x, target, residual, min(2.0 * step, _ZETA_STEP)
            continue
        step *= 0.5
        if reached is None or step < _ZETA_STEP_MIN:
            raise Infeasible(
                f"no {_EI_LABELS[humps]} shaper with vibration tolerance {tolerance:g} exists beyond damping ratio "
                f"about {reached or 0.0:.3g} (asked {zeta:.4g}): its defining conditions (humps of height "
                f"{tolerance:g} with zeros between them) lose their solution as the last impulses merge; "
                f"use a larger vibration_tolerance, fewer humps, or a ZV-D shaper",
                "vibration_tolerance",
            )
    a, t, _, _ = conditions.unpack(x)
    return tuple(a.tolist()), tuple(t.tolist()), worst


def ei_family(mode: Mode, humps: int, tolerance: float) -> tuple[ImpulseSequence, float]:
    """The m-hump EI shaper for a mode, exact to its defining conditions (see the module doc)."""
    a, t, worst = _ei_normalised(humps, round(mode.damping_ratio, 12), tolerance)
    return ImpulseSequence(np.array(a), np.array(t) / mode.natural_frequency_rad_s), worst


# ------------------------------------------------------------------------------------------
# Design entry points


_REFERENCES = {
    "zv": "Singer & Seering 1990; Singhose 2009 (ZV); Klipper get_zv_shaper",
    "zvd": "Chatlatanagulchai & Pongpanich eqs. (8)-(11); Singer & Seering 1990; Klipper get_zvd_shaper",
    "zvd+": "Singhose 2009, Sec. 3: the ZV shaper convolved with itself (ZVDD, ZVDDD, ...)",
    "mzv": "Klipper get_mzv_shaper (3 impulses over 0.75 T_d)",
    "ei": "Singhose, Seering & Singer 1994/1997 (EI); Klipper's damped fit is an approximation",
}


def design_shaper(name: str, mode: Mode, vibration_tolerance: float = DEFAULT_VIBRATION_TOLERANCE) -> ShaperDesign:
    """The named shaper for one mode."""
    name = _check_name(name)
    if name in EI_HUMPS:
        tolerance = _check_tolerance(vibration_tolerance)
        impulses, worst = ei_family(mode, EI_HUMPS[name], tolerance)
        method = "defining conditions solved exactly by root-finding (the literature's damped forms are fits)"
        return ShaperDesign(name, (mode,), impulses, tolerance, method, _REFERENCES["ei"], worst)
    if name == "mzv":
        return ShaperDesign(name, (mode,), mzv(mode), None, "closed form (exact)", _REFERENCES["mzv"], None)
    derivatives = len(name) - 2
    reference = _REFERENCES.get(name, _REFERENCES["zvd+"])
    return ShaperDesign(name, (mode,), zv_family(mode, derivatives), None, "closed form (exact)", reference, None)


def design_for_modes(
    name: str, modes: tuple[Mode, ...], vibration_tolerance: float = DEFAULT_VIBRATION_TOLERANCE
) -> ShaperDesign:
    """One shaper per mode, convolved (the shaper of each mode cancels that mode)."""
    if not modes:
        raise InvalidParameter("plant", "no vibration mode", "the plant has no oscillatory mode to shape")
    designs = [design_shaper(name, mode, vibration_tolerance) for mode in modes]
    impulses = designs[0].impulses
    for other in designs[1:]:  # a loop over a handful of modes
        impulses = convolve(impulses, other.impulses)
    first = designs[0]
    residuals = [d.conditions_residual for d in designs if d.conditions_residual is not None]
    method = first.method + (f", convolved over {len(modes)} modes" if len(modes) > 1 else "")
    return ShaperDesign(
        first.name,
        tuple(modes),
        impulses,
        first.vibration_tolerance,
        method,
        first.reference,
        max(residuals) if residuals else None,
    )


# ------------------------------------------------------------------------------------------
# The catalogue


@dataclass(frozen=True)
class CatalogueEntry:
    name: str
    impulse_count: int
    duration_periods: float
    band: tuple[float | None, float | None] | None  # an end is None past the scanned ratios
    amplitudes: tuple[float, ...]
    times_periods: tuple[float, ...]
    method: str
    reference: str


@lru_cache(maxsize=64)
def catalogue(
    damping_ratio: float = 0.0, vibration_tolerance: float = DEFAULT_VIBRATION_TOLERANCE, threshold: float = 0.05
) -> tuple[tuple[CatalogueEntry, ...], tuple[tuple[str, str], ...]]:
    """Every catalogue shaper for a unit mode with this damping, with its computed band (the
    frequency ratios around 1 where V of Sec. 3.1 stays <= threshold), and the (name, reason) of
    the EI shapers that do not exist at this damping and tolerance."""
    mode = Mode(1.0, damping_ratio)
    entries, missing = [], []
    for name in CATALOGUE_NAMES:  # a loop over eight shapers
        try:
            design = design_shaper(name, mode, vibration_tolerance)
        except Infeasible as exc:
            missing.append((name, exc.reason))
            continue
        band = vibration_band(design.impulses, mode.natural_frequency_rad_s, damping_ratio, threshold)
        entries.append(
            CatalogueEntry(
                name,
                design.impulses.count,
                design.duration_periods,
                band,
                tuple(design.impulses.amplitudes.tolist()),
                tuple((design.impulses.times_s / mode.damped_period_s).tolist()),
                design.method,
                design.reference,
            )
        )
    return tuple(entries), tuple(missing)
