"""Shared pieces of the request and response schemas."""

from __future__ import annotations

import types
import typing
from dataclasses import dataclass
from typing import Annotated, Any, ClassVar

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field

# Bounds of the numbers in request arrays: far beyond any machine, so they only refuse nonsense, and
# small enough that sums, squares and differences of samples stay finite in double precision.
SAMPLE_VALUE_MAX = 1e12
SAMPLE_TIME_MAX_S = 1e6
TOLERANCE_MIN = 1e-12  # a relative tolerance below double precision's resolution means nothing

SampleValue = Annotated[float, Field(ge=-SAMPLE_VALUE_MAX, le=SAMPLE_VALUE_MAX)]
SampleTime = Annotated[float, Field(ge=-SAMPLE_TIME_MAX_S, le=SAMPLE_TIME_MAX_S)]
DampingRatio = Annotated[float, Field(ge=0, lt=1)]


def _integral(value: Any) -> Any:
    """A float with no fractional part as the integer it is: JSON has one number type, and JSON Schema's
    ``integer`` is any number whose fractional part is zero (72.0 is the integer 72)."""
    if isinstance(value, float) and value.is_integer():
        return int(value)
    return value


INTEGRAL = BeforeValidator(_integral)
# An integer field of a request (strict, but 72.0 is 72). Inside a union or a list, write the bounds before the
# validator, Annotated[int, Field(ge=...), INTEGRAL]: after it, pydantic writes them as "ge"/"le" in the schema.
Int = Annotated[int, INTEGRAL]


# --- JSON Schema for the rules between fields ---------------------------------------------------------------
# Each condition says exactly what validation checks, no more: a schema stricter than the validation would have
# schema-invalid requests accepted (schemathesis' negative_data_rejection), a looser one schema-valid requests
# refused. A condition carries its negation written without "not" over objects: schemathesis' generator gives up
# on an operation whose schema holds more than a few of those ("UnsupportedSchema"); "not" is kept to scalars.


@dataclass(frozen=True)
class Cond:
    """A condition on a request body: the schema of the bodies where it ``holds``, and of those where it ``fails``."""

    holds: dict[str, Any]
    fails: dict[str, Any]

    def __invert__(self) -> Cond:
        return Cond(self.fails, self.holds)


def given(name: str, kind: str = "number") -> Cond:
    """A nullable field is there and not null (a JSON ``kind``: number, integer, array, object, string)."""
    return Cond({"required": [name], "properties": {name: {"type": kind}}}, {"properties": {name: {"type": "null"}}})


def present(name: str) -> Cond:
    """A field that cannot be null is there."""
    return Cond({"required": [name]}, {"properties": {name: False}})


def is_value(name: str, value: Any, *, default: bool = False) -> Cond:
    """The field equals ``value`` (``default``: also when it is absent, its default being ``value``)."""
    equal, other = {name: {"const": value}}, {name: {"not": {"const": value}}}
    if default:
        return Cond({"properties": equal}, {"required": [name], "properties": other})
    return Cond({"required": [name], "properties": equal}, {"properties": other})


def leaf(name: str, holds: dict[str, Any], fails: dict[str, Any]) -> Cond:
    """The field is there and ``holds`` (a schema of its value); else it is absent, or ``fails`` (its complement
    among the values the field's own schema allows)."""
    return Cond({"required": [name], "properties": {name: holds}}, {"properties": {name: fails}})


def inside(name: str, *conds: Cond) -> Cond:
    """The object field ``name`` is there and every one of ``conds`` holds in it."""
    holds = {"required": [name], "properties": {name: both(*conds).holds}}
    return Cond(holds, {"properties": {name: both(*conds).fails}})


def limit_given(name: str) -> Cond:
    """``limits.<name>`` is there and not null."""
    return inside("limits", given(name))


def plant_kind_is(*kinds: str) -> Cond:
    """``plant.kind`` is one of ``kinds``."""
    return inside("plant", leaf("kind", {"enum": list(kinds)}, {"not": {"enum": list(kinds)}}))


def both(*conds: Cond) -> Cond:
    if len(conds) == 1:
        return conds[0]
    return Cond({"allOf": [c.holds for c in conds]}, {"anyOf": [c.fails for c in conds]})


def either(*conds: Cond) -> Cond:
    return ~both(*(~c for c in conds))


def never(*conds: Cond) -> dict[str, Any]:
    """The schema of a rule: refused when every one of ``conds`` holds."""
    return both(*conds).fails


def _add_schema_rules(schema: dict[str, Any], model: type[Any]) -> None:
    rules = model.schema_rules() if hasattr(model, "schema_rules") else []
    if rules:
        schema["allOf"] = [*schema.get("allOf", []), *rules]


class StrictModel(BaseModel):
    """Request models: unknown fields, NaN and infinities are refused with a 422, and so are values of the
    wrong JSON type (true for a number, "1" for a number): strict validation, which still takes an
    integer for a number (and, with ``Int``, an integral number for an integer).

    The JSON schema states the rules between fields that it can (``schema_rules``, exactly as validation checks
    them); the others, value comparisons and physics, are listed in ``UNSCHEMED_RULES`` and, for every
    model a request holds, in the operation's description (``unschemed_rules``)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True, json_schema_extra=_add_schema_rules)

    UNSCHEMED_RULES: ClassVar[tuple[str, ...]] = ()

    @classmethod
    def schema_rules(cls) -> list[dict[str, Any]]:
        """JSON Schema ``allOf`` entries for the rules between this model's fields."""
        return []


def _models_in(annotation: Any) -> list[type[BaseModel]]:
    """The pydantic models an annotation holds, through unions, lists and Annotated."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    out: list[type[BaseModel]] = []
    if typing.get_origin(annotation) is not None or isinstance(annotation, types.UnionType):
        for arg in typing.get_args(annotation):
            out += _models_in(arg)
    return out


def unschemed_rules(model: type[BaseModel]) -> list[str]:
    """Every rule validation checks that the JSON schema of ``model`` cannot state: its own (``UNSCHEMED_RULES``,
    along its bases) and those of every model it holds, each once, in order."""
    rules: dict[str, None] = {}
    seen: set[type[BaseModel]] = set()

    def visit(current: type[BaseModel]) -> None:
        if current in seen:
            return
        seen.add(current)
        for base in reversed(current.__mro__):
            rules.update(dict.fromkeys(vars(base).get("UNSCHEMED_RULES", ())))
        for info in current.model_fields.values():
            for inner in _models_in(info.annotation):
                visit(inner)

    visit(model)
    return list(rules)


class OutModel(BaseModel):
    """Response models (used for the OpenAPI schema)."""

    model_config = ConfigDict(extra="forbid")
