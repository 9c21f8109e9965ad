"""The request body that reproduces a design: a family's own fields for its options (compare's rows[].request).

The inverse of each family's ``options`` parsing (app.schemas.<family>): fields at their defaults are left out,
so that a row's request reads like one a user would write.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

from app.presenters import present
from optim.families.pseudo_polynomial.family import PseudoPolynomialOptions
from optim.families.smoother.family import SmootherOptions
from optim.families.stap.family import StapOptions
from optim.families.time_optimal.options import TimeOptimalOptions


def _set_fields(options: Any) -> dict[str, Any]:
    """Every option that is not None, nested options as objects."""
    return {k: v for k, v in dataclasses.asdict(options).items() if v is not None}


def _time_optimal(options: TimeOptimalOptions) -> dict[str, Any]:
    out: dict[str, Any] = {}
    if options.robustness is not None:
        out["robustness"] = _set_fields(options.robustness)
    if options.modes is not None:
        out["modes"] = options.modes
    if options.tradeoff is not None:
        out["tradeoff"] = options.tradeoff
    if options.max_duration_s is not None:
        out["max_duration_s"] = options.max_duration_s
    return out


def _smoother(options: SmootherOptions) -> dict[str, Any]:
    out: dict[str, Any] = {
        "filters": [
            {"type": f.kind, **({"duration_s": f.duration_s} if f.duration_s is not None else {})}
            for f in options.filters
        ]
    }
    if options.discrete_sample_period_s is not None:
        out["discrete_sample_period_s"] = options.discrete_sample_period_s
    return out


def _stap(options: StapOptions) -> dict[str, Any]:
    out = _set_fields(options)
    if out.get("optimization") and out["optimization"].get("damping_ratios") is None:
        out["optimization"].pop("damping_ratios", None)
    return out


def _pseudo_polynomial(options: PseudoPolynomialOptions) -> dict[str, Any]:
    out = _set_fields(options)
    if not options.minimize_duration:
        out.pop("minimize_duration", None)
    if options.order == 2:
        out.pop("order", None)
    return out


FIELDS: dict[str, Callable[[Any], dict[str, Any]]] = {  # the family's options class -> its fields
    "time_optimal": _time_optimal,
    "smoother": _smoother,
    "stap": _stap,
    "pseudo_polynomial": _pseudo_polynomial,
}


def request_fields(family: str, options: Any) -> dict[str, Any]:
    """The family's own request fields that reproduce ``options`` (JSON-ready)."""
    fields: dict[str, Any] = present(FIELDS.get(family, _set_fields)(options))
    return fields
