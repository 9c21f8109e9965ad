"""The answer as JSON: the pipeline's typed ``Result`` and blocks (optim.results) turned into the objects the API
documents. The only place the answer's shape is written; numpy arrays are left for the encoder (app.encoding).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from models.simulation import Response
from optim.results import MetricsReport
from optim.synthesis import Result


@functools.singledispatch
def present(value: Any) -> Any:
    """A block as its JSON object (fields in order; an ``omit_none`` field left out when None), recursively; a
    tuple as a list; anything else (numbers, strings, numpy arrays) as it is."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {
            f.name: present(getattr(value, f.name))
            for f in dataclasses.fields(value)
            if not (f.metadata.get("omit_none") and getattr(value, f.name) is None)
        }
    if isinstance(value, tuple | list):
        return [present(v) for v in value]
    if isinstance(value, Mapping):
        return {k: present(v) for k, v in value.items()}
    return value


@present.register
def load_json(response: Response) -> dict[str, NDArray[np.float64] | None]:
    """The ``load`` block: the simulated load (and the motor torque of a two-inertia plant)."""
    return {
        "time_s": response.time_s,
        "position": response.load_position,
        "velocity": response.load_velocity,
        "acceleration": response.load_acceleration,
        "deflection": response.deflection,
        "motor_torque_nm": response.motor_torque_nm,
    }


@present.register
def metrics_json(report: MetricsReport) -> dict[str, Any]:
    """The ``metrics`` block (docs/api.md: settling, residual, peaks, percentage vibration)."""
    m = report.metrics
    return {
        "command_end_s": m.command_end_s,
        "motion_time_s": m.command_end_s,
        "residual_amplitude": m.residual_amplitude,
        "residual_velocity_amplitude": m.residual_velocity_amplitude,
        "modes": [vars(mode) for mode in m.modes],
        "final_energy_j": m.final_energy_j,
        "settling_time_s": m.settling.time_s,
        "settled": m.settling.time_s is not None,
        "settling_quantity": m.settling.quantity,
        "settling_window": float(m.settling.window),
        "settling_vibration_window": m.settling.vibration_window,
        "peak_velocity": m.peak_velocity,
        "peak_acceleration": m.peak_acceleration,
        "peak_jerk": m.peak_jerk,
        "peak_motor_torque_nm": m.peak_motor_torque_nm,
        "percentage_vibration": report.percentage_vibration,
    }


def answer_body(result: Result) -> dict[str, Any]:
    """The answer of a family endpoint (JSON-ready apart from numpy arrays)."""
    extras = present(result.extras) if result.extras is not None else {}
    return {
        "profile": result.profile,
        "design": present(result.summary),
        "load": load_json(result.response),
        "metrics": metrics_json(result.metrics_report),
        "limits_met": not result.limit_violations,
        "sensitivity": present(result.sensitivity),
        "solver": present(result.solver),
        "limit_violations": list(result.limit_violations),
        "warnings": list(result.warnings),
        **extras,
    }
