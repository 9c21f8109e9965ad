"""The input-shaped family's options: the shaper, the modes it is designed for, and the baseline it shapes."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from optim.families.input_shaped.shapers import DEFAULT_VIBRATION_TOLERANCE, BaselineChoice

MAX_SHAPED_MODES = 3
MAX_SHAPED_RAMPS = 1000  # impulses x baseline steps: bounds the limiter's corners and the step programme


@dataclass(frozen=True)
class InputShapedOptions:
    shaper: str = "zvd"
    vibration_tolerance: float = DEFAULT_VIBRATION_TOLERANCE
    shaped_modes: Literal["first", "all"] = "first"
    baseline: BaselineChoice = "auto"
    baseline_steps: int = 2
