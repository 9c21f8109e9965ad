"""What the input-shaped family says of a design: its ``design`` block (shaper, baseline, drive, firmware) and its
own top-level blocks (the rate-limited and baseline commands, the impulses, the unmodified command's metrics)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from models.shapers import percentage_vibration
from optim.families.input_shaped.firmware_blocks import FirmwareReport
from optim.families.input_shaped.shapers import ShaperDesign
from optim.family import Profile
from optim.results import Block, MetricsReport


@dataclass(frozen=True)
class ShapedMode(Block):
    natural_frequency_hz: float
    natural_frequency_rad_s: float
    damping_ratio: float


@dataclass(frozen=True)
class ShaperReport(Block):
    """The shaper: its impulses' count and span, the modes it is designed for and the V it leaves at each."""

    name: str
    impulse_count: int
    duration_s: float
    duration_periods: float
    vibration_tolerance: float | None
    modes: tuple[ShapedMode, ...]
    residual_at_modes: tuple[float, ...]
    method: str
    reference: str
    conditions_residual: float | None


@dataclass(frozen=True)
class BaselineAlternative(Block):
    """One baseline the automatic choice tried: its shaped end and the residual it leaves at the first mode."""

    kind: str
    steps: int
    ramp_time_s: float
    end_s: float
    nominal_residual: float


@dataclass(frozen=True)
class BaselineReport(Block):
    """The unshaped command the shaper is applied to (Sec. 4 of Chatlatanagulchai and Pongpanich), and why."""

    kind: str
    requested: str
    choice: str
    alternatives: tuple[BaselineAlternative, ...]
    cruise_choice: str | None
    move: str
    velocity: float
    cruise_time_s: float | None
    step_times_s: NDArray[np.float64]
    step_heights: NDArray[np.float64]
    ramp_time_s: float
    method: str


@dataclass(frozen=True)
class InputShapedReport(Block):
    """The ``design`` block."""

    shaper: ShaperReport
    baseline: BaselineReport
    acceleration_limit: float | None
    drive: str
    shaped_peak_acceleration: float | None
    passes_limiter_unchanged: bool
    duration_s: float
    firmware: FirmwareReport


@dataclass(frozen=True)
class ImpulsesReport(Block):
    amplitudes: NDArray[np.floating[Any]]
    times_s: NDArray[np.floating[Any]]


@dataclass(frozen=True)
class InputShapedExtras(Block):
    """The family's top-level blocks: the command the drive's limiter makes, the baseline, the impulses, and the
    metrics of the unshaped baseline through the same limiter (``unmodified``)."""

    rate_limited: Profile
    baseline: Profile
    impulses: ImpulsesReport
    ramp_time_s: float | None
    unmodified: MetricsReport


def shaper_report(design: ShaperDesign) -> ShaperReport:
    impulses = design.impulses
    return ShaperReport(
        name=design.name,
        impulse_count=impulses.count,
        duration_s=impulses.duration_s,
        duration_periods=design.duration_periods,
        vibration_tolerance=design.vibration_tolerance,
        modes=tuple(
            ShapedMode(m.natural_frequency_hz, m.natural_frequency_rad_s, m.damping_ratio) for m in design.modes
        ),
        residual_at_modes=tuple(
            float(percentage_vibration(impulses, m.natural_frequency_rad_s, m.damping_ratio)) for m in design.modes
        ),
        method=design.method,
        reference=design.reference,
        conditions_residual=design.conditions_residual,
    )
