"""The limits a closed-form STAP design works with (Cusimano 2022, Secs. 2-3).

f_n,e is the plant's first vibration mode; a_Max the acceleration limit: ``max_acceleration`` and,
for a two_inertia plant with ``max_torque_nm``, M/(J_M + J_L) (eq. 19) lowered for the torque
oscillation, the smaller. During t_c the load acceleration oscillates with amplitude |a_l,c| / a_max
given by eq. (57) and the motor torque with (J_L/J_M)/(1 + J_L/J_M) times it (eqs. 58-59). The
limit used is M / ((J_M + J_L) (1 + m)), m the worst eq. (59) over f_n / f_n,e in [1 - u, 1 + u]
for the design's k_j = f_n,e t_j: with u = 0.1 and J_L = J_M, m = 0.0546 and the limit is 0.948 of
eq. (19) (the paper rounds it to 0.94). A design "meets" a tolerance when its undamped SC
(Appendix B) stays below it over that band (``band_worst``).
"""

from __future__ import annotations

import numpy as np

from models.errors import InvalidParameter
from models.plants import Mode, Plant, TwoInertiaPlant
from models.stap import FloatArray, Stap, stap_sensitivity, torque_coefficient, worst_torque_overshoot
from models.stap_design import nodal_acceleration_limit
from optim.families.stap.types import StapRequest, TorqueLimit

BAND_POINTS = 401  # SC samples over the band for auto and the reported worst case
LIMIT_RTOL = 1e-9  # a peak within this fraction of a_Max counts as reaching it


def estimated_mode(plant: Plant) -> Mode:
    """The mode the STAP is designed for: the plant's first (lowest) vibration mode (f_n,e)."""
    modes = plant.modes()
    if not modes:
        raise InvalidParameter("plant", plant.kind, "the plant has no vibration mode to design the STAP for")
    return modes[0]


def torque_plant(request: StapRequest) -> TwoInertiaPlant:
    """The plant whose motor torque ``max_torque_nm`` limits: only a two_inertia plant defines it (eq. 58)."""
    plant = request.plant
    if not isinstance(plant, TwoInertiaPlant):
        raise InvalidParameter(
            "max_torque_nm",
            request.max_torque_nm,
            f"a {plant.kind} plant does not define the motor torque (two_inertia does)",
        )
    return plant


def no_acceleration_limit_error() -> InvalidParameter:
    """The error of a rule that needs a_Max (eq. 21) when the request gives none."""
    return InvalidParameter(
        "max_acceleration",
        None,
        "give max_acceleration and/or max_torque_nm (a_Max of eq. 21), or acceleration_time_s",
    )


def has_no_acceleration_limit(request: StapRequest) -> bool:
    """Neither max_acceleration nor max_torque_nm: no a_Max (eqs. 19, 21)."""
    return request.max_acceleration is None and request.max_torque_nm is None


def torque_limit(request: StapRequest, k_j: float) -> TorqueLimit | None:
    """The lowered acceleration limit of the module docstring, for a design with k_j = f_n,e t_j."""
    if request.max_torque_nm is None:
        return None
    plant = torque_plant(request)
    j_m, j_l = plant.motor_inertia_kgm2, plant.load_inertia_kgm2
    nodal = nodal_acceleration_limit(request.max_torque_nm, j_m, j_l)
    load, overshoot, rho = worst_torque_overshoot(k_j, j_l / j_m, request.frequency_uncertainty)
    factor = 1.0 / (1.0 + overshoot)
    return TorqueLimit(
        max_torque_nm=request.max_torque_nm,
        nodal_acceleration_limit=nodal,
        inertia_ratio=j_l / j_m,
        coefficient=torque_coefficient(j_l / j_m),
        load_acceleration_oscillation=load,
        torque_overshoot=overshoot,
        worst_frequency_ratio=rho,
        factor=factor,
        acceleration_limit=nodal * factor,
    )


def acceleration_limit(request: StapRequest, k_j: float) -> tuple[float | None, TorqueLimit | None]:
    """a_Max for a design with k_j = f_n,e t_j: the smaller of max_acceleration and the lowered
    torque-derived limit; None when neither is given."""
    torque = torque_limit(request, k_j)
    limits = [x for x in (request.max_acceleration, torque.acceleration_limit if torque else None) if x is not None]
    return (min(limits) if limits else None), torque


def band_ratios(uncertainty: float, points: int = BAND_POINTS) -> FloatArray:
    """f_n / f_n,e over [1 - u, 1 + u] (1 included), or just 1 when u = 0."""
    if uncertainty <= 0.0:
        return np.array([1.0])
    return np.union1d(np.linspace(1.0 - uncertainty, 1.0 + uncertainty, points), [1.0])


def band_worst(stap: Stap, frequency_hz: float, uncertainty: float) -> float:
    """The largest undamped SC (Appendix B) over the band."""
    return float(np.max(stap_sensitivity(stap, frequency_hz, band_ratios(uncertainty))))
