"""The registered families, one module each: the adapters between the pipeline and each family's synthesis."""

from __future__ import annotations

from typing import TYPE_CHECKING

from optim.families.input_shaped import InputShapedFamily
from optim.families.pseudo_polynomial import PseudoPolynomialFamily
from optim.families.smoother import SmootherFamily
from optim.families.stap import StapFamily
from optim.families.time_optimal import TimeOptimalFamily

if TYPE_CHECKING:
    from optim.family import Family

REGISTRY: dict[str, Family] = {
    family.name: family
    for family in (
        TimeOptimalFamily(),
        PseudoPolynomialFamily(),
        StapFamily(),
        SmootherFamily(),
        InputShapedFamily(),
    )
}

__all__ = [
    "REGISTRY",
    "InputShapedFamily",
    "PseudoPolynomialFamily",
    "SmootherFamily",
    "StapFamily",
    "TimeOptimalFamily",
]
