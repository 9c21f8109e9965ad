"""Shared pieces of the request and response schemas."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

# Bounds of the numbers in request arrays: far beyond any machine, so they only refuse nonsense, and
# small enough that sums, squares and differences of samples stay finite in double precision.
SAMPLE_VALUE_MAX = 1e12
SAMPLE_TIME_MAX_S = 1e6
TOLERANCE_MIN = 1e-12  # a relative tolerance below double precision's resolution means nothing

SampleValue = Annotated[float, Field(ge=-SAMPLE_VALUE_MAX, le=SAMPLE_VALUE_MAX)]
SampleTime = Annotated[float, Field(ge=-SAMPLE_TIME_MAX_S, le=SAMPLE_TIME_MAX_S)]
DampingRatio = Annotated[float, Field(ge=0, lt=1)]


class StrictModel(BaseModel):
    """Request models: unknown fields, NaN and infinities are refused with a 422, and so are values of the
    wrong JSON type (true for a number, "1" for a number): strict validation, which still takes an
    integer for a number."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)


class OutModel(BaseModel):
    """Response models (used for the OpenAPI schema)."""

    model_config = ConfigDict(extra="forbid")
