"""The plant's symbolic form: its state space as CasADi expressions, for the optimisers.

``Plant.symbolic()`` builds it; casadi is imported only when it is used. casadi ships no type
stubs, so its expressions are typed ``SX`` (an alias of ``Any``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

SX = Any  # a casadi.SX expression, or a float where an entry is constant


@dataclass(frozen=True)
class SymbolicPlant:
    """The plant's state space as CasADi SX expressions of its parameter vector.

    ``function`` maps the parameter values to (A, B, C, D); an optimiser builds its problem once
    with ``parameters`` as CasADi parameters and sets the plant's values per solve.
    """

    parameter_names: tuple[str, ...]
    parameters: SX  # column of the parameter symbols, in ``parameter_names`` order
    a: SX
    b: SX
    c: SX
    d: SX
    numerator: tuple[SX, ...] = ()  # G(s) from the motor position, descending powers
    denominator: tuple[SX, ...] = ()

    def symbol(self, name: str) -> SX:
        """The symbol of one scalar parameter."""
        return self.parameters[self.parameter_names.index(name)]

    def second_order_mode(self) -> tuple[SX, SX, SX, SX]:
        """(sigma, omega_d, Re r, Im r) of G's upper pole -sigma + i omega_d and its residue r, for a
        denominator a2 s^2 + a1 s + a0 (the mode of Incerti eq. 4, Cusimano eqs. 1-3), as expressions."""
        import casadi as ca

        if len(self.denominator) != 3:
            raise ValueError("not a second-order plant")
        a2, a1, a0 = self.denominator
        num = [0.0] * (3 - len(self.numerator)) + list(self.numerator)
        b2, b1, b0 = num
        sigma = a1 / (2 * a2)
        root = ca.sqrt(4 * a0 * a2 - a1 * a1)
        omega_d = root / (2 * a2)
        # r = N(p)/D'(p) with D'(p) = 2 a2 p + a1 = i root; G's constant b2/a2 has no residue.
        n_re = b2 * (sigma * sigma - omega_d * omega_d) - b1 * sigma + b0
        n_im = -2 * b2 * sigma * omega_d + b1 * omega_d
        return sigma, omega_d, n_im / root, -n_re / root

    def function(self) -> Any:
        """The casadi.Function p -> (A, B, C, D)."""
        import casadi as ca

        return ca.Function(
            "state_space", [self.parameters], [self.a, self.b, self.c, self.d], ["p"], ["A", "B", "C", "D"]
        )
