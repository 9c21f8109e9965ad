"""Design rules for trajectory smoothers (Biagiotti, Melchiorri and Moriello 2020).

- Kinematic limits: T_1 = |h|/v, T_i = q_max^(i-1)/q_max^(i) (eq. 2) under the ordering T_k >= sum_{i>k} T_i
  (eq. 3); where eq. 3 fails a bound is not reached and the level's peak is lowered until eq. 3 holds
  with equality (the time-optimal multi-segment law of the paper's ref. [8]). The harmonic filter's
  duration under limits is eq. (6).
- Vibration: a filter cancels a mode with pole sigma_p + j Omega when its zeros reach it. S and S_sigma
  have zeros at sigma +- j (2m+1) pi/T for m >= 1 (the first pair is cancelled by the filter's own poles),
  so T = (2m+1) pi/Omega, m >= 1, with sigma = -zeta omega_n for S_sigma (eqs. 11, 13, 15 as corrected in
  PAPER-NOTES: eqs. 13 and 15 allow T = 3 k pi/Omega, which is wrong for even k). M and M_sigma have zeros
  at sigma +- j 2 k pi/T: T = 2 k pi/Omega. The undamped filters cancel a damped mode only approximately.
- Both: the vibration filters are kept and rectangular filters are put in front of them, with eq. (3)
  extended to the whole chain, so every peak has a closed form (see ``design_chain``).
- Drives: eq. (17) at N = round(T/Ts), the residual caused by the rounding and the exact alternatives.
- Identification: the mode from a free vibration record (eq. 16), by a least-squares fit of a damped
  sinusoid (scipy.optimize.least_squares) rather than two peaks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import brentq, least_squares
from scipy.signal import find_peaks

from models.commands import PiecewiseCommand
from models.errors import Infeasible, InvalidParameter
from models.plants import Mode, Plant
from models.simulation import metrics, simulate
from models.smoothers import (
    DAMPED,
    MAX_DURATION_S,
    MIN_DURATION_S,
    SINUSOIDAL,
    Chain,
    DiscreteFilter,
    FilterKind,
    Smoother,
    StepResponse,
    discrete_filter,
    discrete_step_response,
    mode_residuals,
    refinement,
    residual_fraction,
    step_response,
)

VIBRATION_FREE_TOLERANCE = 1e-6  # |F(p)| below this: the filter's zero sits on the mode
_PEAK_SAMPLES = 4096  # samples of a fixed chain's step response when its peaks are measured
_MAX_PEAK_SAMPLES = 1 << 17  # bounds that work for chains mixing very different time scales


# ------------------------------------------------------------------------------------------
# Kinematic limits


@dataclass(frozen=True)
class Limits:
    """Bounds on |velocity|, |acceleration| and |jerk| of the motor command (None: unbounded)."""

    velocity: float | None = None
    acceleration: float | None = None
    jerk: float | None = None

    def by_order(self) -> tuple[float | None, float | None, float | None]:
        return self.velocity, self.acceleration, self.jerk

    @property
    def highest_order(self) -> int:
        """1 for velocity, 2 for acceleration, 3 for jerk; 0 when nothing is bounded."""
        orders = [k + 1 for k, value in enumerate(self.by_order()) if value is not None]
        return max(orders) if orders else 0


def _bracket_root(g, start: float) -> tuple[float, float]:
    """(lo, hi) with g(lo) > 0 >= g(hi), by factors of 4 from ``start`` (bounded search)."""
    hi = start
    for _ in range(400):
        if g(hi) <= 0.0:
            break
        hi *= 4.0
    else:
        raise Infeasible("the limits leave a level of the chain unbounded")
    lo = hi
    for _ in range(400):
        lo /= 4.0
        if g(lo) > 0.0:
            return lo, hi
    raise Infeasible("the limits admit no chain of rectangular filters")


def limited_durations_s(amount: float, caps: list[float], tail_s: float = 0.0) -> list[float]:
    """The shortest T_k..T_m of rectangular filters that take ``amount`` of derivative k-1 with the
    peak of derivative k+i at most caps[i], under T_j >= T_{j+1} + ... + T_m + tail_s (eq. 3; tail_s
    is the duration of the filters that follow).

    A peak that can be reached gives eq. (2), T_k = amount/cap. When it cannot (eq. 3 fails), the level's
    peak v is the root of amount/v = T_{k+1}(v) + ... + tail_s: the left side falls and the right side rises
    with v, so it is unique (scipy.optimize.brentq, on log v).
    """
    cap = caps[0]
    if len(caps) == 1:
        return [max(amount / cap if math.isfinite(cap) else 0.0, tail_s)]

    def rest(v: float) -> list[float]:
        return limited_durations_s(v, caps[1:], tail_s)

    if math.isfinite(cap):
        below = rest(cap)
        if amount / cap >= sum(below) + tail_s:
            return [amount / cap, *below]

    def g(v: float) -> float:
        return amount / v - sum(rest(v)) - tail_s

    lo, hi = _bracket_root(g, cap if math.isfinite(cap) else 1.0)
    log_v = brentq(lambda u: g(math.exp(u)), math.log(lo), math.log(hi), xtol=1e-15, rtol=4 * np.finfo(float).eps)
    v = math.exp(log_v)
    return [amount / v, *rest(v)]


def rectangular_durations_s(displacement: float, limits: Limits) -> tuple[float, ...]:
    """T_1..T_n of the time-optimal chain of n rectangular filters (eqs. 2-3), n = highest bounded order.

    v = 1, a = 2, j = 8 and h = 1 give (1, 0.5, 0.25) s.
    """
    order = limits.highest_order
    if order == 0:
        raise InvalidParameter("limits", "none", "give at least one of max_velocity, max_acceleration, max_jerk")
    caps = [value if value is not None else math.inf for value in limits.by_order()[:order]]
    return tuple(limited_durations_s(abs(displacement), caps))


def harmonic_duration_s(peak_n: float, limit_n1: float | None, limit_n2: float | None) -> float:
    """T_{n+1} of a harmonic filter after n rectangular ones whose output peaks at ``peak_n`` in its
    n-th derivative, so that derivatives n+1 and n+2 stay within their limits (eq. 6):
    max(pi/2 q^(n)/q^(n+1), sqrt(pi^2/2 q^(n)/q^(n+2)))."""
    candidates = []
    if limit_n1 is not None:
        candidates.append(0.5 * math.pi * peak_n / limit_n1)
    if limit_n2 is not None:
        candidates.append(math.sqrt(0.5 * math.pi**2 * peak_n / limit_n2))
    if not candidates:
        raise InvalidParameter("limits", "none", "eq. (6) needs a limit on derivative n+1 or n+2")
    return max(candidates)


# ------------------------------------------------------------------------------------------
# Vibration tuning


def tuned_duration_s(kind: FilterKind, mode: Mode, multiple: int = 1) -> float:
    """The shortest duration (multiple = 1) whose zeros reach the mode's damped frequency Omega:
    (2m+1) pi/Omega with m = multiple for S and S_sigma (eqs. 11, 13 corrected), 2 k pi/Omega with
    k = multiple for M and M_sigma."""
    if multiple < 1:
        raise InvalidParameter("multiple", multiple, "must be >= 1")
    omega = mode.damped_frequency_rad_s
    if kind in SINUSOIDAL:
        return (2 * multiple + 1) * math.pi / omega
    return 2 * multiple * math.pi / omega


def tuned_filter(kind: FilterKind, mode: Mode, duration_s: float | None = None) -> Smoother:
    """A filter tuned to the mode: its duration (unless given) and, for S_sigma and M_sigma, the decay
    rate sigma = -zeta omega_n (eq. 11)."""
    duration = tuned_duration_s(kind, mode) if duration_s is None else duration_s
    decay = mode.decay_rate_1_s if kind in DAMPED else 0.0
    return Smoother(kind, duration, decay)


def cancels(smoother: Smoother, mode: Mode, tolerance: float = VIBRATION_FREE_TOLERANCE) -> bool:
    """Whether a zero of the filter sits on the mode's pole: |F(p)| <= tolerance (the residual as a
    fraction of the unfiltered one, at the same time after the end)."""
    return same_time_ratio(Chain((smoother,)), mode) <= tolerance


def same_time_ratio(chain: Chain, mode: Mode) -> float:
    """|F(p)|: the residual envelope with the chain over the unfiltered one at the same time after the
    end (the percent residual vibration of Sec. IV, / 100); inf where it overflows (very long chains)."""
    with np.errstate(over="ignore", invalid="ignore"):
        value = residual_fraction(chain, mode.pole) * np.exp(-mode.pole.real * chain.total_duration_s)
    return float(value) if np.isfinite(value) else math.inf


def vibration_free_durations_s(kind: FilterKind, mode: Mode, count: int = 3) -> list[float]:
    """The ``count`` shortest durations of a filter of this kind that cancel the mode exactly.

    S_sigma: 3, 5, 7, ... pi/Omega (never an even multiple); M_sigma: 2, 4, 6, ... pi/Omega. The
    undamped S and M cancel only an undamped mode: none are offered when zeta > 0.
    """
    if kind not in DAMPED and mode.damping_ratio > 0.0:
        return []
    return [tuned_duration_s(kind, mode, k) for k in range(1, count + 1)]


# ------------------------------------------------------------------------------------------
# Chains meeting limits and suppression


@dataclass(frozen=True)
class FilterSpec:
    """A requested filter: its kind and duration (None: tuned to the plant's first mode)."""

    kind: FilterKind
    duration_s: float | None = None


@dataclass(frozen=True)
class ChainDesign:
    chain: Chain
    roles: tuple[str, ...]  # per filter: "limits" (designed for the limits), "tuned" or "given"
    mode: Mode | None  # the mode the filters are tuned to (the plant's first)
    predicted_peaks: tuple[float | None, float | None, float | None]  # |v|, |a|, |j| by the closed forms
    warnings: tuple[str, ...] = ()

    @property
    def total_duration_s(self) -> float:
        return self.chain.total_duration_s


def fixed_chain_peaks(filters: tuple[Smoother, ...]) -> tuple[float, float, float]:
    """c_q = sup |f^(q)| for q = 0, 1, 2, f the unit-area impulse response of the chain (inf where
    impulsive): the velocity, acceleration and jerk peaks of its unit step response.

    Measured on the exact step response (at least 4096 samples and |lambda| Ts <= 0.2, Taylor degree 7 in
    between, 16 points per piece): the relative error is below 1e-9 (and the peaks of the final profile are
    checked again). A closed form exists for one filter only (eq. 6 uses the harmonic's).
    """
    chain = Chain(filters)
    period = chain.total_duration_s / _PEAK_SAMPLES
    period = max(period / refinement(chain, period), chain.total_duration_s / _MAX_PEAK_SAMPLES)
    response = step_response(chain, 1.0, period)
    command = response.command()
    peaks = [command.peak_abs(q + 1) for q in range(3)]
    return tuple(math.inf if p is None else p * (1.0 + 1e-9) for p in peaks)  # type: ignore[return-value]


def _prefix_for(
    displacement: float, limits: Limits, fixed_s: float, peaks: tuple[float, float, float], m: int
) -> tuple[list[float], list[float | None]] | None:
    """m rectangular filters in front of the fixed ones (duration fixed_s, unit-step peaks ``peaks``)
    that keep every bounded derivative within its limit, or None when m filters cannot.

    With eq. (3) extended to the whole chain (T_k >= T_{k+1} + ... + T_m + fixed_s), the peak of
    derivative k is |h|/(T_1 ... T_k) for k <= m and |h| c_(k-m-1)/(T_1 ... T_m) above.
    """
    h = abs(displacement)
    bounds = limits.by_order()
    caps: list[float] = [b if b is not None else math.inf for b in bounds[:m]]
    ceiling = math.inf
    for k in range(m + 1, 4):  # derivatives carried by the fixed filters
        if bounds[k - 1] is not None:
            c = peaks[k - m - 1]
            ceiling = min(ceiling, bounds[k - 1] / c if c > 0 else math.inf)
    if m == 0:
        if ceiling < h:
            return None
        return [], [h * peaks[q] if math.isfinite(peaks[q]) else None for q in range(3)]
    if ceiling == 0.0:
        return None
    caps[m - 1] = min(caps[m - 1], ceiling)
    if not math.isfinite(caps[m - 1]) and fixed_s == 0.0:
        return None
    durations = limited_durations_s(h, caps, fixed_s)
    if not all(math.isfinite(t) and t > 0.0 for t in durations):
        return None
    predicted: list[float | None] = []
    product = 1.0
    for k in range(1, 4):
        if k <= m:
            product *= durations[k - 1]
            predicted.append(h / product)
        else:
            c = peaks[k - m - 1]
            predicted.append(h * c / product if math.isfinite(c) else None)
    return durations, predicted


def design_chain(plant: Plant, displacement: float, specs: list[FilterSpec], limits: Limits) -> ChainDesign:
    """The requested filters (tuned to the plant's first mode where no duration is given) preceded by
    the rectangular filters that the limits need: the shortest such chain satisfying eq. (3)."""
    if not (math.isfinite(displacement) and displacement != 0.0):
        raise InvalidParameter("displacement", displacement, "must be a finite, non-zero number")
    modes = plant.modes()
    mode = modes[0] if modes else None
    fixed: list[Smoother] = []
    roles: list[str] = []
    warnings: list[str] = []
    for i, spec in enumerate(specs):
        try:
            if mode is None and (spec.duration_s is None or spec.kind in DAMPED):
                what = "duration" if spec.duration_s is None else "decay rate"
                raise InvalidParameter(
                    "duration_s" if spec.duration_s is None else "type",
                    spec.duration_s if spec.duration_s is not None else spec.kind,
                    f"the plant has no vibration mode to take the {what} from",
                )
            fixed.append(tuned_filter(spec.kind, mode, spec.duration_s))  # type: ignore[arg-type]
        except InvalidParameter as exc:
            if exc.field == "decay_rate_1_s":  # the decay rate comes from the plant, not from the request
                exc = InvalidParameter(
                    "duration_s" if spec.duration_s is not None else "type",
                    spec.duration_s if spec.duration_s is not None else spec.kind,
                    f"{exc.rule}; the decay rate is the plant's ({exc.value:.6g} 1/s)",
                )
            raise exc.under(f"filters[{i}]") from None
        roles.append("tuned" if spec.duration_s is None else "given")
    if not fixed and limits.highest_order == 0:
        raise InvalidParameter(
            "filters", [], "give at least one filter, or a limit (max_velocity, max_acceleration, max_jerk)"
        )
    fixed_s = float(sum(f.duration_s for f in fixed))
    peaks = fixed_chain_peaks(tuple(fixed)) if fixed else (math.inf, math.inf, math.inf)
    best: tuple[float, list[float], list[float | None]] | None = None
    for m in range(0 if fixed else 1, limits.highest_order + 1):
        found = _prefix_for(displacement, limits, fixed_s, peaks, m)
        if found is None:
            continue
        durations, predicted = found
        total = sum(durations) + fixed_s
        if best is None or total < best[0] * (1 - 1e-12):
            best = (total, durations, predicted)
    if best is None:  # m = highest order always succeeds; kept for safety
        raise Infeasible("no chain of rectangular filters meets these limits", "limits")
    total, durations, predicted = best
    if total > MAX_DURATION_S:
        raise Infeasible(
            f"at these limits the move lasts {total:.4g} s, longer than the {MAX_DURATION_S:g} s a smoother may last",
            "limits",
        )
    prefix = []
    for t in sorted(durations, reverse=True):
        if t < MIN_DURATION_S:
            warnings.append(
                f"a limit needs a rectangular filter of {t:.3g} s; it is lengthened to {MIN_DURATION_S:g} s"
            )
            t = MIN_DURATION_S
        prefix.append(Smoother("rectangular", t))
    chain = Chain((*prefix, *fixed))
    return ChainDesign(chain, ("limits",) * len(prefix) + tuple(roles), mode, tuple(predicted), tuple(warnings))  # type: ignore[arg-type]


@dataclass(frozen=True)
class ChainResidual:
    """The residual vibration of a chain, in closed form (see models.smoothers.mode_residuals)."""

    amplitude: float  # sum over modes, load units, when the command ends
    fraction_of_move: float  # amplitude / the load's move |G(0) displacement|
    percent_residual_vibration: float | None  # 100 |F(p)| on the tuning mode (Sec. IV); None if it overflows
    vibration_free: bool | None  # the chain's zeros cancel the tuning mode; None without a mode


def chain_residual(chain: Chain, plant: Plant, displacement: float, mode: Mode | None) -> ChainResidual:
    amplitudes, _ = mode_residuals(chain, plant, displacement)
    total = float(np.sum(amplitudes))
    if mode is None:
        return ChainResidual(total, total / plant.load_move(displacement), None, None)
    prv = same_time_ratio(chain, mode)
    finite = math.isfinite(prv)
    return ChainResidual(
        total,
        total / plant.load_move(displacement),
        100.0 * prv if finite else None,
        bool(finite and prv <= VIBRATION_FREE_TOLERANCE),
    )


def hold_residual(step: StepResponse, plant: Plant) -> float:
    """Residual (fraction of the move) of the plant driven by the sampled profile alone, rebuilt the way a
    cam table with feed-forward interpolates it: the cubic Hermite curve through a quantity and its
    derivative, both continuous (position with velocity for a C^1 profile, velocity with acceleration for
    C^2, acceleration with jerk above), or a linear hold on the position for a C^0 profile.

    A hold on a quantity whose derivative jumps (the acceleration of S_sigma at T) cannot follow the jump
    between samples and leaves far more (figures in tests/models/test_smoothers.py).
    """
    smooth = step.chain.continuous_derivatives
    order, hold = (0, "linear") if smooth == 0 else (min(smooth - 1, 2), "cubic")
    initial = tuple(float(step.derivative(m)[0]) for m in range(order))
    slopes = step.derivative(order + 1) if hold == "cubic" else None
    command = PiecewiseCommand.from_samples(
        step.time_s, step.derivative(order), order, hold=hold, slopes=slopes, initial=initial
    )
    return metrics(simulate(plant, command)).residual_amplitude / plant.load_move(step.displacement)


# ------------------------------------------------------------------------------------------
# Discrete filters for drives


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


# ------------------------------------------------------------------------------------------
# Identification (Sec. V-A)

MIN_RECORD_SAMPLES = 16
MIN_PERIODS = 2.0
MIN_R_SQUARED = 0.5
MIN_SIGNAL_TO_NOISE = 3.0
MIN_SAMPLES_PER_PERIOD = 4.0


@dataclass(frozen=True)
class Identification:
    """A damped sinusoid A e^(sigma t) cos(Omega t + phi) + offset fitted to a free vibration."""

    damped_angular_frequency_rad_s: float  # Omega
    decay_rate_1_s: float  # -sigma >= 0
    amplitude: float
    offset: float
    r_squared: float
    rms_residual: float
    periods: float
    signal_to_noise: float
    frequency_std_rad_s: float
    decay_rate_std_1_s: float
    samples: int
    two_peak: tuple[float, float] | None  # (Omega, -sigma) by eq. (16), for comparison
    warnings: tuple[str, ...] = field(default=())

    @property
    def mode(self) -> Mode:
        omega_n = math.hypot(self.decay_rate_1_s, self.damped_angular_frequency_rad_s)
        return Mode(omega_n, self.decay_rate_1_s / omega_n)


def _refuse(reason: str, field_name: str = "signal", value: object = None) -> InvalidParameter:
    return InvalidParameter(field_name, value, reason)


def _initial_frequency(t: np.ndarray, y: np.ndarray) -> float:
    """The spectral peak of the record resampled on a uniform grid (Hann window, zero-padded FFT,
    parabolic interpolation of the peak)."""
    n = int(min(max(t.size, 64), 1 << 16))
    grid = np.linspace(t[0], t[-1], n)
    u = np.interp(grid, t, y)
    u = (u - np.mean(u)) * np.hanning(n)
    size = 8 * (1 << math.ceil(math.log2(n)))
    spectrum = np.abs(np.fft.rfft(u, size))
    spectrum[0] = 0.0
    k = int(np.argmax(spectrum))
    if 0 < k < spectrum.size - 1:
        a, b, c = spectrum[k - 1], spectrum[k], spectrum[k + 1]
        denom = a - 2 * b + c
        k = k + (0.5 * (a - c) / denom if denom != 0 else 0.0)
    dt = (grid[-1] - grid[0]) / (n - 1)
    return 2.0 * math.pi * k / (size * dt)


def two_peak_estimate(t: np.ndarray, y: np.ndarray, omega_guess: float) -> tuple[float, float] | None:
    """Eq. (16): T0 = t2 - t1 and sigma = ln(p2/p1)/T0 from the first two successive maxima of the
    record (offset removed by its median); returns (Omega, -sigma) or None when there are no two."""
    dt = float(np.median(np.diff(t)))
    distance = max(1, int(0.6 * (2 * math.pi / omega_guess) / dt))
    centred = y - np.median(y)
    peaks, _ = find_peaks(centred, distance=distance)
    peaks = peaks[centred[peaks] > 0]
    if peaks.size < 2:
        return None
    t1, t2 = t[peaks[0]], t[peaks[1]]
    p1, p2 = centred[peaks[0]], centred[peaks[1]]
    if t2 <= t1 or p2 <= 0:
        return None
    period = t2 - t1
    return 2 * math.pi / period, -math.log(p2 / p1) / period


def _basis(t: np.ndarray, sigma: float, omega: float) -> np.ndarray:
    envelope = np.exp(np.clip(sigma * t, -700.0, 700.0))
    return np.column_stack([envelope * np.cos(omega * t), envelope * np.sin(omega * t), np.ones_like(t)])


def identify(time_s: np.ndarray, signal: np.ndarray) -> Identification:
    """Omega and sigma of a free vibration (eq. 16's quantities) by least squares.

    The model y = e^(sigma t) (a cos Omega t + b sin Omega t) + c is linear in (a, b, c): for each
    (sigma, Omega) they are solved exactly (variable projection) and scipy.optimize.least_squares fits
    (sigma, Omega), started from the spectral peak and eq. (16)'s two-peak decay. Standard errors come
    from the full Jacobian at the optimum. A record is refused when it spans fewer than 2 periods, is
    sampled with fewer than 4 samples per period, or holds no oscillation clearly above its noise
    (R^2 < 0.5 or amplitude < 3 times the residual rms).
    """
    from models.commands import check_time_grid

    t_abs = check_time_grid(np.asarray(time_s, dtype=float), "time_s")
    y = np.asarray(signal, dtype=float)
    if y.shape != t_abs.shape:
        raise InvalidParameter("signal", f"{y.size} samples", f"must have as many samples as time_s ({t_abs.size})")
    if not np.all(np.isfinite(y)) or np.max(np.abs(y)) > 1e12:
        k = int(np.argmax(~np.isfinite(y) | (np.abs(y) > 1e12)))
        raise InvalidParameter(f"signal[{k}]", str(y[k]), "must be finite and within +-1e12")
    if t_abs.size < MIN_RECORD_SAMPLES:
        raise InvalidParameter("time_s", f"{t_abs.size} samples", f"needs at least {MIN_RECORD_SAMPLES} samples")
    t = t_abs - t_abs[0]
    spread = float(np.max(y) - np.min(y))
    if spread == 0.0:
        raise _refuse("the signal is constant: it holds no oscillation", value="constant")
    scale = spread / 2.0
    yn = (y - np.median(y)) / scale
    duration = float(t[-1])
    omega0 = _initial_frequency(t, yn)
    if not omega0 > 0.0:
        raise _refuse("the record holds no oscillation (no spectral peak)", value="no peak")
    peaks = two_peak_estimate(t, yn, omega0)
    decay0 = peaks[1] if peaks is not None and 0.0 <= peaks[1] < 10 * omega0 else 0.1 * omega0 / (2 * math.pi)

    def residual(params: np.ndarray) -> np.ndarray:
        basis = _basis(t, params[0], params[1])
        coef, *_ = np.linalg.lstsq(basis, yn, rcond=None)
        return basis @ coef - yn

    best = None
    for omega_start in (omega0, 0.97 * omega0, 1.03 * omega0):  # a few starts: the cost ripples in Omega
        fit = least_squares(
            residual,
            x0=np.array([-decay0, omega_start]),
            x_scale=np.array([max(decay0, 0.01 * omega0), omega0]),
            bounds=([-50.0 * omega0, 1e-3 * omega0], [10.0 * omega0 / max(duration * omega0, 1.0), 1e3 * omega0]),
            method="trf",
            xtol=1e-14,
            ftol=1e-14,
            gtol=1e-14,
            max_nfev=400,
        )
        if best is None or fit.cost < best.cost:
            best = fit
    assert best is not None
    sigma, omega = float(best.x[0]), float(best.x[1])
    basis = _basis(t, sigma, omega)
    (a, b, c), *_ = np.linalg.lstsq(basis, yn, rcond=None)
    fitted = basis @ np.array([a, b, c])
    res = yn - fitted
    ss_res = float(np.sum(res**2))
    ss_tot = float(np.sum((yn - np.mean(yn)) ** 2))
    r2 = 1.0 - ss_res / ss_tot if ss_tot > 0 else 0.0
    rms = math.sqrt(ss_res / t.size)
    amplitude = math.hypot(a, b)
    snr = amplitude / rms if rms > 0 else math.inf
    periods = omega * duration / (2 * math.pi)
    samples_per_period = 2 * math.pi / (omega * float(np.median(np.diff(t))))
    # Standard errors from the Jacobian of the full model in (sigma, Omega, a, b, c).
    env = np.exp(np.clip(sigma * t, -700.0, 700.0))
    cos, sin = np.cos(omega * t), np.sin(omega * t)
    osc = a * cos + b * sin
    jac = np.column_stack([t * env * osc, t * env * (-a * sin + b * cos), env * cos, env * sin, np.ones_like(t)])
    dof = max(1, t.size - 5)
    try:
        cov = np.linalg.inv(jac.T @ jac) * ss_res / dof
        sigma_std, omega_std = math.sqrt(max(cov[0, 0], 0.0)), math.sqrt(max(cov[1, 1], 0.0))
    except np.linalg.LinAlgError:
        sigma_std = omega_std = math.inf
    if r2 < MIN_R_SQUARED or snr < MIN_SIGNAL_TO_NOISE:
        raise _refuse(
            f"the record holds no damped oscillation clearly above its noise: the best damped sinusoid "
            f"explains {100 * max(r2, 0.0):.3g} % of its variance (at least {100 * MIN_R_SQUARED:g} % needed) "
            f"with an amplitude {snr:.3g} times the residual rms (at least {MIN_SIGNAL_TO_NOISE:g} needed)",
            value=f"{t.size} samples",
        )
    if samples_per_period < MIN_SAMPLES_PER_PERIOD:
        raise _refuse(
            f"the fitted oscillation ({omega:.6g} rad/s) has only {samples_per_period:.2g} samples per period; "
            f"at least {MIN_SAMPLES_PER_PERIOD:g} are needed (sample faster)",
            "time_s",
            f"{t.size} samples",
        )
    if periods < MIN_PERIODS:
        raise _refuse(
            f"the record spans {periods:.3g} periods of the fitted oscillation ({omega:.6g} rad/s); at least "
            f"{MIN_PERIODS:g} are needed",
            "time_s",
            f"{duration:.6g} s",
        )
    warnings: list[str] = []
    decay = -sigma
    if decay < 0.0:
        if -decay <= 3.0 * sigma_std:
            warnings.append(
                f"the fitted decay rate {decay:.3g} 1/s is negative but within 3 standard errors of 0: set to 0"
            )
            decay = 0.0
        else:
            raise _refuse(
                f"the oscillation grows (decay rate {decay:.4g} 1/s): not the free vibration of a stable plant",
                value=f"{t.size} samples",
            )
    two_peak = None
    if peaks is not None:
        two_peak = (float(peaks[0]), float(peaks[1]))
    return Identification(
        damped_angular_frequency_rad_s=omega,
        decay_rate_1_s=decay,
        amplitude=amplitude * scale,
        offset=float(c * scale + np.median(y)),
        r_squared=r2,
        rms_residual=rms * scale,
        periods=periods,
        signal_to_noise=snr,
        frequency_std_rad_s=omega_std,
        decay_rate_std_1_s=sigma_std,
        samples=int(t.size),
        two_peak=two_peak,
        warnings=tuple(warnings),
    )
