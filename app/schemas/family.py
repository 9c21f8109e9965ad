"""What every profile family's endpoint shares: limits, sampling, sensitivity and the response.

A family endpoint designs a command (optim), samples it exactly (models.commands), simulates the
plant (models.simulation) and answers with the same blocks: ``profile``, ``design``, ``load``,
``metrics`` and, when asked, ``sensitivity``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import Field, model_validator

from app.schemas.common import OutModel, StrictModel
from app.schemas.simulate import LoadOut, MetricsOut, ProfileOut, check_sample_count, load_out, metrics_out, profile_out
from models.commands import PiecewiseCommand
from models.plants import Plant
from models.sensitivity import band_below, sensitivity
from models.simulation import Metrics, metrics, simulate

MAX_SENSITIVITY_POINTS = 4001
MAX_SENSITIVITY_WORK = 20_000_000  # frequency points x damping ratios x breakpoints: about a second


class LimitsIn(StrictModel):
    """Bounds on the motor command along the whole motion (Ruckig's max_ names); all optional."""

    max_velocity: float | None = Field(None, gt=0, le=1e12, description="Largest |motor velocity| (rad/s or m/s).")
    max_acceleration: float | None = Field(None, gt=0, le=1e12, description="Largest |motor acceleration|.")
    max_jerk: float | None = Field(None, gt=0, le=1e15, description="Largest |motor jerk|.")
    max_torque_nm: float | None = Field(None, gt=0, le=1e12, description="Largest |motor torque| (two_inertia only).")


class SensitivityIn(StrictModel):
    """Where to evaluate the residual vibration versus the true/estimated frequency ratio."""

    frequency_ratios: list[float] | None = Field(
        None,
        min_length=1,
        max_length=MAX_SENSITIVITY_POINTS,
        description="Explicit ratios f_n/f_n,e (each in [0.01, 100]).",
    )
    min_ratio: float = Field(0.5, ge=0.01, le=100, description="Start of a uniform range of ratios (>= 0.01).")
    max_ratio: float = Field(1.5, ge=0.01, le=100, description="End of the range.")
    count: int = Field(201, ge=2, le=MAX_SENSITIVITY_POINTS, description="Points in the range.")
    damping_ratios: list[float] | None = Field(
        None,
        min_length=1,
        max_length=50,
        description="True damping ratios to evaluate (a grid with the ratios); default: the plant's own.",
    )

    @model_validator(mode="after")
    def _check(self) -> SensitivityIn:
        if self.max_ratio <= self.min_ratio:
            raise ValueError("max_ratio must be greater than min_ratio")
        if self.frequency_ratios is not None and any(not (0.01 <= r <= 100) for r in self.frequency_ratios):
            raise ValueError("every frequency ratio must lie in [0.01, 100]")
        if self.damping_ratios is not None and any(not (0 <= z < 1) for z in self.damping_ratios):
            raise ValueError("every damping ratio must satisfy 0 <= zeta < 1")
        if self.damping_ratios is not None and len(self.damping_ratios) * self.points > 20 * MAX_SENSITIVITY_POINTS:
            raise ValueError(f"at most {20 * MAX_SENSITIVITY_POINTS} (damping, frequency) points")
        return self

    @property
    def points(self) -> int:
        return len(self.frequency_ratios) if self.frequency_ratios is not None else self.count

    def ratios(self) -> np.ndarray:
        if self.frequency_ratios is not None:
            return np.asarray(self.frequency_ratios, dtype=float)
        return np.linspace(self.min_ratio, self.max_ratio, self.count)


class SensitivityOut(OutModel):
    frequency_ratio: list[float] = Field(description="f_n / f_n,e: true over estimated natural frequency.")
    residual_vibration: list[float] = Field(
        description="Residual amplitude as a fraction of the move (0.05 = 5 %), at the first damping ratio."
    )
    quantity: str = Field(
        description="position (rest-to-rest: / displacement) or velocity (rest-to-velocity: / final speed)."
    )
    damping_ratio: list[float] = Field(description="The true damping ratios evaluated.")
    residual_vibration_grid: list[list[float]] | None = Field(
        None, description="One residual curve per damping ratio, when several were asked."
    )
    band_5_percent: list[float | None] | None = Field(
        None,
        description="[low, high] ratios around 1 where the residual stays <= 5 % (first damping ratio); an end is "
        "null where the band runs past the evaluated ratios.",
    )


class FamilyResponse(OutModel):
    profile: ProfileOut
    design: dict[str, Any]
    load: LoadOut
    metrics: MetricsOut
    sensitivity: SensitivityOut | None = None
    warnings: list[str] = []


def sample_count_check(
    duration_s: float, sample_period_s: float, max_samples: int, field: str = "sample_period_s"
) -> None:
    """Refuse a sampling that would exceed the cap, before building anything."""
    count = int(duration_s / sample_period_s) + 1
    if count > max_samples:
        from models.errors import InvalidParameter

        raise InvalidParameter(
            field,
            sample_period_s,
            f"{count} samples over {duration_s:.6g} s exceed the cap of {max_samples}; use a period >= "
            f"{duration_s / (max_samples - 1):.3g} s",
        )


def sensitivity_out(command: PiecewiseCommand, plant: Plant, request: SensitivityIn) -> dict[str, Any]:
    """Residual versus frequency ratio around the plant's first mode."""
    modes = plant.modes()
    if not modes:
        from models.errors import InvalidParameter

        raise InvalidParameter("sensitivity", "requested", "the plant has no vibration mode to evaluate it around")
    mode = modes[0]
    zetas = request.damping_ratios or [mode.damping_ratio]
    work = request.points * len(zetas) * (command.end_index() + 1)
    if work > MAX_SENSITIVITY_WORK:
        from models.errors import InvalidParameter

        raise InvalidParameter(
            "sensitivity.count",
            request.points,
            f"{request.points} ratios x {len(zetas)} damping ratios x {command.end_index() + 1} breakpoints exceed "
            f"{MAX_SENSITIVITY_WORK:.0e}: ask fewer ratios or a longer sample_period_s",
        )
    result = sensitivity(command, mode.natural_frequency_rad_s, request.ratios(), np.asarray(zetas))
    band = band_below(result.frequency_ratio, result.residual[0], 0.05)
    return {
        "frequency_ratio": result.frequency_ratio,
        "residual_vibration": result.residual[0],
        "quantity": result.quantity,
        "damping_ratio": result.damping_ratio,
        "residual_vibration_grid": result.residual if len(zetas) > 1 else None,
        "band_5_percent": list(band) if band else None,
    }


def family_response(
    plant: Plant,
    command: PiecewiseCommand,
    design: dict[str, Any],
    *,
    sensitivity_request: SensitivityIn | None = None,
    settling_tolerance: float = 1e-3,
    warnings: list[str] | None = None,
) -> tuple[dict[str, Any], Metrics]:
    """The response body of a family endpoint, and the metrics (for limit checks and compare)."""
    response = simulate(plant, command)
    result = metrics(response, settling_tolerance)
    body = {
        "profile": profile_out(command),
        "design": design,
        "load": load_out(response),
        "metrics": metrics_out(result),
        "sensitivity": sensitivity_out(command, plant, sensitivity_request) if sensitivity_request else None,
        "warnings": warnings or [],
    }
    return body, result


__all__ = [
    "FamilyResponse",
    "LimitsIn",
    "SensitivityIn",
    "SensitivityOut",
    "check_sample_count",
    "family_response",
    "sample_count_check",
]
