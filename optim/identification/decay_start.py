"""Where a free decay starts when nothing says so: after the excitation, found by the fit's own residual.

A record with neither a command column nor ``start_s`` is fitted from its largest excursion, which falls inside the
excitation when the excitation lasts longer than a fraction of a period (a knock of 2 x 20 ms on a 42 Hz mode:
43.06 Hz with zeta 0.31, its interval excluding the truth). The forced part is not a sum of damped sinusoids, so a
fit that starts inside it leaves a residual well above the noise, while one that starts in the free decay leaves
the noise alone. The noise is measured where the vibration is gone: the variance of the record's last TAIL share.
The fit is started at the largest excursion, then every half period of the record's lowest spectral peak after it
(at most STEPS more), and the first fit whose residual variance is within RESIDUAL_LIMIT times the tail's is the
answer. Where none is, the largest excursion's fit is kept, with a warning. (A record that rings to its end has a
tail louder than its noise: the first fit passes, as before.)
"""

from __future__ import annotations

import numpy as np

from models.errors import InvalidParameter
from optim.identification.modal import ModalIdentification, identify_modes
from optim.identification.record import Record

__all__ = ["RESIDUAL_LIMIT", "STEPS", "identify_free_decay"]

STEPS = 8  # half periods of the lowest spectral peak tried after the largest excursion (4 periods)
TAIL = 0.2  # the record's last share, where the noise is measured
# a free decay's fit leaves the noise: residual / tail variance 0.98 to 1.02 on the knocks of
# tests/optim/test_decay_start.py; started inside the excitation, 1.8 to 14
RESIDUAL_LIMIT = 1.1


def _residual_ratio(fit: ModalIdentification, tail_variance: float) -> float:
    return float(np.sum(np.square(fit.noise_rms))) / tail_variance if tail_variance > 0 else 1.0


def identify_free_decay(record: Record, *, max_modes: int = 4, start_s: float | None = None) -> ModalIdentification:
    """optim.identification.modal.identify_modes, from the free decay's start found as the module says where the
    record has no command and no ``start_s``."""
    first = identify_modes(record, max_modes=max_modes, start_s=start_s)
    if start_s is not None or record.command is not None:
        return first
    signals = np.atleast_2d(np.asarray(record.signals, float))
    tail = signals[:, int((1.0 - TAIL) * signals.shape[1]) :]
    tail_variance = float(np.sum(np.var(tail, axis=1)))
    ratio = _residual_ratio(first, tail_variance)
    if ratio <= RESIDUAL_LIMIT:
        return first
    step_s = 0.5 / min(m.peak_frequency_hz for m in first.modes)
    for k in range(1, STEPS + 1):
        try:
            fit = identify_modes(record, max_modes=max_modes, start_s=first.window_start_s + k * step_s)
        except InvalidParameter:  # (too little left, or no clear vibration from there: a later start may fit)
            continue
        if _residual_ratio(fit, tail_variance) <= RESIDUAL_LIMIT:
            note = (
                f"the fit starts {fit.window_start_s - first.window_start_s:.4g} s after the largest excursion, where "
                f"its residual falls to the record's noise (from the excursion it was {ratio:.3g} times the noise: "
                "the excitation was still on)"
            )
            return ModalIdentification(
                **{**vars(fit), "window_source": "residual_at_noise", "warnings": (*fit.warnings, note)}
            )
    note = (
        f"the fit's residual is {ratio:.3g} times the noise of the record's end, and so from every start up to "
        f"{STEPS / 2:g} periods later: the excitation may still be on where the fit starts, or the record is no free "
        "decay (give start_s, or the command as a column)"
    )
    return ModalIdentification(**{**vars(first), "warnings": (*first.warnings, note)})
