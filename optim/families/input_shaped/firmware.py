"""Firmware settings for a designed input shaper: Klipper, RepRapFirmware and Marlin.

Pure functions from the designed shaper (its name, impulses, modes and EI tolerance) to the text a
user pastes into the firmware, with the impulses that text makes the firmware apply, transcribed
from the firmware's own source, so that what differs from the design is measured, not assumed:

- Klipper: an ``[input_shaper]`` section (the X axis lines) with the closest built-in type. Types
  and formulas from klippy/extras/shaper_defs.py at Klipper3d/klipper commit 84104bbbd (master of
  2026-08-07); zv, mzv and zvd are the same in v0.13.0, whose ei, 2hump_ei and 3hump_ei (the
  undamped forms scaled by K) became damped polynomial fits in 5da026a (2025-09-22; the 3hump_ei fit
  had a typo until 0d1445a, 2026-03-31); the amplitudes are normalised to sum 1 as
  klippy/chelper/kin_shaper.c does. Syntax: docs/Config_Reference.md, ``[input_shaper]``
  (https://www.klipper3d.org/Config_Reference.html#input_shaper).
- RepRapFirmware: ``M593`` (https://docs.duet3d.com/User_manual/Reference/Gcodes#m593-configure-input-shaping).
  A named type where RRF's own impulses are ours (zvd, zvdd, zvddd), else ``P"custom"`` with the
  amplitudes and delays, at most 5 impulses (src/Movement/AxisShaper.{h,cpp}: MaxImpulses = 5). The
  meaning of H and T changed in 3.6.0: 3.6 takes the individual amplitudes of every impulse but the
  last and the cumulative delays of every impulse but the first; 3.4 and 3.5 the cumulative
  amplitudes and the durations between impulses. Both strings are given.
- Marlin: ``M493`` of Fixed-Time Motion V2 (bugfix-2.1.x with FT_MOTION; ``M493 V`` answers
  "FTM V2"; https://marlinfw.org/docs/gcode/M493.html), modes C1..C8 = ZV, ZVD, ZVDD, ZVDDD, EI,
  2HEI, 3HEI, MZV, frequency A within [FTM_MIN_SHAPE_FREQ, FTM_FS / 2], damping I within [0.01, 1],
  EI tolerance Q within [0, 1] (Marlin/src/gcode/feature/ft_motion/M493.cpp); amplitudes from
  Marlin/src/module/ft_motion/shaping.cpp, whose delays are whole samples of the FTM_FS = 1000 Hz
  trajectory (rounded half away from zero).

Every firmware block gives the residual the firmware's shaper leaves at the design frequency as a
percentage vibration: ``residual_percent`` in the definition of ``sensitivity.percentage_vibration``
(the design's own baseline shaped by the firmware's impulses, over the unshaped rigid command; the
caller supplies it), and ``shaper_residual_percent``, 100 V of the impulses alone (Sec. 3.1 of
Chatlatanagulchai & Pongpanich: the same number on a plain step).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from models.errors import InvalidParameter
from models.plants import Mode
from models.shapers import ImpulseSequence, percentage_vibration

ResidualPercent = Callable[[ImpulseSequence], float]

KLIPPER_VERSION = "Klipper master 84104bbbd (2026-08-07); zv, mzv and zvd also v0.13.0"
KLIPPER_DOCUMENTATION = (
    "https://www.klipper3d.org/Config_Reference.html#input_shaper",
    "https://github.com/Klipper3d/klipper/blob/84104bbbd7625d28b4eaaad83f4562972460ecd9/klippy/extras/shaper_defs.py",
)
RRF_VERSION = "RepRapFirmware 3.6 (command); 3.4 and 3.5 (command_3_5)"
RRF_DOCUMENTATION = (
    "https://docs.duet3d.com/User_manual/Reference/Gcodes#m593-configure-input-shaping",
    "https://github.com/Duet3D/RepRapFirmware/blob/3.6-dev/src/Movement/AxisShaper.cpp",
)
MARLIN_VERSION = "Marlin bugfix-2.1.x, Fixed-Time Motion V2 (FT_MOTION; M493 V answers FTM V2)"
MARLIN_DOCUMENTATION = (
    "https://marlinfw.org/docs/gcode/M493.html",
    "https://github.com/MarlinFirmware/Marlin/blob/bugfix-2.1.x/Marlin/src/module/ft_motion/shaping.cpp",
)

AXIS = "x"
KLIPPER_DEFAULT_V_TOL = 1.0 / 20.0  # shaper_defs.SHAPER_VIBRATION_REDUCTION = 20
# shaper_defs.INPUT_SHAPERS: the largest damping_ratio each type accepts
KLIPPER_MAX_DAMPING = {"zv": 0.99, "mzv": 0.99, "zvd": 0.99, "ei": 0.4, "2hump_ei": 0.3, "3hump_ei": 0.2}
RRF_MAX_IMPULSES = 5  # AxisShaper.h: MaxImpulses
# M593 F (AxisShaper.cpp, 3.4 to 3.6): from StepClockRate / (2 x 65535) to 1000 Hz. The step clock is 48 MHz / 64 =
# 750 kHz on every Duet 3 (RepRapFirmware.h), 120 MHz / 128 = 937.5 kHz on Duet 2 and Maestro: 5.72 and 7.15 Hz.
RRF_FREQUENCY_HZ = (750_000.0 / 131_070.0, 1000.0)
RRF_DUET2_MIN_FREQUENCY_HZ = 937_500.0 / 131_070.0
RRF_MAX_DAMPING = 0.99  # M593 S is limited to [0, 0.99]
MARLIN_MODES = {"zv": 1, "zvd": 2, "zvdd": 3, "zvddd": 4, "ei": 5, "2hump_ei": 6, "3hump_ei": 7, "mzv": 8}
MARLIN_FTM_FS_HZ = 1000.0  # FTM_FS, the trajectory rate (Configuration_adv.h default)
MARLIN_MIN_SHAPE_FREQ_HZ = 20.0  # FTM_MIN_SHAPE_FREQ (Configuration_adv.h default; a build may lower it)
MARLIN_ZETA = (0.01, 0.99)  # M493 I takes [0.01, 1]; at 1 shaping.cpp divides by sqrt(1 - zeta^2) = 0
RRF_NAMES = {"zvd": "zvd", "zvdd": "zvdd", "zvddd": "zvddd", "mzv": "mzv", "2hump_ei": "ei2", "3hump_ei": "ei3"}
SAME_TOLERANCE = 1e-7  # impulses equal to this (amplitudes; times relative to the duration): the same shaper
SIGNIFICANT_DIGITS = 10  # of every number written (relative error <= 5e-10, well inside SAME_TOLERANCE)
_CURVE_RATIOS = np.linspace(0.25, 1.75, 301)  # where two shapers' V curves are compared for "closest"


@dataclass(frozen=True)
class FirmwareSettings:
    """What one firmware is told (its type, frequency, damping) and the impulses it then applies."""

    kind: str
    frequency_hz: float
    damping_ratio: float
    impulses: ImpulseSequence


# ------------------------------------------------------------------------------------------
# Number formatting: fixed point, 10 significant digits, no exponent, no trailing zeros (40.0 -> "40")


def fixed(value: float, significant: int = SIGNIFICANT_DIGITS) -> str:
    """``value`` to ``significant`` digits in plain fixed-point notation (no exponent, no -0): 40.0 -> "40"."""
    v = float(value) + 0.0
    if v == 0.0 or not math.isfinite(v):
        return "0"
    decimals = min(max(significant - 1 - math.floor(math.log10(abs(v))), 0), 20)
    text = str(np.format_float_positional(v, precision=decimals, unique=True, trim="-"))
    return "0" if text in ("-0", "0.") else text


def rounded(value: float) -> float:
    """The number the firmware reads from ``fixed(value)``."""
    return float(fixed(value))


def _sequence(amplitudes: list[float], times_s: list[float]) -> ImpulseSequence:
    a = np.asarray(amplitudes, dtype=float)
    return ImpulseSequence(a / a.sum(), np.asarray(times_s, dtype=float))


# ------------------------------------------------------------------------------------------
# Klipper (klippy/extras/shaper_defs.py at 84104bbbd)


def _klipper_hump_fit(t: list[list[float]], a: list[list[float]], frequency_hz: float, zeta: float) -> ImpulseSequence:
    """_get_shaper_from_expansion_coeffs: cubic polynomials in zeta; times in undamped periods 1/f."""
    powers = np.array([1.0, zeta, zeta**2, zeta**3])
    return _sequence((np.array(a) @ powers).tolist(), (np.array(t) @ powers / frequency_hz).tolist())


def klipper_impulses(kind: str, frequency_hz: float, zeta: float) -> ImpulseSequence:
    """The impulses of Klipper's ``shaper_type`` at ``shaper_freq`` (the undamped frequency, Hz) and
    ``damping_ratio``, amplitudes normalised (kin_shaper.c): get_zv/mzv/zvd/ei/2hump_ei/3hump_ei_shaper."""
    df = math.sqrt(1.0 - zeta * zeta)
    big_k = math.exp(-zeta * math.pi / df)
    t_d = 1.0 / (frequency_hz * df)
    if kind == "zv":
        return _sequence([1.0, big_k], [0.0, 0.5 * t_d])
    if kind == "zvd":
        return _sequence([1.0, 2.0 * big_k, big_k**2], [0.0, 0.5 * t_d, t_d])
    if kind == "mzv":  # get_mzv_coeffs(3, 0.75) solves to (1 - 1/sqrt 2, sqrt 2 - 1, 1 - 1/sqrt 2); damped by K^i
        k_mzv = math.exp(-0.75 * zeta * math.pi / df)
        a1 = 1.0 - 1.0 / math.sqrt(2.0)
        return _sequence([a1, (math.sqrt(2.0) - 1.0) * k_mzv, a1 * k_mzv**2], [0.0, 0.375 * t_d, 0.75 * t_d])
    if kind == "ei":
        v, dr = KLIPPER_DEFAULT_V_TOL, zeta
        a1 = (0.24968 + 0.24961 * v) + ((0.80008 + 1.23328 * v) + (0.49599 + 3.17316 * v) * dr) * dr
        a3 = (0.25149 + 0.21474 * v) + ((-0.83249 + 1.41498 * v) + (0.85181 - 4.90094 * v) * dr) * dr
        t2 = (
            0.4999
            + (
                ((0.46159 + 8.57843 * v) * v)
                + (((4.26169 - 108.644 * v) * v) + ((1.75601 + 336.989 * v) * v) * dr) * dr
            )
            * dr
        )
        return _sequence([a1, 1.0 - a1 - a3, a3], [0.0, t2 * t_d, t_d])
    if kind == "2hump_ei":
        return _klipper_hump_fit(
            [[0.0] * 4, [0.49890, 0.16270, -0.54262, 6.16180], [0.99748, 0.18382, -1.58270, 8.17120],
             [1.49920, -0.09297, -0.28338, 1.85710]],
            [[0.16054, 0.76699, 2.26560, -1.22750], [0.33911, 0.45081, -2.58080, 1.73650],
             [0.34089, -0.61533, -0.68765, 0.42261], [0.15997, -0.60246, 1.00280, -0.93145]],
            frequency_hz, zeta,
        )  # fmt: skip
    if kind == "3hump_ei":
        return _klipper_hump_fit(
            [[0.0] * 4, [0.49974, 0.23834, 0.44559, 12.4720], [0.99849, 0.29808, -2.36460, 23.3990],
             [1.49870, 0.10306, -2.01390, 17.0320], [1.99960, -0.28231, 0.61536, 5.40450]],
            [[0.11275, 0.76632, 3.29160, -1.44380], [0.23698, 0.61164, -2.57850, 4.85220],
             [0.30008, -0.19062, -2.14560, 0.13744], [0.23775, -0.73297, 0.46885, -2.08650],
             [0.11244, -0.45439, 0.96382, -1.46000]],
            frequency_hz, zeta,
        )  # fmt: skip
    raise ValueError(f"not a Klipper shaper type: {kind}")


# ------------------------------------------------------------------------------------------
# RepRapFirmware (src/Movement/AxisShaper.cpp, AxisShaper::Configure, 3.6)


def rrf_impulses(kind: str, frequency_hz: float, zeta: float) -> ImpulseSequence:
    """The impulses RRF's ``M593 P"kind" F S`` applies (the same in 3.4 to 3.6; 3.6 rounds the delays to
    step clocks, < 2 us, left out). RRF's mzv is Klipper's reversed in time (a3 first), so with damping it
    is not Klipper's; its ei2 and ei3 are Klipper's hump fits with times in damped periods."""
    df = math.sqrt(1.0 - zeta * zeta)
    big_k = math.exp(-zeta * math.pi / df)
    t_d = 1.0 / (frequency_hz * df)
    derivatives = {"zvd": 2, "zvdd": 3, "zvddd": 4}
    if kind in derivatives:
        n = derivatives[kind]
        return _sequence([math.comb(n, i) * big_k**i for i in range(n + 1)], [0.5 * t_d * i for i in range(n + 1)])
    if kind == "mzv":
        k_mzv = math.exp(-zeta * 0.75 * math.pi / df)
        a1 = 1.0 - 0.5 * math.sqrt(2.0)
        return _sequence([a1 * k_mzv**2, (math.sqrt(2.0) - 1.0) * k_mzv, a1], [0.0, 0.375 * t_d, 0.75 * t_d])
    z = np.array([1.0, zeta, zeta**2, zeta**3])
    if kind == "ei2":
        a = np.array([[0.16054, 0.76699, 2.26560, -1.22750], [0.33911, 0.45081, -2.58080, 1.73650],
                      [0.34089, -0.61533, -0.68765, 0.42261]]) @ z  # fmt: skip
        t = np.array([[0.49890, 0.16270, -0.54262, 6.16180], [0.99748, 0.18382, -1.58270, 8.17120],
                      [1.49920, -0.09297, -0.28338, 1.85710]]) @ z  # fmt: skip
    elif kind == "ei3":
        a = np.array([[0.11275, 0.76632, 3.29160, -1.44380], [0.23698, 0.61164, -2.57850, 4.85220],
                      [0.30008, -0.19062, -2.14560, 0.13744], [0.23775, -0.73297, 0.46885, -2.08650]]) @ z  # fmt: skip
        t = np.array([[0.49974, 0.23834, 0.44559, 12.4720], [0.99849, 0.29808, -2.36460, 23.3990],
                      [1.49870, 0.10306, -2.01390, 17.0320], [1.99960, -0.28231, 0.61536, 5.40450]]) @ z  # fmt: skip
    else:
        raise ValueError(f"not a RepRapFirmware shaper type: {kind}")
    return _sequence([*a.tolist(), 1.0 - float(a.sum())], [0.0, *(t * t_d).tolist()])


# ------------------------------------------------------------------------------------------
# Marlin (Marlin/src/module/ft_motion/shaping.cpp: set_axis_shaping_A and set_axis_shaping_N)


def marlin_impulses(kind: str, frequency_hz: float, zeta: float, vtol: float) -> ImpulseSequence:
    """The impulses of Marlin's FTM shaper ``C<mode>`` at ``A`` Hz, damping ``I`` and tolerance ``Q``, with
    its delays in whole samples of FTM_FS (LROUND: half away from zero)."""
    big_k = math.exp(-zeta * math.pi / math.sqrt(1.0 - zeta * zeta))
    df = math.sqrt(1.0 - zeta * zeta)
    step_periods = 0.375 if kind == "mzv" else 0.5
    samples = math.floor(step_periods / frequency_hz / df * MARLIN_FTM_FS_HZ + 0.5)
    if kind in ("zv", "zvd", "zvdd", "zvddd"):
        n = len(kind) - 1
        amplitudes = [math.comb(n, i) * big_k**i for i in range(n + 1)]
    elif kind == "ei":
        a0 = 0.25 * (1.0 + vtol)
        amplitudes = [a0, 0.5 * (1.0 - vtol) * big_k, a0 * big_k**2]
    elif kind == "2hump_ei":
        v2 = vtol * vtol
        x = (v2 * (math.sqrt(1.0 - v2) + 1.0)) ** (1.0 / 3.0)
        a0 = (3.0 * x * x + 2.0 * x + 3.0 * v2) / (16.0 * x)
        amplitudes = [a0, (0.5 - a0) * big_k, (0.5 - a0) * big_k**2, a0 * big_k**3]
    elif kind == "3hump_ei":
        a0 = 0.0625 * (1.0 + 3.0 * vtol + 2.0 * math.sqrt(2.0 * (vtol + 1.0) * vtol))
        a1 = 0.25 * (1.0 - vtol) * big_k
        amplitudes = [a0, a1, (0.5 * (1.0 + vtol) - 2.0 * a0) * big_k**2, a1 * big_k**2, a0 * big_k**4]
    elif kind == "mzv":
        amplitudes = [1.0, math.sqrt(2.0) * big_k, big_k**2]
    else:
        raise ValueError(f"not a Marlin shaper type: {kind}")
    return _sequence(amplitudes, [i * samples / MARLIN_FTM_FS_HZ for i in range(len(amplitudes))])


# ------------------------------------------------------------------------------------------
# Comparison with the design


def same(first: ImpulseSequence, second: ImpulseSequence) -> bool:
    """The same impulses to SAME_TOLERANCE (amplitudes; times relative to the longer duration)."""
    if first.count != second.count:
        return False
    scale = max(first.duration_s, second.duration_s, 1e-300)
    return bool(
        np.max(np.abs(first.amplitudes - second.amplitudes)) <= SAME_TOLERANCE
        and np.max(np.abs(first.times_s - second.times_s)) <= SAME_TOLERANCE * scale
    )


def curve_distance(first: ImpulseSequence, second: ImpulseSequence, mode: Mode) -> float:
    """RMS difference of the two shapers' V (Sec. 3.1) over f/f_n in [0.25, 1.75] at the mode's damping."""
    w = _CURVE_RATIOS * mode.natural_frequency_rad_s
    z = np.full_like(w, mode.damping_ratio)
    diff = percentage_vibration(first, w, z) - percentage_vibration(second, w, z)
    return float(np.sqrt(np.mean(diff * diff)))


def closest(options: dict[str, ImpulseSequence], ours: ImpulseSequence, mode: Mode) -> str:
    """The option whose V curve is nearest ours (curve_distance)."""
    return min(options, key=lambda kind: curve_distance(options[kind], ours, mode))


def valid_options(build: Callable[[str], ImpulseSequence], kinds: tuple[str, ...]) -> dict[str, ImpulseSequence]:
    """The firmware types that are shapers at these settings: increasing times (which Klipper's kin_shaper.c
    checks) and positive amplitudes; the hump fits break down at their largest dampings."""
    options = {}
    for kind in kinds:  # a loop over six types
        try:
            impulses = build(kind)
        except InvalidParameter:
            continue
        if np.all(impulses.amplitudes > 0.0):
            options[kind] = impulses
    return options
