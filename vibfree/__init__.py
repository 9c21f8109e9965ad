"""vibfree: vibration-free motion profiles for elastic machines.

The Python API runs the service's own pipeline in-process, without a server::

    from vibfree import synthesize
    design = synthesize("stap", {"plant": {"kind": "mode", "natural_frequency_hz": 40},
                                 "target_velocity": 150, "limits": {"max_acceleration": 1000}})
    design.answer["metrics"]["settling_time_s"]      # the JSON answer of POST /v1/profiles/stap
    design.csv(columns=["time_s", "position", "load_position"])   # the cam table, as ?format=csv

Requests and answers are the HTTP API's bodies (see /docs); errors are ``VibfreeError`` carrying the same
problem+json the service would answer with.
"""

from __future__ import annotations

import warnings
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from vibfree.api import (
        REQUEST_SCHEMAS,
        ProgramAnswer,
        Sweep,
        Synthesis,
        VibfreeError,
        compare,
        identify,
        program,
        sweep,
        synthesize,
        synthesize_many,
    )

__all__ = [
    "REQUEST_SCHEMAS",
    "ProgramAnswer",
    "Sweep",
    "Synthesis",
    "VibfreeError",
    "compare",
    "identify",
    "program",
    "sweep",
    "synthesize",
    "synthesize_many",
]


def __getattr__(name: str) -> Any:
    """The API on first use: ``vibfree.cli`` (``--help``, ``--url``) starts without the solvers' imports."""
    if name == "FAMILIES":  # the old name of REQUEST_SCHEMAS (family name -> request schema)
        warnings.warn("vibfree.FAMILIES is deprecated: use vibfree.REQUEST_SCHEMAS", DeprecationWarning, stacklevel=2)
        name = "REQUEST_SCHEMAS"
    if name in __all__:
        from vibfree import api

        return getattr(api, name)
    raise AttributeError(f"module 'vibfree' has no attribute {name!r}")
