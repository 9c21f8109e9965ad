"""Placeholder: the smoothers family's endpoints are added by its issue."""

from __future__ import annotations

from fastapi import APIRouter

router = APIRouter(prefix="/v1", tags=["smoothers"])
