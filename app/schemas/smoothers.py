"""Requests and responses of the smoothers family: /v1/profiles/smoother and /v1/identify."""

from __future__ import annotations

from typing import Any, ClassVar, Literal

from pydantic import Field

from app.schemas.common import OutModel, SampleTime, SampleValue, StrictModel, leaf, limit_given, never
from app.schemas.family import REST_TO_REST_ONLY, FamilyResponse, ProfileRequest
from app.schemas.plants import ModeOut
from models.commands import MIN_STEP_S
from models.smoothers import MAX_DURATION_S, MAX_REQUESTED_FILTERS, MIN_DURATION_S
from optim.families.smoother.family import SmootherOptions
from optim.families.smoother.smoothers import FilterSpec
from optim.problem import Problem
from optim.registry import FAMILIES

FAMILY = FAMILIES["smoother"]

FilterType = Literal["rectangular", "harmonic", "damped_harmonic", "exponential"]

_TYPE_DESCRIPTION = (
    "rectangular: M (eq. 1), impulse response 1/T; harmonic: S (eqs. 4-5), (pi/2T) sin(pi t/T); "
    "damped_harmonic: S_sigma (eqs. 10, 14), e^(sigma t) sin(pi t/T) with sigma = -zeta omega_n of the plant; "
    "exponential: M_sigma (the damped rectangular filter of Sec. V), e^(sigma t) on [0, T]."
)


class FilterIn(StrictModel):
    """One filter of the chain. Without ``duration_s`` it is tuned to the plant's first mode."""

    type: FilterType = Field(description=_TYPE_DESCRIPTION)
    duration_s: float | None = Field(
        None,
        ge=MIN_DURATION_S,
        le=MAX_DURATION_S,
        description="Length T of the impulse response, s. Omitted: 3 pi/Omega for harmonic and damped_harmonic "
        "(eq. 11), 2 pi/Omega for rectangular and exponential (Omega: the damped frequency). Vibration-free "
        "values are (2m+1) pi/Omega, m >= 1 (odd multiples only: eqs. 13 and 15 of the paper are wrong for "
        "even k) and 2 k pi/Omega respectively; the undamped filters cancel only an undamped mode.",
    )


class SmootherRequest(ProfileRequest):
    """A rest-to-rest move: a step of ``displacement`` filtered by a chain of FIR smoothers. The limits are
    designed for by rectangular filters (velocity, acceleration, jerk: eqs. 2, 3 and 6); a torque limit is
    checked on the result, not designed for."""

    filters: list[FilterIn] = Field(
        default_factory=lambda: [FilterIn(type="damped_harmonic")],
        max_length=MAX_REQUESTED_FILTERS,
        description="The vibration filters, in series. Rectangular filters that the limits need are added in "
        "front of them. Empty: a time-optimal chain of rectangular filters for the limits (eqs. 2-3). Default: one "
        "damped harmonic smoother tuned to the plant's first mode.",
    )
    discrete_sample_period_s: float | None = Field(
        None,
        ge=MIN_STEP_S,
        le=MAX_DURATION_S,
        description="A drive's sample period: also return the discrete filters (eq. 17) and what rounding "
        "N = T/Ts to an integer costs.",
    )

    UNSCHEMED_RULES: ClassVar[tuple[str, ...]] = (
        "discrete_sample_period_s: the discrete filters may span at most the service's sample cap "
        "(VIBFREE_MAX_SAMPLES) samples.",
    )

    @classmethod
    def move_rules(cls) -> list[dict[str, Any]]:
        return REST_TO_REST_ONLY

    @classmethod
    def schema_rules(cls) -> list[dict[str, Any]]:
        # no filter needs a limit to design the chain for (optim.families.smoother.smoothers.design_chain; the torque
        # is only checked)
        no_filter = leaf("filters", {"type": "array", "maxItems": 0}, {"minItems": 1})
        limits = (limit_given("max_velocity"), limit_given("max_acceleration"), limit_given("max_jerk"))
        return [*super().schema_rules(), never(no_filter, *(~limit for limit in limits))]

    def options(self, problem: Problem) -> SmootherOptions:
        return SmootherOptions(
            tuple(FilterSpec(f.type, f.duration_s) for f in self.filters), self.discrete_sample_period_s
        )


# --- response ------------------------------------------------------------------------------


class FilterOut(OutModel):
    type: FilterType
    duration_s: float
    decay_rate_1_s: float = Field(description="-sigma of the paper (>= 0): the impulse response decays as e^(-rate t).")
    role: Literal["limits", "tuned", "given"] = Field(
        description="limits: a rectangular filter added for the kinematic limits; tuned: duration from the plant; "
        "given: duration from the request."
    )
    vibration_free: bool | None = Field(
        description="Whether a zero of this filter sits on the plant's first mode (null: the plant has no mode)."
    )
    percent_residual_vibration: float | None = Field(
        description="100 |F(p)| at the first mode's pole p: the residual with this filter over the residual without "
        "it, at the same time after the end (Sec. IV's PRV)."
    )
    vibration_free_durations_s: list[float] = Field(
        description="The three shortest durations of this type that cancel the first mode exactly (none for the "
        "undamped types on a damped mode)."
    )


class DiscreteFilterOut(OutModel):
    type: FilterType
    samples: int = Field(description="N = round(T/Ts): the filter lasts N Ts.")
    duration_s: float = Field(description="N Ts: the duration the drive actually implements.")
    numerator: list[float] = Field(description="Coefficients of z^0, z^-1, ...: H(z) = gain * num(z^-1)/den(z^-1).")
    denominator: list[float]
    gain: float = Field(description="K of eq. (17): the static gain H(1) is exactly 1.")


class DiscreteOut(OutModel):
    sample_period_s: float
    filters: list[DiscreteFilterOut]
    lead_s: float = Field(
        description="Eq. (17) is a rectangle-rule sum: each harmonic/damped harmonic stage runs half a sample ahead "
        "of the continuous filter (rectangular and exponential stages are exact at the samples)."
    )
    max_deviation: float = Field(
        description="max_k |y[k] - q(k Ts + lead_s)|: how far the discrete output strays from "
        "the continuous profile once the lead is allowed for (motor units)."
    )
    percent_residual_vibration: float | None = Field(
        description="100 |D(e^(p Ts))| at the first mode's pole: the vibration left by rounding N (0 when N Ts = T)."
    )
    residual_amplitude: float = Field(
        description="Residual of the plant driven by the discrete output held linearly between samples (simulated)."
    )
    residual_fraction_of_move: float = Field(
        description="residual_amplitude / the load's move |G(0) displacement| (G(0) the plant's static gain)."
    )
    exact_sample_period_s: float | None = Field(
        description="The sample period nearest the requested one with N Ts = T for every vibration-free filter: "
        "at it the discrete chain cancels the mode exactly. Keeping Ts instead means running filters of "
        "duration_s = N Ts, with the residual above."
    )
    samples: int = Field(description="Samples of the discrete step response until it rests.")


class PeaksOut(OutModel):
    velocity: float | None
    acceleration: float | None
    jerk: float | None = Field(description="null where impulsive.")


class SmootherDesignOut(OutModel):
    filters: list[FilterOut] = Field(description="The chain, limit filters first (eq. 3 holds along it).")
    total_duration_s: float = Field(description="T_1 + ... + T_n: the motion's duration.")
    duration_s: float = Field(description="The same: the motion's duration.")
    continuous_derivatives: int = Field(description="The profile is of class C^k (each M adds 1, each S adds 2).")
    mode: ModeOut | None = Field(description="The plant's first mode, to which untimed filters are tuned.")
    vibration_free: bool | None = Field(description="Whether the chain cancels the first mode.")
    percent_residual_vibration: float | None = Field(description="100 |F(p)| of the whole chain (Sec. IV).")
    residual_amplitude_closed_form: float = Field(
        description="Residual envelope when the motion ends, from the chain's transfer function at the plant's "
        "poles (sum over modes): an independent check of metrics.residual_amplitude."
    )
    residual_fraction_of_move: float = Field(
        description="residual_amplitude_closed_form / the load's move |G(0) displacement| (G(0) the plant's static "
        "gain, e.g. lambda for belt_platform)."
    )
    residual_vibration: float = Field(
        description="The load's residual vibration amplitude after the command (metrics.residual_amplitude, the "
        "returned samples simulated on the plant) as a fraction of the load's move |G(0) displacement|: the same "
        "definition in every family."
    )
    sample_period_s: float = Field(
        description="Period of the returned profile: the requested one, divided by an integer when the filters are "
        "too fast for it (see warnings)."
    )
    commensurate_sample_period_s: float | None = Field(
        description="The sample period nearest sample_period_s at which every vibration-free filter lasts a whole "
        "number of samples: there even a linear hold on the returned position or velocity samples is "
        "vibration-free (the hold's transform is then eq. 17's sampled filter)."
    )
    hold_residual_fraction_of_move: float = Field(
        description="Residual left when the returned samples alone drive the plant, interpolated as a cam table "
        "with feed-forward does: the cubic Hermite curve through position and velocity (C^1 profiles), velocity "
        "and acceleration (C^2) or acceleration and jerk (C^3 and smoother); linear position for C^0. A fraction "
        "of the load's move |G(0) displacement|."
    )
    predicted_peaks: PeaksOut = Field(
        description="Peak |velocity|, |acceleration|, |jerk| by the design's closed forms."
    )
    discrete: DiscreteOut | None = None


class SmootherResponse(FamilyResponse):
    design: SmootherDesignOut  # type: ignore[assignment]


class IdentifyRequest(StrictModel):
    time_s: list[SampleTime] = Field(
        min_length=2, description="Strictly increasing sample times of the record, s (|t| <= 1e6)."
    )
    signal: list[SampleValue] = Field(
        min_length=2,
        description="The free vibration (e.g. the spring force or the load's deflection), any units and offset "
        "(|x| <= 1e12).",
    )


class FitOut(OutModel):
    r_squared: float = Field(description="Share of the record's variance the fitted damped sinusoid explains.")
    rms_residual: float = Field(description="RMS of the fit's residual (signal units): the noise level.")
    amplitude: float = Field(description="A of A e^(sigma t) cos(Omega t + phi) at the record's start.")
    offset: float
    periods: float = Field(description="Periods of the fitted oscillation in the record.")
    signal_to_noise: float = Field(description="amplitude / rms_residual.")
    damped_angular_frequency_std_rad_s: float = Field(description="Standard error of Omega.")
    decay_rate_std_1_s: float = Field(description="Standard error of the decay rate.")
    samples: int


class TwoPeakOut(OutModel):
    damped_angular_frequency_rad_s: float
    decay_rate_1_s: float


class SmootherOut(OutModel):
    type: Literal["damped_harmonic"]
    duration_s: float = Field(description="T = 3 pi/Omega = 1.5 T0 (eqs. 15-16).")
    decay_rate_1_s: float = Field(description="-sigma (eq. 16).")
    vibration_free_durations_s: list[float] = Field(description="3, 5 and 7 pi/Omega.")


class IdentifyResponse(OutModel):
    damped_angular_frequency_rad_s: float = Field(description="Omega (eq. 16: 2 pi/T0).")
    decay_rate_1_s: float = Field(description="-sigma >= 0: the envelope decays as e^(-rate t).")
    natural_frequency_rad_s: float = Field(description="omega_n = sqrt(sigma^2 + Omega^2).")
    natural_frequency_hz: float
    damping_ratio: float = Field(description="zeta = -sigma/omega_n.")
    damped_period_s: float = Field(description="T0 = 2 pi/Omega.")
    fit: FitOut
    two_peak_estimate: TwoPeakOut | None = Field(
        description="Eq. (16) from the first two maxima, for comparison (null if the record has no two)."
    )
    smoother: SmootherOut = Field(description="The damped harmonic smoother tuned to the identified mode.")
    plant: dict[str, Any] = Field(description="The identified mode as a plant object for /v1/profiles/smoother.")
    warnings: list[str]
