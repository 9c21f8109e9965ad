"""The answers of the routes with sampled arrays: JSON with numpy arrays (orjson, no Python loop over samples), the
``fields=`` selection, numpy's own ``.npz`` format and the profile routes' CSV tables."""

from __future__ import annotations

import io
import re
import types
import typing
from collections.abc import Iterable
from dataclasses import dataclass
from importlib.metadata import version
from typing import Annotated, Any, Literal

import numpy as np
import orjson
from fastapi import Depends, Query, Request
from pydantic import BaseModel
from starlette.concurrency import run_in_threadpool
from starlette.responses import Response

from app.encoding import dumps
from app.schemas.family import ProfileRequest
from models.errors import InvalidParameter
from optim import tables
from optim.synthesis import Result

__version__ = version("vibfree")


class NumpyJSONResponse(Response):
    """``application/json`` rendered by orjson; numpy arrays are written natively.

    Routes declare their ``response_model`` for the OpenAPI schema and return this response
    directly, which skips a second validation of arrays of up to the sample cap.
    """

    media_type = "application/json"

    def render(self, content: Any) -> bytes:
        return dumps(content)


CSV_MEDIA_TYPE = "text/csv"
COLUMNS_DESCRIPTION = (
    "CSV columns, comma-separated, time_s always first: any of " + ", ".join(tables.COLUMNS) + " (load_* and "
    "deflection from the simulated load; motor_torque_nm on two_inertia plants), or `all` (every column this plant "
    "defines). Default: " + ",".join(tables.PROFILE_COLUMNS) + "."
)


def _names(names: Iterable[str]) -> str:
    return "(?:" + "|".join(re.escape(n) for n in names) + ")"


def list_pattern(names: Iterable[str], *, at_least_one: bool) -> str:
    r"""A comma-separated list of ``names`` as it is parsed here, unanchored: each item stripped of white space
    (``str.strip``, which strips what Python's ``\s`` matches), empty items skipped; ``at_least_one``: at least
    one name."""
    name = _names(names)
    first = rf"(?:\s*,)*\s*{name}" if at_least_one else rf"\s*{name}?"
    return rf"{first}\s*(?:,\s*{name}?\s*)*"


# columns=: any of the table's columns, or all alone (tables.check_columns). Two patterns, not one alternation:
# hypothesis (schemathesis) never finishes drawing a string from their alternation.
COLUMNS_MAX_CHARS = 400
COLUMNS_PATTERNS = ("^" + list_pattern(tables.COLUMNS, at_least_one=False) + "$", r"^(?:\s*,)*\s*all\s*(?:,\s*)*$")
COLUMNS_SCHEMA = {
    "anyOf": [
        *({"type": "string", "maxLength": COLUMNS_MAX_CHARS, "pattern": pattern} for pattern in COLUMNS_PATTERNS),
        {"type": "null"},
    ]
}


NPZ_MEDIA_TYPE = "application/x-npz"
NPZ_JSON_ENTRY = "json"  # the .npz entry with the rest of the answer, as UTF-8 JSON bytes
# Arrays that repeat another array of the same answer: left out unless asked for by ``fields=`` (deprecated
# aliases). ``load.time_s`` is the time grid of the command the load was simulated with, which the answer also
# carries as the first of these blocks that holds the same array.
DUPLICATES: dict[str, tuple[str, ...]] = {"load.time_s": ("rate_limited.time_s", "profile.time_s")}
FIELDS_DESCRIPTION = (
    "Comma-separated dotted paths of what the answer holds, e.g. `profile,load.position,metrics`: a block (all of "
    "it) or one key within it; everything else is left out (JSON and npz; the CSV table takes `columns=`). Default: "
    "the whole answer, without `load.time_s` (deprecated: it repeats `profile.time_s`; `fields=load.time_s` "
    "returns it). An unknown path is a 422 naming `fields` that lists the allowed ones."
)
FORMAT_DESCRIPTION = (
    "csv: the profile as a CSV table; npz: numpy's .npz (as `Accept: application/x-npz`), one array per dotted "
    "path, the rest of the answer as JSON in the `json` entry"
)


def _prefers(request: Any, media_type: str) -> bool:
    """An Accept header that names ``media_type`` before application/json."""
    accept = request.headers.get("accept", "")
    return media_type in accept and "application/json" not in accept.split(media_type)[0]


def wants_csv(request: Any) -> bool:
    """``?format=csv`` or an Accept header that prefers text/csv to JSON."""
    if request.query_params.get("format", "").lower() == "csv":
        return True
    return _prefers(request, CSV_MEDIA_TYPE)


def wants_npz(request: Any) -> bool:
    """``?format=npz`` or an Accept header that prefers application/x-npz to JSON."""
    chosen = request.query_params.get("format", "").lower()
    return chosen == "npz" or (not chosen and _prefers(request, NPZ_MEDIA_TYPE))


def _model_in(annotation: Any) -> type[BaseModel] | None:
    """The response model an annotation holds (``Model``, ``Model | None``), else None (lists are leaves)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        models = [m for m in map(_model_in, typing.get_args(annotation)) if m is not None]
        return models[0] if len(models) == 1 else None
    return None


def field_paths(model: type[BaseModel]) -> tuple[str, ...]:
    """The dotted paths of a response model that ``fields=`` may name: its blocks, and the keys within them."""
    out: list[str] = []
    for name, info in model.model_fields.items():
        out.append(name)
        inner = _model_in(info.annotation)
        if inner is not None:
            out.extend(f"{name}.{key}" for key in inner.model_fields)
    return tuple(out)


def parse_fields(text: str, allowed: Iterable[str]) -> tuple[str, ...]:
    """The dotted paths of ``fields=``, checked against the route's own: a 422 naming ``fields`` otherwise, whose
    rule lists the blocks (and the keys of a block when the unknown path is within one)."""
    known = tuple(allowed)
    names = tuple(dict.fromkeys(n.strip() for n in text.split(",") if n.strip()))
    unknown = [n for n in names if n not in known]
    if names and not unknown:
        return names
    blocks = [n for n in known if "." not in n]
    rule = "comma-separated dotted paths of the answer, each a block or one key within it"
    if not names:
        rule += f", none given; the blocks are {', '.join(blocks)}"
        raise InvalidParameter("fields", text, rule)
    first = unknown[0]
    head = first.split(".", 1)[0]
    keys = [n.split(".", 1)[1] for n in known if n.startswith(head + ".")]
    rule += f"; unknown: {', '.join(unknown)}; the blocks are {', '.join(blocks)}"
    if keys:
        rule += f"; the keys within {head} are {', '.join(keys)}"
    elif head in blocks:
        rule += f"; {head} has no keys to choose from"
    raise InvalidParameter("fields", text, rule)


@dataclass(frozen=True)
class Output:
    """What a route answers with: JSON, npz or the CSV table with these columns (and comment lines), holding the
    ``fields`` (None: the whole answer, without the duplicated arrays)."""

    csv: bool
    columns: tuple[str, ...] | None  # None: the default (profile) columns; ('all',): every column
    comments: bool
    npz: bool = False
    fields: tuple[str, ...] | None = None


class FieldsOutput:
    """An output dependency with ``fields=``, checked against the route's response model (``parse_fields``)."""

    UNSCHEMED_RULES: tuple[str, ...] = ()

    def __init__(self, model: type[BaseModel]) -> None:
        self.allowed = field_paths(model)

    def query_schemas(self) -> dict[str, dict[str, Any]]:
        """What the OpenAPI adds to a query parameter's schema for this route (its own ``fields=`` paths: the
        dependency's Query is shared by every route)."""
        return {"fields": {"pattern": "^" + list_pattern(self.allowed, at_least_one=True) + "$"}}


class ProfileOutput(FieldsOutput):
    """The output options of a profile route (``format``, ``columns``, ``comments``, ``fields``), from the query
    and the Accept header; ``fields`` checked against the route's response model before anything is designed."""

    UNSCHEMED_RULES = (
        "fields= selects what the JSON or npz answer holds: not with the CSV table (format=csv, or an Accept "
        "header that prefers text/csv), whose columns columns= chooses.",
    )

    async def __call__(
        self,
        request: Request,
        format: Annotated[Literal["json", "csv", "npz"] | None, Query(description=FORMAT_DESCRIPTION)] = None,
        columns: Annotated[
            str | None,
            Query(max_length=COLUMNS_MAX_CHARS, description=COLUMNS_DESCRIPTION, json_schema_extra=COLUMNS_SCHEMA),
        ] = None,
        comments: Annotated[
            bool,
            Query(
                description="CSV: add `#` comment lines (units, plant, family, design, sample period) before the "
                "header."
            ),
        ] = False,
        fields: Annotated[str | None, Query(max_length=1000, description=FIELDS_DESCRIPTION)] = None,
    ) -> Output:
        names: tuple[str, ...] | None = None
        if columns is not None:
            names = tuple(c.strip() for c in columns.split(",") if c.strip())
            tables.check_columns(names)  # 422 on columns before anything is designed
        csv = wants_csv(request)
        chosen = parse_fields(fields, self.allowed) if fields is not None else None
        if csv and chosen is not None:
            raise InvalidParameter(
                "fields", fields, "selects what the JSON or npz answer holds; the CSV table takes columns="
            )
        return Output(csv=csv, columns=names, comments=comments, npz=not csv and wants_npz(request), fields=chosen)


class ArrayOutput(FieldsOutput):
    """The output options of a route with sampled arrays and no CSV table (/v1/simulate): ``format`` (json or
    npz, or the Accept header) and ``fields``."""

    async def __call__(
        self,
        request: Request,
        format: Annotated[
            Literal["json", "npz"] | None,
            Query(
                description="npz: numpy's .npz (as `Accept: application/x-npz`), one array per dotted path, the "
                "rest of the answer as JSON in the `json` entry"
            ),
        ] = None,
        fields: Annotated[str | None, Query(max_length=1000, description=FIELDS_DESCRIPTION)] = None,
    ) -> Output:
        chosen = parse_fields(fields, self.allowed) if fields is not None else None
        return Output(csv=False, columns=None, comments=False, npz=wants_npz(request), fields=chosen)


def profile_output(model: type[BaseModel]) -> Any:
    """The ``Output`` dependency of a profile route answering with ``model``."""
    return Annotated[Output, Depends(ProfileOutput(model))]


def array_output(model: type[BaseModel]) -> Any:
    """The ``Output`` dependency of a route with arrays and no CSV answering with ``model``."""
    return Annotated[Output, Depends(ArrayOutput(model))]


def _lookup(answer: dict[str, Any], path: str) -> Any:
    value: Any = answer
    for key in path.split("."):
        if not isinstance(value, dict) or key not in value:
            return None
        value = value[key]
    return value


def _same_array(a: Any, b: Any) -> bool:
    if a is b:
        return True
    if isinstance(a, np.ndarray) and isinstance(b, np.ndarray):
        return a.shape == b.shape and bool(np.array_equal(a, b))
    return False


def _without(block: dict[str, Any], path: tuple[str, ...]) -> dict[str, Any]:
    """``block`` with the key at ``path`` left out (new dicts on the way, the rest shared)."""
    head, *rest = path
    if head not in block:
        return block
    if not rest:
        return {k: v for k, v in block.items() if k != head}
    inner = block[head]
    return {**block, head: _without(inner, tuple(rest))} if isinstance(inner, dict) else block


def drop_duplicates(answer: dict[str, Any], keep: Iterable[str] = ()) -> dict[str, Any]:
    """The answer without the arrays that repeat another of its arrays (``DUPLICATES``), at the top and one block
    down (``initial.load.time_s`` beside ``initial.profile.time_s``), except the paths in ``keep``."""
    kept = set(keep)
    out = answer
    prefixes = [""] + [f"{k}." for k, v in answer.items() if isinstance(v, dict)]
    for prefix in prefixes:
        for path, originals in DUPLICATES.items():
            full = prefix + path
            value = _lookup(answer, full)
            if value is None or full in kept:
                continue
            if any(_same_array(value, _lookup(answer, prefix + o)) for o in originals):
                out = _without(out, tuple(full.split(".")))
    return out


def select(answer: dict[str, Any], fields: tuple[str, ...]) -> dict[str, Any]:
    """The parts of the answer that ``fields`` names, in the answer's order (a block whole, or keys within it)."""
    tree: dict[str, Any] = {}
    for path in fields:
        node = tree
        *heads, last = path.split(".")
        for key in heads:
            child = node.setdefault(key, {})
            if child is True:
                break
            node = child
        else:
            node[last] = True

    def pick(value: dict[str, Any], wanted: dict[str, Any]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for key, item in value.items():
            if key not in wanted:
                continue
            sub = wanted[key]
            out[key] = item if sub is True or not isinstance(item, dict) else pick(item, sub)
        return out

    return pick(answer, tree)


def shape(answer: dict[str, Any], fields: tuple[str, ...] | None) -> dict[str, Any]:
    """What the client asked for: the answer without its duplicated arrays, then the ``fields`` it names."""
    trimmed = drop_duplicates(answer, keep=fields or ())
    return trimmed if fields is None else select(trimmed, fields)


def split_arrays(answer: dict[str, Any], prefix: str = "") -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """The numpy arrays of an answer by dotted path (in dicts, at any depth), and the rest of it."""
    arrays: dict[str, np.ndarray] = {}
    rest: dict[str, Any] = {}
    for key, value in answer.items():
        path = prefix + key
        if isinstance(value, np.ndarray):
            arrays[path] = value
        elif isinstance(value, dict):
            inner, left = split_arrays(value, path + ".")
            arrays.update(inner)
            if left or not inner:
                rest[key] = left
        else:
            rest[key] = value
    return arrays, rest


def npz_body(answer: dict[str, Any]) -> bytes:
    """numpy's .npz of an answer (``np.savez``, uncompressed): one array per dotted path, and the rest of the
    answer as UTF-8 JSON bytes in the ``json`` entry; no object arrays, so ``np.load`` needs no pickle
    (https://numpy.org/doc/stable/reference/generated/numpy.savez.html)."""
    arrays, rest = split_arrays(answer)
    buffer = io.BytesIO()
    entries: dict[str, Any] = {**arrays, NPZ_JSON_ENTRY: np.frombuffer(dumps(rest), dtype=np.uint8)}
    np.savez(buffer, **entries)
    return buffer.getvalue()


RENDER_IN_THREAD_SAMPLES = 10_000  # a larger answer is written in a thread (a 1k-sample one costs less than a hop)


def render(output: Output, answer: dict[str, Any]) -> Response:
    """The answer as JSON (default) or npz, holding what ``output.fields`` selects."""
    shaped = shape(answer, output.fields)
    if output.npz:
        return Response(
            npz_body(shaped),
            media_type=NPZ_MEDIA_TYPE,
            headers={"content-disposition": 'attachment; filename="answer.npz"'},
        )
    return NumpyJSONResponse(shaped)


def csv_body(table: tables.Table, comment_lines: list[str]) -> bytes:
    """The header row, then one row per instant (``csv_rows``: no Python loop over samples). Comment lines go
    first, when any."""
    head = "".join(f"# {line}\n" for line in comment_lines) + ",".join(table.columns) + "\n"
    return head.encode() + csv_rows(table.values)


def csv_rows(values: np.ndarray) -> bytes:
    """Rows of a 2-D array as CSV lines: orjson writes the flat array (shortest round-trip floats; twice as fast
    as its nested form), then every n-th comma becomes a line break, found by numpy."""
    rows, columns = values.shape
    text = bytearray(orjson.dumps(np.ascontiguousarray(values).ravel(), option=orjson.OPT_SERIALIZE_NUMPY)[1:-1])
    chars = np.frombuffer(text, dtype=np.uint8)
    if columns > 1:
        commas = np.flatnonzero(chars == ord(","))
        chars[commas[columns - 1 :: columns]] = ord("\n")
    return bytes(text) + b"\n" if rows else b""


def comment_lines(title: str, body: ProfileRequest, answer: dict[str, Any], table: tables.Table) -> list[str]:
    """Units and metadata, one per line: what the table is, for whom and how it was sampled."""
    request = body.common_body()
    move = {k: request[k] for k in ("displacement", "target_velocity", "limits") if k in request}
    design = {k: v for k, v in answer["design"].items() if not isinstance(v, np.ndarray)}
    return [
        f"{title}; vibfree {__version__}",
        f"plant: {dumps(request['plant']).decode()}",
        f"move: {dumps(move).decode()}",
        f"design: {dumps(design).decode()}",
        f"sample_period_s: {table.period_s!r}; rows: {table.values.shape[0]}; time_s = k * sample_period_s exactly",
        "units: " + "; ".join(f"{c} in {tables.UNITS[c]}" for c in table.columns),
    ]


async def respond(output: Output, answer: dict[str, Any], result: Result, body: ProfileRequest, title: str) -> Response:
    """JSON by default (or npz, ``render``); the CSV table on the uniform grid when the client asks for it."""
    if not output.csv:
        if result.command.time_s.size > RENDER_IN_THREAD_SAMPLES:  # orjson holds the GIL, not the event loop
            return await run_in_threadpool(render, output, answer)
        return render(output, answer)
    table = await run_in_threadpool(tables.table, result, output.columns or tables.PROFILE_COLUMNS)
    lines = comment_lines(title, body, answer, table) if output.comments else []
    return Response(
        csv_body(table, lines),
        media_type=CSV_MEDIA_TYPE,
        headers={"content-disposition": 'attachment; filename="profile.csv"'},
    )


NPZ_DESCRIPTION = (
    "With `?format=npz` / `Accept: application/x-npz`: numpy's .npz (np.savez, uncompressed), one float64 array per "
    "dotted path of the answer (`profile.position`, `load.velocity`, ...) and the rest of the answer as UTF-8 JSON "
    "in the `json` entry (`fields=` applies). Read it without pickle: "
    "`z = np.load(io.BytesIO(r.content)); z['profile.position']; json.loads(z['json'].tobytes())`."
)
NPZ_CONTENT: dict[str, Any] = {NPZ_MEDIA_TYPE: {"schema": {"type": "string", "format": "binary"}}}
ARRAY_RESPONSE_DOC: dict[int | str, dict[str, Any]] = {
    200: {"description": "The answer as JSON (`fields=` selects its parts). " + NPZ_DESCRIPTION, "content": NPZ_CONTENT}
}
CSV_RESPONSE_DOC: dict[int | str, dict[str, Any]] = {
    200: {
        "description": "The design as JSON (`fields=` selects its parts), or with `?format=csv` / `Accept: text/csv` "
        "a CSV table for a drive: "
        "the header row first (default columns time_s,position,velocity,acceleration,jerk; `columns=` chooses), then "
        "one row per instant t_k = k * sample_period_s exactly, every value computed at that instant (no -0.0). "
        "`comments=true` adds `#` lines with units and metadata before the header "
        "(read them with `pandas.read_csv(f, comment='#')`). " + NPZ_DESCRIPTION,
        "content": {CSV_MEDIA_TYPE: {"schema": {"type": "string"}}, **NPZ_CONTENT},
    }
}
