"""The time-optimal family's options (robustness, modes, trade-off, search horizon) and the bands they ask for."""

from __future__ import annotations

import math
from dataclasses import dataclass

from models.plant_base import Mode
from optim.families.time_optimal.types import DEFAULT_MAX_PERCENTAGE_VIBRATION, Band
from optim.problem import Problem

MAX_TRADEOFF = 8


@dataclass(frozen=True)
class Robustness:
    """A band (ratios to each cancelled mode, or absolute Hz) where V <= max_percentage_vibration, or zero
    residual and zero frequency derivatives up to ``derivative_order`` at the nominal modes."""

    frequency_ratio_range: tuple[float, float] | None = None
    frequency_range_hz: tuple[float, float] | None = None
    max_percentage_vibration: float = DEFAULT_MAX_PERCENTAGE_VIBRATION
    damping_ratio_range: tuple[float, float] | None = None
    derivative_order: int = 0
    zero_residual_at_modes: bool = True  # a band keeps exactly zero residual at the nominal modes too

    @property
    def has_band(self) -> bool:
        return self.frequency_ratio_range is not None or self.frequency_range_hz is not None


@dataclass(frozen=True)
class TimeOptimalOptions:
    robustness: Robustness | None = None
    modes: tuple[int, ...] | None = None
    tradeoff: tuple[float, ...] | None = None
    max_duration_s: float | None = None
    # a command this short is enough (a synchronized program axis that another axis's longer move sets the pace
    # of): the shaped rigid optimum is the answer where it is no longer, with no search (not proven minimum-time)
    sufficient_duration_s: float | None = None


def zetas_of(robust: Robustness | None, mode: Mode) -> tuple[float, ...]:
    """The damping ratios a band holds for: the mode's, or a range's ends and middle."""
    if robust is None or robust.damping_ratio_range is None:
        return (mode.damping_ratio,)
    lo, hi = robust.damping_ratio_range
    return tuple(sorted({lo, 0.5 * (lo + hi), hi}))


def bands_of(problem: Problem, robust: Robustness | None, chosen: tuple[int, ...]) -> tuple[tuple[Band, ...], set[int]]:
    """The bands, and the chosen modes a band covers (exact zero there only if zero_residual_at_modes)."""
    if robust is None or not robust.has_band:
        return (), set()
    modes = problem.plant.modes()
    vmax = robust.max_percentage_vibration
    if robust.frequency_ratio_range is not None:
        lo, hi = robust.frequency_ratio_range
        bands = tuple(
            Band(
                lo * modes[i].natural_frequency_rad_s,
                hi * modes[i].natural_frequency_rad_s,
                zetas_of(robust, modes[i]),
                vmax,
            )
            for i in chosen
        )
        return bands, set(chosen)
    assert robust.frequency_range_hz is not None
    lo_w, hi_w = (2 * math.pi * f for f in robust.frequency_range_hz)
    centre = math.sqrt(lo_w * hi_w)
    nearest = min(chosen, key=lambda i: abs(math.log(modes[i].natural_frequency_rad_s / centre)))
    covered = {i for i in chosen if lo_w <= modes[i].natural_frequency_rad_s <= hi_w}
    band = Band(lo_w, hi_w, zetas_of(robust, modes[nearest]), vmax)
    return (band,), covered
