"""Smoothers run by a drive at a fixed sample period (Biagiotti, Melchiorri and Moriello 2020, Sec. VI).

Each filter becomes its Z-transform at N = round(T/Ts) samples: eq. (17) for S_sigma,
K (z^-1 + e^(sigma N Ts) z^-(N+1)) / (1 - 2 e^(sigma Ts) cos(pi/N) z^-1 + e^(2 sigma Ts) z^-2), and its
analogues for the other kinds (models.smoothers.discrete_filter). The rounding of T to N Ts moves the
filter's zeros off the mode: ``design_discrete`` reports the residual it leaves, the half-sample lead of the
rectangle-rule sum and the exact alternative, a sample period with N Ts = T for every tuned filter
(``commensurate_sample_period_s``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from models.commands import PiecewiseCommand
from models.errors import InvalidParameter
from models.metrics import metrics
from models.plants import Mode, Plant
from models.simulation import simulate
from models.smoothers import (
    SINUSOIDAL,
    Chain,
    DiscreteFilter,
    discrete_filter,
    discrete_step_response,
    step_response,
)
from optim.families.smoother.filter_tuning import cancels

__all__ = ["DiscreteDesign", "commensurate_sample_period_s", "design_discrete"]


@dataclass(frozen=True)
class DiscreteDesign:
    sample_period_s: float
    filters: tuple[DiscreteFilter, ...]
    lead_s: float  # half a sample per sinusoidal stage (eq. 17 is a rectangle-rule sum)
    percent_residual_vibration: float | None  # 100 |D(e^(p Ts))| on the tuning mode
    residual_amplitude: float  # of the plant driven by the discrete output (first-order hold), simulated
    residual_fraction_of_move: float
    exact_sample_period_s: float | None  # a Ts with N Ts = T for every vibration-tuned filter
    max_deviation: float  # max_k |y_d[k] - q(k Ts + lead)|, motor units
    samples: int  # length of the discrete step response until it rests


def commensurate_sample_period_s(chain: Chain, mode: Mode | None, sample_period_s: float) -> float | None:
    """The sample period nearest ``sample_period_s`` with N Ts = T for every filter that cancels the
    mode (candidates: T_i/round(T_i/Ts) and (pi/Omega)/round(pi/(Omega Ts)), since tuned durations are
    multiples of pi/Omega); None when no filter cancels it.

    At such a period the discrete filters (eq. 17) cancel the mode, and so does a linear hold on the
    sampled velocity of the continuous profile: the hold's transform is the sampled impulse response's,
    whose aliases p + j 2 pi n/Ts all fall on zeros sigma + j (2m+1) pi/T of the tuned filter.
    """
    if mode is None:
        return None
    tuned = [f.duration_s for f in chain.filters if cancels(f, mode)]
    if not tuned:
        return None
    base = math.pi / mode.damped_frequency_rad_s
    candidates = [t / max(1, round(t / sample_period_s)) for t in (*tuned, base)]

    def exact(ts: float) -> bool:
        return all(abs(t / ts - round(t / ts)) <= 1e-9 * (t / ts) for t in tuned)

    good = [ts for ts in candidates if exact(ts)]
    return min(good, key=lambda ts: abs(ts - sample_period_s)) if good else None


def design_discrete(
    chain: Chain,
    plant: Plant,
    displacement: float,
    mode: Mode | None,
    sample_period_s: float,
    max_samples: int,
    field_name: str = "discrete_sample_period_s",
) -> DiscreteDesign:
    """Each filter at N = round(T/Ts) samples (eq. 17 and its analogues), the residual that rounding
    leaves, the half-sample lead, and the exact sample period."""
    ts = float(sample_period_s)
    counts = [max(1, round(f.duration_s / ts)) for f in chain.filters]
    for f, n in zip(chain.filters, counts, strict=True):
        if f.kind in SINUSOIDAL and n < 2:
            raise InvalidParameter(
                field_name, ts, f"must be at most half the {f.kind} filter's duration ({f.duration_s / 2:.6g} s)"
            )
    if sum(counts) + 2 > max_samples:
        raise InvalidParameter(
            field_name,
            ts,
            f"the discrete filters would span {sum(counts) + 2} samples; at most {max_samples} are allowed "
            f"(use a period >= {chain.total_duration_s / (max_samples - 2):.3g} s)",
        )
    filters = tuple(discrete_filter(f, ts, n) for f, n in zip(chain.filters, counts, strict=True))
    # The step response changes until sample sum(N_i): each stage's last tap is at N_i (zero for S, S_sigma).
    last = sum(counts)
    y = discrete_step_response(filters, displacement, last + 1)
    y[-1] = displacement  # the FIR chain has reached its static gain exactly; drop the IIR round-off
    t = ts * np.arange(last + 1)
    command = PiecewiseCommand.from_samples(t, y, 0, field="discrete")
    result = metrics(simulate(plant, command))
    lead = 0.5 * ts * sum(1 for f in chain.filters if f.kind in SINUSOIDAL)
    # The continuous profile, exact at k Ts + lead (the engine's samples, no interpolation).
    shifted = step_response(chain, displacement, ts, degree=0, offset_s=lead)
    on_grid = np.abs((shifted.time_s - lead) / ts - np.round((shifted.time_s - lead) / ts)) < 1e-6
    reference = np.full(t.size, float(displacement))
    k = np.round((shifted.time_s[on_grid] - lead) / ts).astype(int)
    inside = k < t.size
    reference[k[inside]] = shifted.position[on_grid][inside]
    prv = None
    if mode is not None:
        with np.errstate(over="ignore", invalid="ignore"):
            z = np.exp(np.array([mode.pole]) * ts)
            value = abs(np.prod([f.transfer(z)[0] for f in filters]))
        prv = 100.0 * float(value) if np.isfinite(value) else None
    return DiscreteDesign(
        sample_period_s=ts,
        filters=filters,
        lead_s=lead,
        percent_residual_vibration=prv,
        residual_amplitude=result.residual_amplitude,
        residual_fraction_of_move=result.residual_amplitude / plant.load_move(displacement),
        exact_sample_period_s=commensurate_sample_period_s(chain, mode, ts),
        max_deviation=float(np.max(np.abs(y - reference))),
        samples=last + 1,
    )
