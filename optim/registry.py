"""The registered design families, by name (the names are stated once, in app.family_names): the adapters
between the pipeline (optim.synthesis) and each family's synthesis, and the warm-up of their solvers."""

from __future__ import annotations

from optim.families.input_shaped.family import InputShapedFamily
from optim.families.pseudo_polynomial.family import PseudoPolynomialFamily
from optim.families.smoother.family import SmootherFamily
from optim.families.stap.family import StapFamily
from optim.families.time_optimal.family import TimeOptimalFamily
from optim.family import Family
from optim.solver import SolveCaps

FAMILIES: dict[str, Family] = {
    family.name: family
    for family in (
        TimeOptimalFamily(),
        PseudoPolynomialFamily(),
        StapFamily(),
        SmootherFamily(),
        InputShapedFamily(),
    )
}


def warm_up_all(solver: SolveCaps) -> None:
    """Build every family's solver problems (run once in each new worker process)."""
    for family in FAMILIES.values():
        family.warm_up(solver)
