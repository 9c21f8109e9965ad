"""Shared pieces of the request and response schemas."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class StrictModel(BaseModel):
    """Request models: unknown fields, NaN and infinities are refused with a 422."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class OutModel(BaseModel):
    """Response models (used for the OpenAPI schema)."""

    model_config = ConfigDict(extra="forbid")
