"""GET /problems/{slug}: what a problem type means (every problem's ``type`` URI resolves here, RFC 9457)."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter

from app.problems import PROBLEM_TYPE_PATH, PROBLEM_TYPES, ProblemError

router = APIRouter(tags=["problems"])


@router.get(PROBLEM_TYPE_PATH, summary="What a problem type means")
async def problem_type(slug: str) -> dict[str, Any]:
    if slug not in PROBLEM_TYPES:
        raise ProblemError("not-found", f"no problem type {slug!r}; known: {', '.join(PROBLEM_TYPES)}")
    status, title, meaning = PROBLEM_TYPES[slug]
    return {"type": f"/problems/{slug}", "title": title, "status": status, "description": meaning}
