"""The FastAPI application: a thin factory that wires settings, routers, problems and the pool."""

from __future__ import annotations

import copy
import functools
import os
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from fastapi import FastAPI
from prometheus_client import multiprocess as prometheus_multiprocess
from pydantic import BaseModel

from app import body_middleware, json_logs, observability, problem_handlers, problems
from app.responses import FieldsOutput
from app.routers import (
    compare,
    docs,
    health,
    identify,
    metrics,
    page,
    plants,
    programs,
    pseudo_polynomial,
    shapers,
    simulate,
    smoothers,
    stap,
    sweeps,
    time_optimal,
)
from app.routers import (
    problems as problem_types,
)
from app.schemas.common import unschemed_rules
from app.settings import Settings, get_settings
from app.warmup import example_jobs, warm_up_worker
from runtime.dask import require_distributed
from runtime.pool import SolverPool
from runtime.threads import ThreadLane

DESCRIPTION = """
Designs motor commands for machines whose load hangs on something elastic (belts, compliant
shafts, springs, ropes), so that the load arrives, or comes up to speed, without ringing.

Conventions: SI units, with the unit in each field's name; motor positions in the plant's motor
coordinate (rad or m). The drive is assumed to execute the motor command exactly; the load follows
through the plant's transfer function. Every error is `application/problem+json` whose `type` is
documented under `/problems/{type}`.

Yardsticks, the same in every family: `settling_time_s` is the earliest time after which the load
stays within `settling.position_tolerance` of its target and its vibration envelope below
`settling.vibration_tolerance` for ever (null if an undamped mode is left ringing). The percentage
vibration `V` is the residual at the true frequency over the residual envelope of the unshaped rigid
command under the same limits (the step itself without an acceleration limit, so shapers on a step have
their textbook curves); `band_5_percent` is where `V <= 5 %` around ratio 1. Limits are hard: a design
that breaks one is a 422 `/problems/infeasible`, unless `allow_limit_violation` asks to see it.
"""


def create_app(settings: Settings | None = None) -> FastAPI:
    settings = settings or get_settings()
    json_logs.configure_logging()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        # Each HTTP process (uvicorn --workers) runs this: its own pool, warmed up on the documented examples
        # (app.warmup), its caches sized by the settings, its state written to the metrics' files.
        if settings.dask_scheduler:
            require_distributed()  # without Dask installed the server refuses to start, saying what to install
        warm_up = functools.partial(
            warm_up_worker, settings.solve_caps, settings.solver_cache_size, example_jobs(settings)
        )
        gauges = app.state.metrics.pool_gauges
        pool = SolverPool(
            settings.workers,
            settings.worker_start_timeout_s,
            warm_up=functools.partial(json_logs.start_worker, warm_up),
            max_queued=settings.queue_limit,
            niceness=settings.worker_niceness,
            memory_mb=settings.worker_memory_mb,
            on_change=gauges.update if gauges is not None else None,
        )
        app.state.pool = pool
        thread_gauges = app.state.metrics.thread_gauges
        threads = ThreadLane(
            settings.threads,
            settings.thread_queue_limit,
            on_change=thread_gauges.update if thread_gauges is not None else None,
        )
        app.state.threads = threads  # the closed-form designs and fits of this process (runtime.threads)
        pool.start_in_background()
        try:
            yield
        finally:
            threads.close()
            await pool.close()
            directory = app.state.metrics.multiprocess_dir
            if directory is not None:  # this process's live gauges leave the sums; its counters stay
                prometheus_multiprocess.mark_process_dead(os.getpid(), directory)  # type: ignore[no-untyped-call]

    app = FastAPI(
        title="Vibration-free motion profiles",
        version="0.1.0",
        description=DESCRIPTION,
        lifespan=lifespan,
        docs_url=None,  # /docs and /redoc come from app.routers.docs, on the vendored bundles
        redoc_url=None,
        generate_unique_id_function=lambda route: route.name,  # operation ids: stap_profile, compare, ...
    )
    app.state.settings = settings  # the routes' SettingsDep (app.deps.get_app_settings)
    observability.install(app)
    problem_handlers.install(app)
    app.add_middleware(body_middleware.BodySizeLimit, max_bytes=settings.max_body_bytes)
    routers = (
        health,
        plants,
        simulate,
        time_optimal,
        pseudo_polynomial,
        stap,
        smoothers,
        identify,
        shapers,
        compare,
        sweeps,
        programs,
        metrics,
        page,
        docs,
        problem_types,
    )
    for router in (r.router for r in routers):
        app.include_router(router)
    app.mount("/static", page.static, name="static")
    _declare_problem_schema(app)
    return app


def _declare_problem_schema(app: FastAPI) -> None:
    """Add the Problem schema to the OpenAPI components, and declare on every operation each problem
    status it can answer with (``problems.declared_statuses``), whatever the route itself lists."""
    original = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema:
            return app.openapi_schema
        schema = original()
        components = schema.setdefault("components", {}).setdefault("schemas", {})
        components["Problem"] = problems.ProblemDetails.model_json_schema(ref_template="#/components/schemas/{model}")
        components.update(components["Problem"].pop("$defs", {}))
        # FastAPI documents its own 422 (HTTPValidationError); ours is a problem.
        for path in schema.get("paths", {}).values():
            for operation in path.values():
                for status, response in operation.get("responses", {}).items():
                    content = response.get("content", {})
                    if status == "422" and "application/json" in content and "HTTPValidationError" in str(content):
                        response["content"] = {
                            problems.PROBLEM_MEDIA_TYPE: {"schema": {"$ref": "#/components/schemas/Problem"}}
                        }
        for name in ("HTTPValidationError", "ValidationError"):
            components.pop(name, None)
        for path_format, route in problems.api_routes(app):
            for method in route.methods or ():
                operation = schema.get("paths", {}).get(path_format, {}).get(method.lower())
                if operation is None:
                    continue
                declared = operation.setdefault("responses", {})
                for status, response in problems.responses(*problems.declared_statuses(route)).items():
                    declared.setdefault(str(status), response)
                _declare_rules(operation, route, components)
        app.openapi_schema = schema
        return schema

    app.openapi = openapi  # type: ignore[method-assign]


def _declare_rules(operation: dict[str, Any], route: Any, components: dict[str, Any]) -> None:
    """The route's own query schemas (``fields=`` lists its answer's paths) and its JSON answer with ``fields=``
    (a part of it), and, in its description, every rule validation checks that the schema does not state (value
    comparisons, physics): so that a request the schema allows is refused only for a rule written here
    (``app.schemas.common.unschemed_rules``)."""
    rules: list[str] = []
    body = route.body_field.field_info.annotation if route.body_field is not None else None
    if isinstance(body, type) and issubclass(body, BaseModel):
        rules += unschemed_rules(body)
    stack = list(route.dependant.dependencies)
    while stack:
        dependency = stack.pop()
        stack.extend(dependency.dependencies)
        if isinstance(dependency.call, FieldsOutput):
            rules += dependency.call.UNSCHEMED_RULES
            extra = dependency.call.query_schemas()
            for parameter in operation.get("parameters", []):
                if parameter.get("in") == "query" and parameter.get("name") in extra:
                    parameter["schema"] = {**parameter.get("schema", {}), **extra[parameter["name"]]}
            content = operation.get("responses", {}).get("200", {}).get("content", {}).get("application/json", {})
            whole = content.get("schema", {}).get("$ref", "")
            if whole.startswith(COMPONENTS):
                part = COMPONENTS + _selected(components, whole.removeprefix(COMPONENTS))
                content["schema"] = {"anyOf": [{"$ref": whole}, {"$ref": part}]}
    if rules:
        listed = "\n".join(f"- {rule}" for rule in dict.fromkeys(rules))
        operation["description"] = (
            operation.get("description", "").rstrip()
            + "\n\n**Rules the schema does not state** (each a 422 `invalid-input` naming the field):\n\n"
            + listed
        ).lstrip()


COMPONENTS = "#/components/schemas/"


def _selected(components: dict[str, Any], name: str, depth: int = 2) -> str:
    """The component ``name`` with no member required, and so its blocks down ``depth`` levels (added once as
    ``<name>Selected``): the schema of an answer that ``fields=`` cut down to some blocks, or to some keys of a
    block (``responses.field_paths``)."""
    selected = f"{name}Selected"
    if selected in components:
        return selected
    schema = copy.deepcopy(components[name])
    components[selected] = schema
    schema.pop("required", None)
    schema["title"] = f"{schema.get('title', name)} (the parts fields= names)"
    stack: list[Any] = list(schema.get("properties", {}).values()) if depth > 1 else []
    while stack:
        node = stack.pop()
        if isinstance(node, dict):
            ref = node.get("$ref")
            if isinstance(ref, str) and ref.startswith(COMPONENTS):
                node["$ref"] = COMPONENTS + _selected(components, ref.removeprefix(COMPONENTS), depth - 1)
            stack.extend(value for key, value in node.items() if key != "$ref")
        elif isinstance(node, list):
            stack.extend(node)
    return selected


app = create_app()
