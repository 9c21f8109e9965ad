"""The family table: what the service has for each design family, by its name (app.family_names, where its slug
and endpoint are derived): its request schema and worked examples, in one row. The warm-up reads it (no router is
read for it)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from app.examples import input_shaped, pseudo_polynomial, smoother, stap, time_optimal
from app.family_names import NAMES
from app.schemas.family import ProfileRequest
from app.schemas.registry import REQUEST_SCHEMAS

_EXAMPLES: dict[str, dict[str, dict[str, Any]]] = {
    "time_optimal": time_optimal.EXAMPLES,
    "pseudo_polynomial": pseudo_polynomial.EXAMPLES,
    "stap": stap.EXAMPLES,
    "smoother": smoother.EXAMPLES,
    "input_shaped": input_shaped.EXAMPLES,
}


@dataclass(frozen=True)
class FamilyEntry:
    name: str  # app.family_names: its slug and endpoint follow from it (slug_of, endpoint_of)
    request: type[ProfileRequest]
    examples: dict[str, dict[str, Any]]  # OpenAPI examples: {key: {"summary", "value", ...}}


FAMILY_TABLE: tuple[FamilyEntry, ...] = tuple(
    FamilyEntry(name, REQUEST_SCHEMAS[name], _EXAMPLES[name]) for name in NAMES
)
BY_NAME: dict[str, FamilyEntry] = {entry.name: entry for entry in FAMILY_TABLE}
