"""POST /v1/identify: the JSON free vibration (one damped sinusoid; app.schemas.smoothers) and the measured
record in CSV (modes with 95 % intervals, spectrum, quality, recommended design)."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from app.schemas.common import OutModel
from app.schemas.smoothers import IdentifyRequest, IdentifyResponse
from models.errors import InvalidParameter
from optim.identification.modal import MAX_MODES
from optim.problem import MAX_MOVE

__all__ = [
    "IdentifyMeasurementResponse",
    "IdentifyRequest",
    "IdentifyResponse",
    "IdentifySpectrumResponse",
    "MeasurementParams",
]


class MeasurementParams(BaseModel):
    """The query parameters of a CSV record: the move and limits a design is recommended for, and the fit's
    options. Without displacement or target_velocity, ``recommended`` is null. (Query strings are text: the
    numbers are parsed from it, unlike a JSON body's strict types; unknown parameters, NaN and infinities
    are refused.)"""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    displacement: float | None = Field(
        None, ge=-MAX_MOVE, le=MAX_MOVE, description="Rest-to-rest move to recommend a design for (rad or m)."
    )
    target_velocity: float | None = Field(
        None, ge=-MAX_MOVE, le=MAX_MOVE, description="Rest-to-velocity move to recommend a design for."
    )
    max_velocity: float | None = Field(None, ge=1e-6, le=1e12, description="limits.max_velocity of the design.")
    max_acceleration: float | None = Field(None, ge=1e-6, le=1e12, description="limits.max_acceleration.")
    max_jerk: float | None = Field(None, ge=1e-6, le=1e15, description="limits.max_jerk.")
    max_modes: int = Field(4, ge=1, le=MAX_MODES, description="The most modes fitted (the strongest peaks).")
    start_s: float | None = Field(
        None,
        ge=-1e9,
        le=1e9,
        description="Where the free vibration starts, s (default: where the command column last changes, else "
        "the record's largest excursion).",
    )
    command_column: str = Field(
        "command",
        min_length=1,
        max_length=64,
        description="The CSV column holding the known command the record responds to (when present): the fit "
        "starts where it last changes.",
    )
    format: Literal["auto", "generic", "klipper_raw", "klipper_psd", "rrf_accelerometer"] = Field(
        "auto",
        description="The CSV's format: klipper_raw (#time,accel_x,accel_y,accel_z: ACCELEROMETER_MEASURE, or a "
        "resonance test's raw_data), klipper_psd (freq,psd_x,psd_y,psd_z,psd_xyz: TEST_RESONANCES or "
        "SHAPER_CALIBRATE), rrf_accelerometer (Sample,X,Y,Z in g and a last line Rate <samples/s>, overflows <n>: "
        "RepRapFirmware's M956), generic (a time column and signals); auto tells it from the header.",
    )
    target: Literal["klipper", "reprapfirmware", "marlin"] | None = Field(
        None,
        description="The firmware to recommend an input shaper for (recommendation.shaper, max_acceleration, "
        "remaining_vibration_percent, smoothing, firmware), scored by Klipper's calibration criteria.",
    )
    square_corner_velocity: float = Field(
        5.0,
        ge=0.0,
        le=1000.0,
        description="mm/s: the printer's square_corner_velocity, which Klipper's smoothing and max_accel use "
        "(its calibrate_shaper.py default 5). Accelerations are read in mm/s^2, Klipper's unit.",
    )
    max_smoothing: float | None = Field(
        None,
        ge=0.05,
        le=10.0,
        description="mm: Klipper's max_smoothing ([resonance_tester], SHAPER_CALIBRATE MAX_SMOOTHING; at least "
        "0.05 as there): Klipper's pick is made under it, and no shaper smoothing more is recommended.",
    )
    frequency_tolerance: float | None = Field(
        None,
        ge=0.0,
        le=0.5,
        description="The share the resonances may differ from the measured ones (payload, position): the shaper "
        "is made robust over f x [1 - tol, 1 + tol]. Default: the measurement's own uncertainty.",
    )

    sweep_min_freq: float = Field(
        5.0, ge=1.0, le=300.0, description="Hz: the resonance test's min_freq (FREQ_START; Klipper's default 5)."
    )
    sweep_max_freq: float = Field(
        135.0,
        ge=1.0,
        le=300.0,
        description="Hz: the resonance test's max_freq (FREQ_END; Klipper's default 135 for x and y, 100 for z). A "
        "sweep's or a resonance CSV's modes are fitted with the test as the excitation, set by the sweep and "
        "sweeping parameters; those not given are read off a raw record, and are Klipper's defaults for a CSV.",
    )
    sweep_hz_per_sec: float = Field(
        1.0, gt=0.0, le=2.0, description="The resonance test's hz_per_sec (HZ_PER_SEC; Klipper's default 1)."
    )
    sweep_accel_per_hz: float = Field(
        60.0, gt=0.0, le=1e6, description="mm/s^2 per Hz: the test's accel_per_hz (ACCEL_PER_HZ; default 60, z 15)."
    )
    sweeping_accel: float = Field(
        400.0, gt=0.0, le=1e6, description="mm/s^2: the test's sweeping_accel (SWEEPING_ACCEL; default 400, z 50)."
    )
    sweeping_period: float = Field(
        1.2,
        ge=0.0,
        le=1e3,
        description="s: the test's sweeping_period (SWEEPING_PERIOD; default 1.2; 0 for none, and for Klipper "
        "releases before the sweeping test).",
    )

    def check(self) -> None:
        """At most one move (an InvalidParameter naming target_velocity otherwise), and a test that sweeps up."""
        if self.displacement is not None and self.target_velocity is not None:
            raise InvalidParameter(
                "target_velocity", self.target_velocity, "give at most one of displacement or target_velocity"
            )
        if self.sweep_max_freq < self.sweep_min_freq:
            raise InvalidParameter(
                "sweep_max_freq", self.sweep_max_freq, f"must be at least sweep_min_freq ({self.sweep_min_freq:g})"
            )

    def has_move(self) -> bool:
        return self.displacement is not None or self.target_velocity is not None


class ModalModeOut(OutModel):
    natural_frequency_hz: float
    damping_ratio: float
    natural_frequency_ci_hz: list[float] = Field(description="95 % interval [lo, hi]: estimate +- t(0.975, dof) SE.")
    damping_ratio_ci: list[float] = Field(description="95 % interval [lo, hi] (lo clipped at 0).")
    natural_frequency_std_hz: float = Field(description="Standard error of f_n (from the fit's covariance).")
    damping_ratio_std: float
    damped_frequency_hz: float
    decay_rate_1_s: float = Field(description="zeta omega_n: the envelope decays as exp(-rate t).")
    peak_frequency_hz: float = Field(description="The Welch spectrum's peak that started the fit.")
    amplitude: list[float] = Field(description="Per signal, at the fit window's start (signal units).")
    signal_to_noise: float = Field(description="sqrt(sum over signals of (amplitude / noise std)^2).")
    detection_snr: float = Field(
        description="sqrt(the mode's energy over the fit window / the noise variance): modes below 10 are dropped."
    )
    periods: float = Field(description="Damped periods in the fit window.")
    periods_above_noise: float = Field(description="Damped periods until the envelope falls to the noise's std.")
    samples_per_period: float


class SpectrumOut(OutModel):
    frequency_hz: list[float]
    psd: list[float] = Field(description="Welch PSD summed over the signals, (signal units)^2/Hz.")
    resolution_hz: float
    segment_samples: int
    window: str = Field(description="The Welch window (boxcar: the free vibration decays within a segment).")


class QualityOut(OutModel):
    sample_rate_hz: float
    nyquist_hz: float
    samples: int = Field(description="Samples in the record.")
    signals: list[str]
    fit_start_s: float = Field(description="Where the fitted free vibration starts.")
    fit_start_source: str = Field(
        description="command_end, start_s, largest_excursion, or residual_at_noise (after the largest excursion, "
        "where the fit's residual falls to the noise of the record's end: the excitation was still on before)."
    )
    fit_samples: int
    r_squared: float = Field(description="Share of the (noise-weighted) variance the fit explains.")
    noise_rms: list[float] = Field(description="Per signal: the fit's residual rms (signal units).")
    offsets: list[float] = Field(description="Per signal: the fitted constant.")
    degrees_of_freedom: int
    confidence: float
    t_quantile: float = Field(description="Student t quantile of the intervals.")
    alias_energy_fraction: float = Field(
        description="Share of the spectrum's power above its noise floor (its median) that lies above 0.8 f_Nyquist."
    )
    resampled: bool = Field(description="Whether the times were not uniform and the signals were interpolated.")


class RecommendedOut(OutModel):
    endpoint: str
    request: dict[str, Any] = Field(description="POST it to endpoint to get the design.")
    family: str
    label: str
    settling_time_s: float | None
    band_5_percent: list[float | None] | None
    frequency_ratio_interval: list[float] = Field(description="The interval the band covers, f/f_estimated.")


class RecommendedCandidateOut(OutModel):
    family: str
    label: str
    endpoint: str
    settling_time_s: float | None
    motion_time_s: float | None
    band_5_percent: list[float | None] | None
    covers: bool
    reason: str | None


class FirmwareShaperOut(OutModel):
    type: str = Field(description="The firmware's own name of the shaper type (RepRapFirmware: ei2, ei3).")
    frequency_hz: float
    damping_ratio: float


class KlipperCalibrationOut(OutModel):
    type: str
    frequency_hz: float
    max_acceleration: float = Field(description="mm/s^2: the acceleration whose smoothing is 0.12 mm.")
    remaining_vibration_percent: float
    smoothing: float = Field(description="mm at 5000 mm/s^2.")
    each_type: list[dict[str, Any]] = Field(description="Klipper's pick of each of its types.")


class RecommendationOut(OutModel):
    plant: dict[str, Any] | None = Field(description="The plant designed for: the lowest identified mode.")
    frequency_ratio_interval: list[float] | None = Field(
        description="The interval of f_true / f_measured the design or the shaper covers."
    )
    reason: str = Field(description="Why this design or shaper, or why none.")
    candidates: list[RecommendedCandidateOut]
    target: str | None = Field(None, description="With target: the firmware.")
    shaper: FirmwareShaperOut | None = Field(None, description="With target: the shaper to set.")
    max_acceleration: float | None = Field(
        None, description="mm/s^2: the largest acceleration whose smoothing stays within 0.12 mm (Klipper's rule)."
    )
    remaining_vibration_percent: float | None = Field(
        None, description="Klipper's remaining vibrations over the measured spectrum, percent."
    )
    robust_remaining_vibration_percent: float | None = Field(
        None, description="The same at its worst with the resonances shifted across frequency_ratio_interval."
    )
    smoothing: float | None = Field(None, description="mm at 5000 mm/s^2 and square_corner_velocity.")
    robust_over: dict[str, Any] | None = Field(
        None,
        description="With target: the frequency_ratio_interval the shaper is robust over, and its source "
        "(frequency_tolerance, the mode's 95 % interval, or the spectrum's resolution).",
    )
    klipper_calibration: KlipperCalibrationOut | None = Field(
        None, description="The shaper Klipper's own calibration picks from the same spectrum (the reference)."
    )
    dominates_klipper: bool | None = Field(
        None, description="No more remaining vibration and no lower max_acceleration than Klipper's pick."
    )
    firmware: dict[str, Any] | None = Field(
        None, description="The firmware blocks, as an input-shaped design's design.firmware."
    )
    response: dict[str, list[float]] | None = Field(
        None,
        description="With target: frequency_hz and psd_normalized (the spectrum scored, up to 200 Hz), and the "
        "recommended and Klipper's shapers' V there, at its worst over the damping ratios 0.075, 0.1 and 0.15.",
    )


class PeakOut(OutModel):
    frequency_hz: float
    damping_ratio_half_power: float = Field(description="The half-power width over twice the frequency.")
    frequency_interval_hz: list[float] = Field(description="Half a frequency bin either side.")


class PsdSpectrumOut(OutModel):
    frequency_hz: list[float]
    psd: list[float] = Field(description="Summed over the axes, (mm/s^2)^2/Hz.")
    psd_normalized: list[float] = Field(description="Divided by f + 0.1 (and cut below 10 Hz), as Klipper scores.")
    resolution_hz: float
    window: str


class SpectralModeOut(OutModel):
    natural_frequency_hz: float
    damping_ratio: float
    natural_frequency_ci_hz: list[float] = Field(description="95 % interval [lo, hi]: estimate +- 1.96 SE.")
    damping_ratio_ci: list[float] = Field(description="95 % interval [lo, hi] (lo clipped at 0).")
    natural_frequency_std_hz: float = Field(description="Standard error of f_n (the whitened fit's covariance).")
    damping_ratio_std: float
    relative_gain: float = Field(description="The mode's gain over the lowest-started mode's.")
    peak_frequency_hz: float = Field(description="Where the fit started: a PSD peak, or the bin of largest misfit.")


class SweepFitOut(OutModel):
    model: str = Field(description="What was fitted: the test's spectrum through the modes, per axis.")
    test: dict[str, float] = Field(
        description="The resonance test the model simulates: min_freq, max_freq, hz_per_sec, accel_per_hz, "
        "sweeping_accel, sweeping_period (as stated, else Klipper's defaults, else read off a raw record), and start_s "
        "(where it starts in a raw record, from its ridge; 0 for a CSV)."
    )
    reduced_chi_squared: float | None = Field(
        description="chi^2 / dof of the fit whitened by the spectrum's covariance: about 1 when the model holds."
    )
    bins: int = Field(description="PSD bins fitted per axis.")
    segments: int = Field(description="Welch segments the PSD averages (the test's own for a CSV).")
    simulations: int = Field(description="The test simulated through a mode (units of work).")


class IdentifySpectrumResponse(OutModel):
    """A Klipper resonance CSV, or a raw resonance test (a sweep): the spectrum, its peaks, and its modes fitted
    with the test as the excitation."""

    format: str
    excitation: str = Field(description="spectrum (a PSD file) or sweep (a raw resonance test).")
    spectrum: PsdSpectrumOut
    peaks: list[PeakOut]
    modes: list[SpectralModeOut] = Field(description="Lowest frequency first, with 95 % intervals.")
    fit: SweepFitOut
    recommended: RecommendedOut | None = Field(
        description="The fastest design whose 5 % band covers the lowest mode's interval (null: see recommendation)."
    )
    recommendation: RecommendationOut
    warnings: list[str]


class IdentifyMeasurementResponse(OutModel):
    format: str = Field("generic", description="The record's format (klipper_raw or generic).")
    modes: list[ModalModeOut] = Field(description="Lowest frequency first.")
    spectrum: SpectrumOut
    quality: QualityOut
    recommended: RecommendedOut | None = Field(
        description="The fastest design whose 5 % band covers the lowest mode's interval (null: see recommendation)."
    )
    recommendation: RecommendationOut
    warnings: list[str]
