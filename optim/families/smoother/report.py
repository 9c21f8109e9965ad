"""What the smoothers family says of a design: its ``design`` block (the chain's filters, the mode they are tuned to,
the closed-form residual and peaks, the discrete filters), completed after sampling with the sampling and the
simulated residuals (optim.results blocks)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from models.plants import Mode
from models.smoother_filters import FilterKind
from models.smoothers import Chain
from optim.families.smoother.smoothers import (
    ChainDesign,
    DiscreteDesign,
    cancels,
    same_time_ratio,
    vibration_free_durations_s,
)
from optim.results import Block


@dataclass(frozen=True)
class FilterReport(Block):
    """One filter of the chain, and what it does to the tuning mode on its own."""

    type: FilterKind
    duration_s: float
    decay_rate_1_s: float
    role: str  # limits, tuned or given
    vibration_free: bool | None
    percent_residual_vibration: float | None
    vibration_free_durations_s: tuple[float, ...]


@dataclass(frozen=True)
class ModeReport(Block):
    """The mode the filters are tuned to (the plant's first), every derived quantity by name."""

    natural_frequency_hz: float
    natural_frequency_rad_s: float
    damping_ratio: float
    damped_frequency_hz: float
    damped_frequency_rad_s: float
    natural_period_s: float
    damped_period_s: float
    decay_rate_1_s: float

    @classmethod
    def of(cls, mode: Mode) -> ModeReport:
        """The mode's derived quantities, named once (models.plant_base.Mode.as_dict)."""
        return cls(**mode.as_dict())


@dataclass(frozen=True)
class PredictedPeaks(Block):
    """|v|, |a|, |j| of the filtered step by the closed forms (None: impulsive)."""

    velocity: float | None
    acceleration: float | None
    jerk: float | None


@dataclass(frozen=True)
class DiscreteFilterReport(Block):
    """One eq. (17) filter: H(z) = gain * sum numerator[i] z^-i / sum denominator[i] z^-i."""

    type: FilterKind
    samples: int
    duration_s: float
    numerator: NDArray[np.float64]
    denominator: NDArray[np.float64]
    gain: float


@dataclass(frozen=True)
class DiscreteReport(Block):
    """The discrete filters at ``sample_period_s`` and what their output leaves."""

    sample_period_s: float
    filters: tuple[DiscreteFilterReport, ...]
    lead_s: float
    max_deviation: float
    percent_residual_vibration: float | None
    residual_amplitude: float
    residual_fraction_of_move: float
    exact_sample_period_s: float | None
    samples: int


@dataclass(frozen=True)
class SmootherReport(Block):
    """The ``design`` block."""

    filters: tuple[FilterReport, ...]
    total_duration_s: float
    duration_s: float
    continuous_derivatives: int
    mode: ModeReport | None
    vibration_free: bool | None
    percent_residual_vibration: float | None
    residual_amplitude_closed_form: float
    residual_fraction_of_move: float
    predicted_peaks: PredictedPeaks
    discrete: DiscreteReport | None
    # after sampling (optim.results.Finish)
    sample_period_s: float | None = None
    commensurate_sample_period_s: float | None = None
    hold_residual_fraction_of_move: float | None = None
    residual_vibration: float | None = None


def filter_reports(design: ChainDesign) -> tuple[FilterReport, ...]:
    out = []
    mode = design.mode
    for f, role in zip(design.chain.filters, design.roles, strict=True):
        prv = None
        if mode is not None:
            ratio = same_time_ratio(Chain((f,)), mode)
            prv = 100.0 * ratio if math.isfinite(ratio) else None
        out.append(
            FilterReport(
                type=f.kind,
                duration_s=f.duration_s,
                decay_rate_1_s=f.decay_rate_1_s,
                role=role,
                vibration_free=None if mode is None else cancels(f, mode),
                percent_residual_vibration=prv,
                vibration_free_durations_s=() if mode is None else tuple(vibration_free_durations_s(f.kind, mode)),
            )
        )
    return tuple(out)


def discrete_report(d: DiscreteDesign) -> DiscreteReport:
    return DiscreteReport(
        sample_period_s=d.sample_period_s,
        filters=tuple(
            DiscreteFilterReport(
                type=f.kind,
                samples=f.samples,
                duration_s=f.duration_s,
                numerator=f.numerator,
                denominator=f.denominator,
                gain=f.gain,
            )
            for f in d.filters
        ),
        lead_s=d.lead_s,
        max_deviation=d.max_deviation,
        percent_residual_vibration=d.percent_residual_vibration,
        residual_amplitude=d.residual_amplitude,
        residual_fraction_of_move=d.residual_fraction_of_move,
        exact_sample_period_s=d.exact_sample_period_s,
        samples=d.samples,
    )
