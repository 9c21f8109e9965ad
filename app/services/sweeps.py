"""The sweeps use case: one family's design at every point of a grid of requests, and the table check between
neighbouring points (``optim.sweeps``).

The base request and the axes are checked before anything runs (a 422 naming ``request.<field>`` or
``axes[i].path``); each point's request is then validated by the family's schema, and a point that is invalid or
has no design is a row with the problem+json its endpoint would answer, not a failure of the sweep. The route
(app.routers.sweeps), the Python API and the CLI read its ``lines``.
"""

from __future__ import annotations

import contextlib
import copy
import logging
import re
import types
import typing
from collections.abc import AsyncIterator, Callable
from typing import Annotated, Any

import orjson
from pydantic import BaseModel, ValidationError

from app import problems
from app.presenters import present
from app.schemas.compare import DEFAULT_SENSITIVITY
from app.schemas.family import ProfileRequest
from app.schemas.registry import REQUEST_SCHEMAS
from app.schemas.sweeps import SweepIn
from app.services import profile as profiles
from app.settings import Settings
from models.errors import DomainError, InvalidParameter, NotApplicable
from optim import sweeps as engine
from optim.registry import FAMILIES
from runtime.dask import DaskExecutor
from runtime.executor import Executor
from runtime.pool import SolverPool

log = logging.getLogger(__name__)
_SEGMENT = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)(?:\[([0-9]+)\])?$")


# --- the plan: the base request, the axes' fields, each point's request ------------------------------


class SweepPlan:
    """A checked sweep: the family's schema, the base request (as sent) and the axes."""

    def __init__(self, body: SweepIn, settings: Settings) -> None:
        self.body = body
        self.settings = settings
        self.family = FAMILIES[body.family_key]
        self.schema: type[ProfileRequest] = REQUEST_SCHEMAS[body.family_key]
        self.base = dict(body.request)
        if self.base.get("sensitivity") is None:
            self.base["sensitivity"] = DEFAULT_SENSITIVITY.model_dump(exclude_none=True)
        try:
            model = self.schema.model_validate(self.base)
        except ValidationError as exc:
            raise problems.InvalidRequestBody(
                [{**e, "loc": ("body", "request", *e.get("loc", ()))} for e in exc.errors()]
            ) from None
        if body.points > settings.sweep_max_points:
            raise InvalidParameter(
                "axes",
                body.points,
                f"{body.points} points (the product of the axes' sizes) exceed the cap of {settings.sweep_max_points} "
                "(VIBFREE_SWEEP_MAX_POINTS)",
            )
        kinds = [_field_kind(model, a.path, i) for i, a in enumerate(body.axes)]
        self.axes = [
            engine.Axis(a.path, tuple(_typed(a.grid(), kind)), a.scale == "log", kind == "int")
            for a, kind in zip(body.axes, kinds, strict=True)
        ]

    def prepare(self, values: tuple[float, ...]) -> engine.Prepared:
        """A point's request validated by the family's schema, its problem and options (``profiles.design``'s
        steps, errors named as the caller sent the field)."""
        raw = copy.deepcopy(self.base)
        for axis, value in zip(self.axes, values, strict=True):
            _set(raw, axis.path, value)
        request = self.schema.model_validate(raw)  # a ValidationError is the point's invalid-input row
        try:
            problem = request.to_problem(self.settings)
            reason = self.family.not_applicable(problem)
            if reason is not None:
                raise NotApplicable(reason)
            options = request.options(problem)
        except DomainError as exc:
            raise profiles.as_sent(exc, request) from None
        return engine.Prepared(problem, options, request)


def _segments(path: str) -> list[tuple[str, int | None]]:
    out = []
    for part in path.split("."):
        match = _SEGMENT.match(part)
        assert match is not None  # the schema's pattern
        out.append((match[1], None if match[2] is None else int(match[2])))
    return out


def _field_kind(model: BaseModel, path: str, i: int) -> str:
    """ "int" or "float": the kind of the numeric field at ``path`` of the validated base request; else the 422
    naming axes[i].path."""
    field = f"axes[{i}].path"
    current: Any = model
    annotation: Any = None
    where = "the request"
    for name, index in _segments(path):
        if not isinstance(current, BaseModel):
            raise InvalidParameter(field, path, f"{where} is not an object (it has no field {name!r})")
        fields = type(current).model_fields
        if name not in fields:
            known = ", ".join(sorted(fields))
            raise InvalidParameter(field, path, f"{where} has no field {name!r} (its fields: {known})")
        current, annotation = current.__dict__.get(name), fields[name].annotation
        where = f"{where.removeprefix('the request')}.{name}".lstrip(".")
        if index is not None:
            if not isinstance(current, list) or index >= len(current):
                raise InvalidParameter(field, path, f"{where} has no item [{index}] in the base request")
            current, annotation = current[index], _item(annotation)
            where = f"{where}[{index}]"
    kind = _numeric(annotation)
    if kind is None or isinstance(current, bool):
        raise InvalidParameter(field, path, f"{where} is not a numeric field")
    return kind


def _strip(annotation: Any) -> set[Any]:
    """The types an annotation admits, None aside (Optional and Annotated unwrapped)."""
    if typing.get_origin(annotation) is Annotated:
        return _strip(typing.get_args(annotation)[0])
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        return set().union(*(_strip(a) for a in typing.get_args(annotation) if a is not type(None)))
    return {annotation}


def _numeric(annotation: Any) -> str | None:
    kinds = _strip(annotation)
    if kinds == {float}:
        return "float"
    if kinds == {int}:
        return "int"
    return None


def _item(annotation: Any) -> Any:
    for kind in _strip(annotation):
        if typing.get_origin(kind) is list:
            return typing.get_args(kind)[0]
    return None


def _typed(values: list[float], kind: str) -> list[float]:
    """An integer field's values as ints (a strict schema refuses 2.0 for an int); a range must land on them."""
    if kind != "int":
        return values
    return [int(v) if float(v).is_integer() else v for v in values]


def _set(raw: dict[str, Any], path: str, value: float) -> None:
    """Set a field of the raw request, making the objects on the way that the request left to their defaults."""
    segments = _segments(path)
    current: Any = raw
    for n, (name, index) in enumerate(segments):
        last = n == len(segments) - 1
        if index is None:
            if last:
                current[name] = value
                return
            if not isinstance(current.get(name), dict):
                current[name] = {}
            current = current[name]
        else:
            item = current[name]
            if last:
                item[index] = value
                return
            current = item[index]


# --- running it ------------------------------------------------------------------------------------


def describe(exc: Exception, request: Any) -> dict[str, Any]:
    """A point's failure as the problem+json its endpoint would answer (fields named as in its request)."""
    if isinstance(exc, ValidationError):
        response = problems.invalid_input(problems.validation_errors(exc.errors()), total=len(exc.errors()))
    elif isinstance(exc, DomainError):
        if isinstance(request, ProfileRequest):
            exc = profiles.as_sent(exc, request)
        response = problems.domain_problem(exc)
    else:
        log.error("sweep point failed unexpectedly", exc_info=exc)
        response = problems.problem_response("internal-error", "the point's design failed unexpectedly (logged)")
    answer: dict[str, Any] = orjson.loads(response.body)
    return answer


def capacity_of(executor: Executor) -> int:
    """Points in flight on the pool: one running and one queued per worker (the pipeline stays full and other
    requests keep room in the queue); one in-process."""
    if isinstance(executor, SolverPool):
        return executor.workers + min(executor.workers, executor.max_queued)
    return 1


def line_json(line: engine.Line, described: Callable[[Exception, Any], dict[str, Any]] | None = None) -> dict[str, Any]:
    """One NDJSON line: ``row`` (the point's numbers, or its failure as problem+json: ``describe``), ``check`` or
    ``summary``."""
    if isinstance(line, engine.PointDone):
        out: dict[str, Any] = {
            "line": "row",
            "index": line.index,
            "values": line.values,
            "between": present(line.between),
        }
        if line.row is not None:
            return out | {"ok": True, **present(line.row), "problem": None}
        assert line.error is not None
        return out | {"ok": False, "problem": (described or describe)(line.error, line.context)}
    return {"line": "check" if isinstance(line, engine.PairCheck) else "summary", **present(line)}


async def lines(plan: SweepPlan, executor: Executor, capacity: int | None = None) -> AsyncIterator[dict[str, Any]]:
    """The sweep's lines (the route's, the Python API's and the CLI's)."""
    body = plan.body
    async for line in engine.sweep(
        body.family_key,
        plan.axes,
        plan.prepare,
        executor,
        capacity=capacity or capacity_of(executor),
        deadline_s=plan.settings.solve_deadline_s,
        threshold_percent=body.threshold_percent,
        refine=body.refine,
        max_refined_points=body.max_refined_points,
        max_points=plan.settings.sweep_max_points,
    ):
        yield line_json(line)


@contextlib.asynccontextmanager
async def executor_for(
    scheduler: str | None, default: Executor, capacity: int | None
) -> AsyncIterator[tuple[Executor, int | None]]:
    """Where the points run and how many are in flight: the Dask cluster at ``scheduler`` (twice its threads),
    connected for the block, or ``default`` with ``capacity`` (None: ``capacity_of``)."""
    if scheduler:
        async with DaskExecutor.connect(scheduler) as dask:
            yield dask, 2 * await dask.capacity()
    else:
        yield default, capacity
