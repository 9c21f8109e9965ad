"""JSON bodies with numpy arrays (orjson, no Python loop over samples), and the profile routes' CSV tables."""

from __future__ import annotations

from dataclasses import dataclass
from importlib.metadata import version
from typing import Annotated, Any, Literal

import numpy as np
import orjson
from fastapi import Depends, Query, Request
from starlette.concurrency import run_in_threadpool
from starlette.responses import Response

from app.schemas.family import ProfileRequest
from optim import tables
from optim.synthesis import Result

__version__ = version("vibfree")

_OPTIONS = orjson.OPT_SERIALIZE_NUMPY | orjson.OPT_NON_STR_KEYS


def dumps(content: Any) -> bytes:
    return orjson.dumps(content, option=_OPTIONS)


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


def wants_csv(request: Any) -> bool:
    """``?format=csv`` or an Accept header that prefers text/csv to JSON."""
    if request.query_params.get("format", "").lower() == "csv":
        return True
    accept = request.headers.get("accept", "")
    return CSV_MEDIA_TYPE in accept and "application/json" not in accept.split(CSV_MEDIA_TYPE)[0]


@dataclass(frozen=True)
class Output:
    """What a profile route answers with: JSON, or the CSV table with these columns (and comment lines)."""

    csv: bool
    columns: tuple[str, ...] | None  # None: the default (profile) columns; ('all',): every column
    comments: bool


async def output(
    request: Request,
    format: Annotated[Literal["json", "csv"] | None, Query(description="csv: the profile as a CSV table")] = None,
    columns: Annotated[str | None, Query(max_length=400, description=COLUMNS_DESCRIPTION)] = None,
    comments: Annotated[
        bool,
        Query(
            description="CSV: add `#` comment lines (units, plant, family, design, sample period) before the header."
        ),
    ] = False,
) -> Output:
    """The profile routes' output options, from the query (and the Accept header)."""
    names: tuple[str, ...] | None = None
    if columns is not None:
        names = tuple(c.strip() for c in columns.split(",") if c.strip())
        tables.check_columns(names)  # 422 on columns before anything is designed
    return Output(csv=wants_csv(request), columns=names, comments=comments)


OutputDep = Annotated[Output, Depends(output)]


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
    """JSON by default; the CSV table on the uniform grid when the client asks for it."""
    if not output.csv:
        return NumpyJSONResponse(answer)
    table = await run_in_threadpool(tables.table, result, output.columns or tables.PROFILE_COLUMNS)
    lines = comment_lines(title, body, answer, table) if output.comments else []
    return Response(
        csv_body(table, lines),
        media_type=CSV_MEDIA_TYPE,
        headers={"content-disposition": 'attachment; filename="profile.csv"'},
    )


CSV_RESPONSE_DOC: dict[int | str, dict[str, Any]] = {
    200: {
        "description": "The design as JSON, or with `?format=csv` / `Accept: text/csv` a CSV table for a drive: "
        "the header row first (default columns time_s,position,velocity,acceleration,jerk; `columns=` chooses), then "
        "one row per instant t_k = k * sample_period_s exactly, every value computed at that instant (no -0.0). "
        "`comments=true` adds `#` lines with units and metadata before the header "
        "(read them with `pandas.read_csv(f, comment='#')`).",
        "content": {CSV_MEDIA_TYPE: {"schema": {"type": "string"}}},
    }
}
