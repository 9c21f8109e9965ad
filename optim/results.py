"""The typed pieces of a design's answer: blocks the app presents as JSON (app.presenters), never dicts.

A ``Block`` is a frozen dataclass whose fields, in their order, are the keys of one JSON object; a field whose
metadata says ``OMIT_NONE`` is left out of it when None (a block the request did not ask for). Arrays stay
numpy arrays; the app's encoder writes them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from models.metrics import Metrics

OMIT_NONE = {"omit_none": True}


def omitted_when_none() -> Any:
    """A field (default None) that the answer leaves out when it is None."""
    return field(default=None, metadata=OMIT_NONE)


@dataclass(frozen=True)
class Block:
    """Base of every answer block (a frozen dataclass: its fields are the JSON object's keys, in order)."""


@dataclass(frozen=True)
class MetricsReport(Block):
    """The ``metrics`` block of one simulated command: the metrics and V at the nominal first mode (%)."""

    metrics: Metrics
    percentage_vibration: float | None = None


@dataclass(frozen=True)
class SensitivityCurve(Block):
    """Percentage vibration versus f_n / f_n,e around the plant's first mode (optim.synthesis.sensitivity_curve):
    one row per damping ratio, the 5 % band of the first row, and the reference the percentages are of."""

    frequency_ratio: NDArray[np.float64]
    percentage_vibration: NDArray[np.float64]
    reference_amplitude: NDArray[np.float64]
    reference: str
    residual_amplitude: NDArray[np.float64]
    residual_vibration: NDArray[np.float64]
    quantity: str
    damping_ratio: NDArray[np.float64]
    percentage_vibration_grid: NDArray[np.float64] | None
    residual_vibration_grid: NDArray[np.float64] | None
    band_5_percent: tuple[float | None, float | None] | None
    method: tuple[str, ...] | None = omitted_when_none()  # per damping ratio, where a family has a closed form


@dataclass(frozen=True)
class Finish:
    """What a family adds once its command is sampled and simulated: its design block completed (None: as
    designed), its own top-level blocks (the fields of ``extras``) and warnings."""

    design: Block | None = None
    extras: Block | None = None
    warnings: tuple[str, ...] = ()
