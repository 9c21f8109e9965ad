"""Requests and designs of the STAP family (Cusimano 2022, Machines 10, 767).

Frozen dataclasses: they cross the worker-process boundary. ``StapRequest`` is what a caller asks
for; ``StapDesign`` the closed-form design (``optim.families.stap.ramp``, ``optim.families.stap.moves``) with its
``TorqueLimit`` (eqs. 19, 57-59), zero-vibration ``ZeroVibrationCandidate`` jerk times (eqs. 44, 49) and the
``AutoStep`` trail of the Fig. 25 flowchart; ``OptimizedDesign`` the CasADi/IPOPT one
(``optim.families.stap.multistart``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from models.plants import Plant
from models.stap import RestToRest, Stap
from optim.solver import SolveCaps, SolverReport

DEFAULT_FREQUENCY_UNCERTAINTY = 0.1
DEFAULT_RESIDUAL_TOLERANCE = 0.05  # "a few hundredths" (Sec. 3)
OBJECTIVES = ("residual", "worst_case", "residual_and_time")
MAX_FREQUENCY_POINTS = 41
MAX_BAND_DAMPING_RATIOS = 5


@dataclass(frozen=True)
class StapRequest:
    plant: Plant
    target_velocity: float | None = None  # rest-to-velocity v, or the cruise speed with a displacement
    displacement: float | None = None
    max_acceleration: float | None = None
    max_torque_nm: float | None = None
    jerk_periods: int | None = None  # k_j; None = auto
    delta: int = 0
    acceleration_time_s: float | None = None
    frequency_uncertainty: float = DEFAULT_FREQUENCY_UNCERTAINTY
    residual_tolerance: float = DEFAULT_RESIDUAL_TOLERANCE
    objective: str = "residual"
    band_damping_ratios: tuple[float, ...] | None = None
    frequency_points: int = 21
    caps: SolveCaps = field(default_factory=SolveCaps)


@dataclass(frozen=True)
class TorqueLimit:
    """The acceleration limit that keeps the motor torque within max_torque_nm (eqs. 19, 57-59)."""

    max_torque_nm: float
    nodal_acceleration_limit: float  # eq. (19)
    inertia_ratio: float  # J_L / J_M
    coefficient: float  # (J_L/J_M)/(1 + J_L/J_M)
    load_acceleration_oscillation: float  # worst eq. (57) over the band
    torque_overshoot: float  # worst eq. (59) over the band
    worst_frequency_ratio: float
    factor: float  # 1 / (1 + torque_overshoot)
    acceleration_limit: float  # nodal limit times factor


@dataclass(frozen=True)
class ZeroVibrationCandidate:
    """A zero-vibration jerk time at a fixed t_a (eq. 49), marked."""

    k_j: int
    delta: int
    jerk_time_s: float
    kind: str  # fundamental, multiple, side_band
    peak_acceleration: float
    acceleration_limit: float | None
    reaches_limit: bool
    note: str


@dataclass(frozen=True)
class AutoStep:
    what: str
    acceleration_time_s: float
    jerk_time_s: float
    band_worst_residual: float
    meets: bool


@dataclass(frozen=True)
class StapDesign:
    """A closed-form design of the ramp (rest-to-velocity), and the move it belongs to."""

    stap: Stap
    estimated_frequency_hz: float
    k_j: int | None
    delta: int | None
    rule: str
    acceleration_limit: float | None  # a_Max used for this design
    min_acceleration_time_s: float | None  # eq. (21) with it
    limit_reached: bool
    torque: TorqueLimit | None
    candidates: tuple[ZeroVibrationCandidate, ...] = ()
    candidates_truncated: bool = False
    k_j_max: int | None = None  # exact enumeration at a fixed t_a
    delta_f: int | None = None
    paper_k_j_max: int | None = None  # eq. (45)
    paper_delta_f: int | None = None  # eq. (46)
    auto_steps: tuple[AutoStep, ...] = ()
    band_worst_residual: float = 0.0
    frequency_uncertainty: float = 0.0
    notes: tuple[str, ...] = ()
    fixed_acceleration_time: bool = False  # t_a given by the caller
    keeps_acceleration_time: bool = False  # t_a does not follow the speed (caller's, or auto's n/f_n,e)
    # rest-to-rest
    move: RestToRest | None = None
    move_notes: tuple[str, ...] = ()  # what the rest-to-rest rules did (lowered speed, ...)
    requested_velocity: float | None = None
    velocity_lowered: bool = False
    # the real torque (optim.families.stap.torque): its exact peak, and the acceleration cap that made it fit
    peak_torque_nm: float | None = None
    torque_lowered_acceleration: float | None = None


@dataclass(frozen=True)
class OptimizedDesign:
    stap: Stap
    objective: str
    start: Stap
    nominal_residual: float  # sum over the plant's modes of residual / move (the optimiser's model)
    start_nominal_residual: float
    grid_worst_residual: float | None  # largest residual / move over the optimiser's band grid
    start_grid_worst_residual: float | None
    solver: SolverReport
    solves: int
    selection: str  # optimized, or closed_form_kept when no solve improved on the start
    acceleration_time_bounds_s: tuple[float, float]
    jerk_time_floor_s: float
    move: RestToRest | None = None
    notes: tuple[str, ...] = ()  # why the closed form was kept, when it was
