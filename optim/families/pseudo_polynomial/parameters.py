"""A request's parameters for the pseudo-polynomial problem: its modes (Incerti eqs. 27-30), scaled at the start."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from models.errors import InvalidParameter
from models.plants import Plant, TwoInertiaPlant
from models.simulation import ModalForm, modal_form
from optim.families.pseudo_polynomial.problem import MAX_MODES, CompiledLaw, active_limits, compiled_problem
from optim.families.pseudo_polynomial.product_integration import product_weights
from optim.families.pseudo_polynomial.types import FloatArray, PseudoPolynomialRequest

__all__ = ["evaluate"]


def oscillatory_modal_form(plant: Plant) -> ModalForm:
    num, den = plant.load_transfer_function()
    modal = modal_form(num, den, 1)
    keep = modal.oscillatory
    if not np.any(keep):
        raise InvalidParameter("plant", plant.kind, "the plant has no vibration mode to suppress")
    if np.count_nonzero(keep) > MAX_MODES:
        raise InvalidParameter(
            "plant",
            f"{np.count_nonzero(keep)} modes",
            f"the pseudo-polynomial design handles up to {MAX_MODES} vibration modes",
        )
    return ModalForm(modal.taylor, modal.poles[keep], modal.residues[keep], modal.weights[keep])


def parameter_vector(
    request: PseudoPolynomialRequest, modal: ModalForm, compiled: CompiledLaw, gamma0: FloatArray
) -> FloatArray:
    lay = compiled.layout
    p = np.zeros(compiled.parameter_count)
    p[lay["phi"]] = request.displacement
    p[lay["T"]] = request.duration_s
    p[lay["gamma0"]] = gamma0
    if "plant" in lay:
        p[lay["plant"]] = request.plant.symbolic_parameter_values()
    else:
        p[lay["sigma"]] = -modal.poles.real
        p[lay["wd"]] = modal.poles.imag
        wr = modal.weights * modal.residues
        p[lay["wr_re"]] = wr.real
        p[lay["wr_im"]] = wr.imag
        inertia = request.plant.energy_inertia
        p[lay["mass"]] = inertia if inertia is not None and modal.poles.size == 1 else 1.0
        if isinstance(request.plant, TwoInertiaPlant):
            p[lay["torque"]] = [
                request.plant.motor_inertia_kgm2,
                request.plant.stiffness_nm_per_rad,
                request.plant.damping_nms_per_rad,
            ]
    quad = np.concatenate([product_weights(complex(pole) * request.duration_s) for pole in modal.poles])
    p[lay["quad_re"]], p[lay["quad_im"]] = quad.real, quad.imag
    p[lay["scale"]] = 1.0
    p[lay["energy_ref"]] = 1.0
    lim = request.limits
    p[lay["inv_limit"]] = [
        0.0 if x is None else 1.0 / x for x in (lim.max_velocity, lim.max_acceleration, lim.max_jerk, lim.max_torque_nm)
    ]
    return p


def prepare(request: PseudoPolynomialRequest) -> tuple[CompiledLaw, FloatArray, FloatArray]:
    """The compiled problem for a request, its parameter vector (scaled at the initial design)
    and the initial exponents."""
    modal = oscillatory_modal_form(request.plant)
    compiled = compiled_problem(
        request.order, modal.poles.size, active_limits(request.limits), request.caps, request.plant
    )
    gamma0 = np.sort(np.asarray(request.initial_exponents, dtype=float))
    p = parameter_vector(request, modal, compiled, gamma0)
    energy0, _, free0 = (np.asarray(v).ravel() for v in compiled.evaluate(gamma0, p))
    scales = np.hypot(free0[0::2], free0[1::2])
    p[compiled.layout["scale"]] = np.where(scales > 0, scales, 1.0)
    p[compiled.layout["energy_ref"]] = energy0[0] if energy0[0] > 0 else 1.0
    return compiled, p, gamma0


def evaluate(request: PseudoPolynomialRequest, exponents: FloatArray) -> tuple[float, float]:
    """Final energy and residual amplitude of given exponents (the optimiser's own model)."""
    compiled, p, _ = prepare(replace(request, initial_exponents=tuple(exponents)))
    energy, residual, _ = compiled.evaluate(np.asarray(exponents, dtype=float), p)
    return float(energy), float(residual)
