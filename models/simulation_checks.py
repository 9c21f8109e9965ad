"""The checks of models.simulation's exact response: overflow, and round-off against the motion's size.

The real second-order form of a complex pole's recurrence rounds the pole's angle (``pair_roundoff``); the sum of
a quasi-static part and free responses that cancel keeps only eps times their size (``check_conditioning``)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from models.errors import InvalidParameter

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from models.commands import PiecewiseCommand
    from models.modal_data import FreeResponse, ModalForm

# Largest round-off the real second-order form may add to a pole's free response, relative to the load's
# motion, before the complex first-order recurrence is used instead (see ``pair_roundoff``).
PAIR_ROUNDOFF_RELATIVE = 1e-12
RELIABLE_RELATIVE = 1e-6  # largest round-off accepted, relative to the load's motion


def pair_roundoff(free: FreeResponse, weighted: complex, samples: int) -> float:
    """Estimated round-off of the real second-order form in |w r h| (Oppenheim & Schafer, Discrete-Time
    Signal Processing, 3rd ed., Sec. 6.8-6.9: coefficient quantisation and round-off noise of direct forms).
    Rounding 2 Re(z) moves the pole's angle by eps / Im(z) per step, which the free response (of size
    about |a| max|s| |1 - z|) accumulates over its memory (the samples, or 1 / (1 - |z|) steps of decay);
    each step's rounding, eps |s|, adds a free response of |a| eps |s|, summed at random over the memory."""
    eps = float(np.finfo(float).eps)
    memory = min(float(samples), 1.0 / max(1.0 - abs(free.decay), eps))
    angle = abs(1.0 - free.decay) * memory / abs(free.decay.imag)
    return abs(weighted) * free.bound * eps * (angle + math.sqrt(memory) + 4.0)


def check_finite(
    cmd: PiecewiseCommand,
    modal: ModalForm,
    free: tuple[FreeResponse, ...],
    motion: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]],
) -> None:
    """Refuse a load ``motion`` (position, velocity, acceleration) that overflows double precision. A bound on
    every output (the quasi-static sizes plus each pole's |c| max|h|) below 1e300 proves them finite without
    looking at the samples."""
    weighted = np.abs(modal.weights * modal.residues)
    bounds = [f.bound for f in free]
    for k, (name, arr) in enumerate(zip(("load position", "load velocity", "load acceleration"), motion, strict=True)):
        size = sum(abs(float(g)) * cmd.max_abs(m + k) for m, g in enumerate(modal.taylor) if g != 0.0)
        size += sum(float(w * abs(p) ** k) * b for w, p, b in zip(weighted, modal.poles, bounds, strict=True))
        if size < 1e300:
            continue
        if not (math.isfinite(float(arr.max())) and math.isfinite(float(arr.min()))):
            raise InvalidParameter("profile", "out of range", f"the {name} overflows double precision")


def quasi_static_size(command: PiecewiseCommand, modal: ModalForm) -> float:
    """sum_m |g_m| max |p^(m)|: the size of the quasi-static motion, the scale of round-off bounds."""
    return sum(abs(float(g)) * command.max_abs(m) for m, g in enumerate(modal.taylor) if g != 0.0)


def check_conditioning(
    command: PiecewiseCommand,
    modal: ModalForm,
    free: tuple[FreeResponse, ...],
    position: NDArray[np.float64],
    quasi_static_size: float,
) -> None:
    """Refuse a result that round-off could have spoilt.

    The load position is the sum of the quasi-static part sum_m g_m p^(m) (of size ``quasi_static_size``) and
    the free responses; when a mode is very slow next to how fast the command changes, both are huge
    (1/lambda^(m+1)) and cancel, and the sum keeps only eps times their size of accuracy.
    """
    eps = np.finfo(float).eps
    size = quasi_static_size + sum(
        abs(float(w)) * f.bound for w, f in zip(np.abs(modal.weights * modal.residues), free, strict=True)
    )
    scale = max(abs(modal.taylor[0]) * command.max_abs(0), 1e-300)
    if 16 * eps * size > RELIABLE_RELATIVE * scale:  # only then the load's own extent decides
        scale = max(scale, float(position.max()), -float(position.min()))
    if 16 * eps * size > RELIABLE_RELATIVE * scale:
        slowest = float(np.min(np.abs(modal.poles))) / (2 * np.pi)
        raise InvalidParameter(
            "plant",
            f"{slowest:.3g} Hz",
            f"the slowest pole ({slowest:.3g} Hz) is too slow for how fast this command changes: round-off would "
            f"reach {16 * eps * size / scale:.1e} of the motion; sample a slower command or check the plant",
        )
