"""JSON bodies with numpy arrays, serialised by orjson without a Python loop over samples."""

from __future__ import annotations

from typing import Any

import orjson
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
