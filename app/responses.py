"""JSON bodies with numpy arrays, serialised by orjson without a Python loop over samples."""

from __future__ import annotations

from typing import Annotated, Any, Literal

import numpy as np
import orjson
from fastapi import Query
from starlette.responses import Response

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
PROFILE_COLUMNS = ("time_s", "position", "velocity", "acceleration", "jerk")


def wants_csv(request: Any) -> bool:
    """``?format=csv`` or an Accept header that prefers text/csv to JSON."""
    if request.query_params.get("format", "").lower() == "csv":
        return True
    accept = request.headers.get("accept", "")
    return CSV_MEDIA_TYPE in accept and "application/json" not in accept.split(CSV_MEDIA_TYPE)[0]


def profile_csv(profile: dict[str, Any], title: str) -> bytes:
    """The profile as CSV for a drive's cam table: a comment line with the units, a header, rows.

    Rows are written by orjson (shortest round-trip floats) as a 2-D array whose brackets become
    line breaks: no Python loop over samples.
    """
    table = np.column_stack([np.asarray(profile[c], dtype=float) for c in PROFILE_COLUMNS])
    body = orjson.dumps(table, option=orjson.OPT_SERIALIZE_NUMPY)[2:-2].replace(b"],[", b"\n")
    header = (
        f"# {title}; units: time_s in s; position in the motor's unit (rad or m); velocity per s; "
        "acceleration per s^2; jerk per s^3 (right-hand values where it jumps)\n" + ",".join(PROFILE_COLUMNS) + "\n"
    )
    return header.encode() + body + b"\n"


def negotiate(request: Any, body: dict[str, Any], title: str) -> Response:
    """JSON by default; the profile as CSV when the client asks for it."""
    if wants_csv(request):
        return Response(
            profile_csv(body["profile"], title),
            media_type=CSV_MEDIA_TYPE,
            headers={"content-disposition": 'attachment; filename="profile.csv"'},
        )
    return NumpyJSONResponse(body)


CSV_RESPONSE_DOC: dict[int | str, dict[str, Any]] = {
    200: {
        "description": "The design as JSON, or with `?format=csv` / `Accept: text/csv` the profile as CSV "
        "(time_s,position,velocity,acceleration,jerk, units in the first comment line).",
        "content": {CSV_MEDIA_TYPE: {"schema": {"type": "string"}}},
    }
}


# The ``format`` query parameter every profile route declares (negotiate() reads it).
CsvFormat = Annotated[Literal["json", "csv"] | None, Query(description="csv: the profile only, as CSV")]
