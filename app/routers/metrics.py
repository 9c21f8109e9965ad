"""Prometheus metrics: requests, solves and the solver pools; with several HTTP processes, summed over them
(``app.service_metrics``: prometheus_client's multiprocess mode)."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import Response
from prometheus_client import generate_latest

# What generate_latest writes (prometheus_client's CONTENT_TYPE_LATEST is 1.0.0 in recent versions).
CONTENT_TYPE_PLAIN_0_0_4 = "text/plain; version=0.0.4; charset=utf-8"
router = APIRouter(tags=["health"])


@router.get(
    "/metrics",
    summary="Prometheus metrics: requests by route, solves by family, the solver pool's state",
    response_class=Response,
    responses={
        200: {
            "description": "The Prometheus text exposition format, version 0.0.4.",
            "content": {CONTENT_TYPE_PLAIN_0_0_4: {"schema": {"type": "string"}}},
        }
    },
)
async def metrics(request: Request) -> Response:
    return Response(generate_latest(request.app.state.metrics.scrape_registry()), media_type=CONTENT_TYPE_PLAIN_0_0_4)
