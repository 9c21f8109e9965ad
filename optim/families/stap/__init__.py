"""STAP design (Cusimano 2022, Machines 10, 767): closed-form rules and a CasADi/IPOPT formulation.

The paper's pure formulas (eqs. 19, 21, 44-46, 57-59, Appendix B) are in ``models.stap``; this
package composes them:

- ``types``: the request and the designs (frozen, they cross the worker-process boundary);
- ``limits``: f_n,e and a_Max, with the torque limit lowered for the oscillation (eqs. 19, 57-59);
- ``ramp``: the closed-form ramp at one speed and the Fig. 25 flowchart (Secs. 2-4, Appendix C);
- ``moves``: request checks, rest-to-velocity and rest-to-rest designs (``design``);
- ``torque``: the real motor torque J_M a_M + J_L a_L held within max_torque_nm (a 1-D search on the
  acceleration against the exact peak, beyond eqs. 19 and 57-59);
- ``problem``: the CasADi problem over (t_a, t_j), built once per shape with named parameters;
- ``multistart``: the optimised design (``optimize``): starts, solves and selection.
"""

from __future__ import annotations

from models.stap import worst_torque_overshoot
from models.stap_design import min_acceleration_time, nodal_acceleration_limit, paper_delta_f, paper_k_j_max
from optim.families.stap.limits import (
    BAND_POINTS,
    LIMIT_RTOL,
    acceleration_limit,
    band_ratios,
    band_worst,
    estimated_mode,
    torque_limit,
)
from optim.families.stap.moves import check_request, closed_form, design
from optim.families.stap.multistart import (
    FEASIBLE,
    JERK_PERIODS_FLOOR,
    MAX_STARTS,
    TIME_RANGE,
    TORQUE_BAND_POINTS,
    optimize,
)
from optim.families.stap.problem import (
    OPTIONS,
    SOLVER_CACHE,
    TORQUE_GRID_SIZES,
    TORQUE_MARGIN,
    TORQUE_POINTS_PER_PERIOD,
    warm_up,
)
from optim.families.stap.ramp import AUTO_MAX_PERIODS, MAX_LISTED_CANDIDATES, zero_vibration_candidates
from optim.families.stap.torque import fits_torque, lower_acceleration
from optim.families.stap.types import (
    DEFAULT_FREQUENCY_UNCERTAINTY,
    DEFAULT_RESIDUAL_TOLERANCE,
    MAX_BAND_DAMPING_RATIOS,
    MAX_FREQUENCY_POINTS,
    OBJECTIVES,
    AutoStep,
    OptimizedDesign,
    StapDesign,
    StapRequest,
    TorqueLimit,
    ZeroVibrationCandidate,
)

__all__ = [
    "AUTO_MAX_PERIODS",
    "BAND_POINTS",
    "DEFAULT_FREQUENCY_UNCERTAINTY",
    "DEFAULT_RESIDUAL_TOLERANCE",
    "FEASIBLE",
    "JERK_PERIODS_FLOOR",
    "LIMIT_RTOL",
    "MAX_BAND_DAMPING_RATIOS",
    "MAX_FREQUENCY_POINTS",
    "MAX_LISTED_CANDIDATES",
    "MAX_STARTS",
    "OBJECTIVES",
    "OPTIONS",
    "SOLVER_CACHE",
    "TIME_RANGE",
    "TORQUE_BAND_POINTS",
    "TORQUE_GRID_SIZES",
    "TORQUE_MARGIN",
    "TORQUE_POINTS_PER_PERIOD",
    "AutoStep",
    "OptimizedDesign",
    "StapDesign",
    "StapRequest",
    "TorqueLimit",
    "ZeroVibrationCandidate",
    "acceleration_limit",
    "band_ratios",
    "band_worst",
    "check_request",
    "closed_form",
    "design",
    "estimated_mode",
    "fits_torque",
    "lower_acceleration",
    "min_acceleration_time",
    "nodal_acceleration_limit",
    "optimize",
    "paper_delta_f",
    "paper_k_j_max",
    "torque_limit",
    "warm_up",
    "worst_torque_overshoot",
    "zero_vibration_candidates",
]
