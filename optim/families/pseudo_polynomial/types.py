"""The request and the design of the pseudo-polynomial family (Incerti, Secs. IV-V).

A request asks for a rest-to-rest move of ``displacement`` in ``duration_s`` by the law of order n
phi(t) = Phi [1 - sum_i C_i (1 - t/T)^gamma_i] (eq. 17, C_i by eq. 22) from initial exponents, within
optional limits; the design carries the exponents chosen, the final energy (eq. 26) before and after,
and how the exponents were selected.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from models.plants import Plant
from models.pseudo_polynomial import PseudoPolynomial
from optim.problem import Limits  # the service's limits, re-exported for the family's core
from optim.solver import SolveCaps, SolverReport

__all__ = ["FloatArray", "Limits", "PseudoPolynomialDesign", "PseudoPolynomialRequest"]

FloatArray = NDArray[np.float64]  # exponents, parameter vectors, bounds


@dataclass(frozen=True)
class PseudoPolynomialRequest:
    plant: Plant
    displacement: float
    duration_s: float
    order: int = 2
    initial_exponents: tuple[float, ...] | None = None
    limits: Limits = field(default_factory=Limits)
    minimize_duration: bool = False
    residual_tolerance: float | None = None  # load units; default 1e-6 of the load displacement
    caps: SolveCaps = field(default_factory=SolveCaps)


@dataclass(frozen=True)
class PseudoPolynomialDesign:
    law: PseudoPolynomial
    initial: PseudoPolynomial
    initial_energy: float
    final_energy: float
    residual_amplitude: float  # sum over modes of the free-oscillation envelope of the load at T
    initial_residual_amplitude: float
    selection: str
    solver: SolverReport
    solves: int
    energy_is_physical: bool
    duration_search: tuple[tuple[float, bool], ...] = ()
    longest_infeasible_below_s: float | None = None  # minimize_duration's bracket below the answer
    fallback_reason: str = ""  # selection "fallback": why, and which design

    @property
    def energy_ratio(self) -> float:
        return self.final_energy / self.initial_energy if self.initial_energy > 0 else 0.0
