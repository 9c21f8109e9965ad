"""The design page at /, the printer page at /printer, the programs page at /programs, and their static files (no
build step, no CDN)."""

from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter
from fastapi.responses import FileResponse
from fastapi.staticfiles import StaticFiles

STATIC_DIR = Path(__file__).resolve().parent.parent / "static"
router = APIRouter(include_in_schema=False)
static = StaticFiles(directory=STATIC_DIR)


@router.get("/")
async def page() -> FileResponse:
    return FileResponse(STATIC_DIR / "index.html", media_type="text/html")


@router.get("/printer")
async def printer_page() -> FileResponse:
    """A printer's accelerometer file to its firmware's input shaper (POST /v1/identify with a target)."""
    return FileResponse(STATIC_DIR / "printer.html", media_type="text/html")


@router.get("/programs")
async def programs_page() -> FileResponse:
    """A machine program: its path in the plane, its axes against time, each stop's residual (POST /v1/programs)."""
    return FileResponse(STATIC_DIR / "programs.html", media_type="text/html")
