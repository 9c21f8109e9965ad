"""The design families' names, stated once: the name optim and compare use (``time_optimal``) and the slug of
the endpoint and of sweeps (``time-optimal``), in the same order. Every list of families in the service is
derived from these (request schemas, compare's and sweeps' enums, the endpoints, the CLI's choices); the table
of what each family has (schema, examples) is ``app.families``. Light on purpose: the CLI's ``--help``
imports it without the solver stack.
"""

from __future__ import annotations

import typing
from typing import Literal

FamilyName = Literal["time_optimal", "pseudo_polynomial", "stap", "smoother", "input_shaped"]
FamilySlug = Literal["time-optimal", "pseudo-polynomial", "stap", "smoother", "input-shaped"]
NAMES: tuple[str, ...] = typing.get_args(FamilyName)
SLUGS: tuple[str, ...] = typing.get_args(FamilySlug)
_SLUG_OF = dict(zip(NAMES, SLUGS, strict=True))
_NAME_OF = dict(zip(SLUGS, NAMES, strict=True))


def slug_of(name: str) -> str:
    """``time_optimal`` -> ``time-optimal``."""
    return _SLUG_OF[name]


def name_of(slug_or_name: str) -> str:
    """``time-optimal`` (or ``time_optimal``) -> ``time_optimal``."""
    return _NAME_OF.get(slug_or_name, slug_or_name)


def endpoint_of(name: str) -> str:
    """The family's endpoint: ``/v1/profiles/<slug>``."""
    return f"/v1/profiles/{slug_of(name)}"
