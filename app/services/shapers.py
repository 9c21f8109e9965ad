"""The shaper catalogue use case: every shaper designed for a unit mode, with its computed 5 % band."""

from __future__ import annotations

from typing import Any

from optim.families.input_shaped.shapers import catalogue

BAND_THRESHOLD = 0.05  # the band of a shaper: where its percentage vibration V stays <= 5 %


def _width(band: tuple[float | None, float | None] | None) -> float | None:
    """high - low of a band closed at both ends."""
    if band is None or band[0] is None or band[1] is None:
        return None
    return band[1] - band[0]


def catalogue_answer(damping_ratio: float, vibration_tolerance: float) -> dict[str, Any]:
    """The answer of GET /v1/shapers: each shaper's impulses and band, and the EI shapers that do not exist at
    this damping and tolerance."""
    entries, missing = catalogue(damping_ratio, vibration_tolerance, BAND_THRESHOLD)
    shapers = [
        {
            "name": e.name,
            "impulse_count": e.impulse_count,
            "duration_periods": e.duration_periods,
            "band_5_percent": list(e.band) if e.band else None,
            "band_width": _width(e.band),
            "amplitudes": list(e.amplitudes),
            "times_periods": list(e.times_periods),
            "method": e.method,
            "reference": e.reference,
        }
        for e in entries
    ]
    return {
        "damping_ratio": damping_ratio,
        "vibration_tolerance": vibration_tolerance,
        "band_threshold": BAND_THRESHOLD,
        "shapers": shapers,
        "unavailable": [{"name": name, "reason": reason} for name, reason in missing],
    }
