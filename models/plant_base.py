"""The plant base: modes, parameter limits and the transfer-function machinery every kind shares.

Every kind maps the motor command to the load motion through a linear transfer function, defined
once by ``Plant._command_tf`` with plain arithmetic so that the same formula serves the numeric
form (floats -> numpy state space) and the symbolic form (CasADi SX -> ``SymbolicPlant`` for the
optimisers). The concrete kinds are in ``models.plants``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import Field, dataclass, fields
from typing import Any, ClassVar, Literal

import numpy as np
from numpy.typing import NDArray

from models.errors import InvalidParameter
from models.plant_symbolic import SymbolicPlant

# Ranges that keep every derived quantity finite in double precision; they are far outside
# what a machine can have, so they only refuse nonsense.
PARAMETER_MAX = 1e12
FREQUENCY_MIN_HZ = 1e-3
FREQUENCY_MAX_HZ = 1e5

CommandInput = Literal["position", "velocity"]
# A field's value: a number, a coefficient vector (``TransferFunctionPlant``) or the command input.
ParameterValue = float | tuple[float, ...] | str
# A matrix as nested lists whose entries are floats or CasADi expressions (see ``realise``).
Rows = list[list[Any]]


@dataclass(frozen=True)
class Mode:
    """A vibration mode: a pair of complex poles -zeta w +- j w sqrt(1 - zeta^2)."""

    natural_frequency_rad_s: float
    damping_ratio: float

    @classmethod
    def from_pole(cls, pole: complex) -> Mode:
        """The mode of a pole in the upper half-plane: w = |p|, zeta = -Re(p)/|p|."""
        omega = abs(pole)
        return cls(omega, max(0.0, -pole.real / omega))

    @property
    def natural_frequency_hz(self) -> float:
        return self.natural_frequency_rad_s / (2.0 * math.pi)

    @property
    def damped_frequency_rad_s(self) -> float:
        return self.natural_frequency_rad_s * math.sqrt(1.0 - self.damping_ratio**2)

    @property
    def damped_frequency_hz(self) -> float:
        return self.damped_frequency_rad_s / (2.0 * math.pi)

    @property
    def natural_period_s(self) -> float:
        return 1.0 / self.natural_frequency_hz

    @property
    def damped_period_s(self) -> float:
        return 1.0 / self.damped_frequency_hz

    def as_dict(self) -> dict[str, float]:
        """Every derived quantity of the mode, by name."""
        return {
            "natural_frequency_hz": self.natural_frequency_hz,
            "natural_frequency_rad_s": self.natural_frequency_rad_s,
            "damping_ratio": self.damping_ratio,
            "damped_frequency_hz": self.damped_frequency_hz,
            "damped_frequency_rad_s": self.damped_frequency_rad_s,
            "natural_period_s": self.natural_period_s,
            "damped_period_s": self.damped_period_s,
            "decay_rate_1_s": self.decay_rate_1_s,
        }

    @property
    def decay_rate_1_s(self) -> float:
        """sigma = zeta w: the envelope decays as exp(-sigma t)."""
        return self.damping_ratio * self.natural_frequency_rad_s

    @property
    def pole(self) -> complex:
        return complex(-self.decay_rate_1_s, self.damped_frequency_rad_s)


@dataclass(frozen=True)
class StateSpace:
    """x' = A x + B u, y = C x + D u, with u the motor position and y the load position."""

    a: NDArray[np.float64]
    b: NDArray[np.float64]
    c: NDArray[np.float64]
    d: NDArray[np.float64]


def check_positive(name: str, value: float, *, allow_zero: bool = False) -> float:
    """``value`` as a float, if finite, > 0 (>= 0 with ``allow_zero``) and <= PARAMETER_MAX."""
    value = float(value)
    if not math.isfinite(value):
        raise InvalidParameter(name, value, "must be a finite number")
    if allow_zero and value < 0.0:
        raise InvalidParameter(name, value, "must be >= 0")
    if not allow_zero and value <= 0.0:
        raise InvalidParameter(name, value, "must be > 0")
    if value > PARAMETER_MAX:
        raise InvalidParameter(name, value, f"must be <= {PARAMETER_MAX:g}")
    return value


def check_derived_frequency(field: str, omega_rad_s: float) -> float:
    """A derived natural frequency (rad/s), checked against the frequency range before any use (a
    division by it), blaming ``field``."""
    f = omega_rad_s / (2.0 * math.pi)
    if not (math.isfinite(f) and FREQUENCY_MIN_HZ <= f <= FREQUENCY_MAX_HZ):
        raise InvalidParameter(
            field,
            f,
            f"the derived natural frequency {f:.6g} Hz must lie in [{FREQUENCY_MIN_HZ:g}, {FREQUENCY_MAX_HZ:g}] Hz",
        )
    return omega_rad_s


def check_modes(modes: Sequence[Mode], field: str) -> None:
    """Refuse derived modes outside the frequency range or not underdamped, blaming ``field``."""
    for mode in modes:
        f = mode.natural_frequency_hz
        if not FREQUENCY_MIN_HZ <= f <= FREQUENCY_MAX_HZ:
            raise InvalidParameter(
                field,
                f,
                f"the derived natural frequency {f:.6g} Hz must lie in [{FREQUENCY_MIN_HZ:g}, {FREQUENCY_MAX_HZ:g}] Hz",
            )
        if mode.damping_ratio >= 1.0:
            raise InvalidParameter(field, mode.damping_ratio, "the derived damping ratio must be < 1")


def realise(num: Sequence[Any], den: Sequence[Any]) -> tuple[Rows, Rows, Rows, Rows]:
    """Controllable canonical realisation of num/den (descending powers, deg num <= deg den).

    The same layout as ``scipy.signal.tf2ss``; written with plain arithmetic so it builds either
    floats or CasADi expressions.
    """
    n = len(den) - 1
    lead = den[0]
    a_coef = [den[i] / lead for i in range(1, n + 1)]
    padded = [0.0] * (n + 1 - len(num)) + list(num)
    b_coef = [padded[i] / lead for i in range(n + 1)]
    a = [[-a_coef[j] if i == 0 else (1.0 if j == i - 1 else 0.0) for j in range(n)] for i in range(n)]
    b = [[1.0] if i == 0 else [0.0] for i in range(n)]
    c = [[b_coef[j + 1] - a_coef[j] * b_coef[0] for j in range(n)]]
    d = [[b_coef[0]]]
    return a, b, c, d


# Fields that are not parameters of the transfer function (no symbol, no entry in the vector).
NON_NUMERIC_FIELDS = {"command_input"}


class Plant:
    """Base of the plant kinds. Subclasses are frozen dataclasses whose fields are parameters."""

    kind: ClassVar[str]
    # Set by @dataclass on every kind; declared so that ``dataclasses.fields(self)`` type-checks.
    __dataclass_fields__: ClassVar[dict[str, Field[Any]]]

    # --- defined by each kind -------------------------------------------------------------
    @staticmethod
    def _command_tf(p: Mapping[str, Any]) -> tuple[list[Any], list[Any]]:
        """Numerator and denominator (descending powers) from the command input to the load."""
        raise NotImplementedError

    @property
    def command_input(self) -> CommandInput:
        """The motor quantity the transfer function takes: ``position`` or ``velocity``."""
        return "position"

    # Physical data for energy and torque, where the kind has them.
    @property
    def energy_inertia(self) -> float | None:
        """Inertia (or mass) of the vibrating load, for the vibration energy."""
        return None

    @property
    def energy_stiffness(self) -> float | None:
        """Stiffness of the elastic element, in the load's coordinate."""
        return None

    def torque_inertias(self) -> tuple[float, float] | None:
        """(J_M, J_L) where the kind defines the motor torque J_M th_M'' + J_L th_L''."""
        return None

    # --- shared ---------------------------------------------------------------------------
    def parameter_values(self) -> dict[str, ParameterValue]:
        """The fields by name."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def command_transfer_function(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The kind's own transfer function (from ``command_input`` to the load), as numbers."""
        num, den = self._command_tf(self.parameter_values())
        return np.asarray(num, dtype=float), np.asarray(den, dtype=float)

    @functools.cached_property
    def _load_tf(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """G(s) computed once per plant object (its parameters are frozen)."""
        return self._load_transfer_function()

    @functools.cached_property
    def _cached_modes(self) -> tuple[Mode, ...]:
        return self._modes()

    @functools.cached_property
    def modal_forms(self) -> dict[int, Any]:
        """models.simulation's modal forms of G(s), by Taylor count, filled on first use (one plant, many runs)."""
        return {}

    def load_transfer_function(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """G(s) from the motor position to the load position (numerator, denominator); fresh copies of
        arrays computed once per plant."""
        num, den = self._load_tf
        return num.copy(), den.copy()

    def _load_transfer_function(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        num, den = self.command_transfer_function()
        if self.command_input == "velocity":
            num = np.append(num, 0.0)  # V(s) = s Theta_m(s)
        num = np.trim_zeros(num, "f")
        return num, den

    def modes(self) -> tuple[Mode, ...]:
        """The vibration modes: the complex pole pairs, lowest frequency first (computed once per plant)."""
        return self._cached_modes

    def _modes(self) -> tuple[Mode, ...]:
        _, den = self.command_transfer_function()
        poles = np.roots(den)
        upper = sorted((p for p in poles if p.imag > 0.0), key=abs)
        return tuple(Mode.from_pole(complex(p)) for p in upper)

    @property
    def dc_gain(self) -> float:
        """G(0): load displacement per unit motor displacement (0 for velocity-input kinds)."""
        num, den = self._load_tf
        return float(num[-1] / den[-1])

    def load_move(self, motor_move: float) -> float:
        """|G(0)| times a motor move: how far the load goes (or how fast it ends up moving). For
        plants without a position gain (velocity input) the motor's own move is the reference."""
        gain = abs(self.dc_gain) if self.command_input == "position" else 0.0
        return abs(motor_move) * (gain if gain > 0.0 else 1.0)

    def state_space(self) -> StateSpace:
        """Numeric state space of G(s) (motor position in, load position out)."""
        num, den = self.load_transfer_function()
        a, b, c, d = (np.array(m, dtype=float).reshape(len(m), -1) for m in realise(list(num), den.tolist()))
        return StateSpace(a, b, c, d)

    def symbolic(self) -> SymbolicPlant:
        """The same state space with the parameters as CasADi symbols.

        It depends only on the kind and its shape (``symbolic_key``), never on parameter values,
        so an optimiser builds it once per key and passes ``symbolic_parameter_values()``.
        """
        import casadi as ca

        sizes = self.symbolic_sizes()
        names: list[str] = []
        values: dict[str, Any] = {}
        for f in fields(self):
            if f.name in NON_NUMERIC_FIELDS:
                continue
            if f.name in sizes:
                values[f.name] = [ca.SX.sym(f"{f.name}_{i}") for i in range(sizes[f.name])]
                names += [f"{f.name}[{i}]" for i in range(sizes[f.name])]
            else:
                values[f.name] = ca.SX.sym(f.name)
                names.append(f.name)
        num, den = self._command_tf(values)
        if self.command_input == "velocity":
            num = [*list(num), 0.0]
        a, b, c, d = (
            ca.vertcat(*[ca.horzcat(*[ca.SX(e) if isinstance(e, float) else e for e in row]) for row in m])
            for m in realise(num, den)
        )
        flat = [s for v in values.values() for s in (v if isinstance(v, list) else [v])]
        return SymbolicPlant(tuple(names), ca.vertcat(*flat), a, b, c, d, tuple(num), tuple(den))

    def symbolic_key(self) -> tuple[str, tuple[tuple[str, int], ...], CommandInput]:
        """What the symbolic form depends on: kind, vector sizes and command input."""
        return (self.kind, tuple(sorted(self.symbolic_sizes().items())), self.command_input)

    def symbolic_parameter_values(self) -> NDArray[np.float64]:
        """The numeric parameter vector matching ``symbolic()``'s parameter order."""
        out: list[float] = []
        for name, value in self.parameter_values().items():
            if name in NON_NUMERIC_FIELDS:
                continue
            out += [float(x) for x in value] if isinstance(value, tuple) else [float(value)]
        return np.asarray(out, dtype=float)

    def symbolic_sizes(self) -> dict[str, int]:
        """Lengths of the vector-valued fields (transfer-function coefficients); none by default."""
        return {}
