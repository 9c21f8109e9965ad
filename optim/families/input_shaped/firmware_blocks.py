"""The firmware blocks of a shaper design (``design.firmware``): what to paste into Klipper, RepRapFirmware and
Marlin, and the residual each firmware's own shaper leaves (the transcriptions are optim.families.input_shaped
.firmware's, with their sources)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypedDict

import numpy as np

from models.plants import Mode
from models.shapers import ImpulseSequence, percentage_vibration
from optim.families.input_shaped.firmware import (
    AXIS,
    KLIPPER_DEFAULT_V_TOL,
    KLIPPER_DOCUMENTATION,
    KLIPPER_MAX_DAMPING,
    KLIPPER_VERSION,
    MARLIN_DOCUMENTATION,
    MARLIN_FTM_FS_HZ,
    MARLIN_MIN_SHAPE_FREQ_HZ,
    MARLIN_MODES,
    MARLIN_VERSION,
    MARLIN_ZETA,
    RRF_DOCUMENTATION,
    RRF_DUET2_MIN_FREQUENCY_HZ,
    RRF_FREQUENCY_HZ,
    RRF_MAX_DAMPING,
    RRF_MAX_IMPULSES,
    RRF_NAMES,
    RRF_VERSION,
    FirmwareSettings,
    ResidualPercent,
    closest,
    fixed,
    klipper_impulses,
    marlin_impulses,
    rounded,
    rrf_impulses,
    same,
    valid_options,
)
from optim.families.input_shaped.shapers import ShaperDesign
from optim.results import Block


class _Residuals(TypedDict):
    """What every firmware block says of the residual its shaper leaves (module docstring of .firmware)."""

    exact: bool
    residual_percent: float
    shaper_residual_percent: float
    other_modes_shaper_residual_percent: tuple[float, ...]


@dataclass(frozen=True)
class KlipperSettings(Block):
    """The ``[input_shaper]`` section for the X axis."""

    firmware: str
    version: str
    documentation: tuple[str, ...]
    axis: str
    shaper_type: str
    shaper_freq_hz: float
    damping_ratio: float
    section: str
    exact: bool
    residual_percent: float
    shaper_residual_percent: float
    other_modes_shaper_residual_percent: tuple[float, ...]
    note: str | None


@dataclass(frozen=True)
class ReprapFirmwareSettings(Block):
    """``M593`` for RRF 3.6 (``command``) and 3.4/3.5 (``command_3_5``)."""

    firmware: str
    version: str
    documentation: tuple[str, ...]
    shaper_type: str
    frequency_hz: float
    damping_ratio: float
    command: str
    command_3_5: str
    exact: bool
    residual_percent: float
    shaper_residual_percent: float
    other_modes_shaper_residual_percent: tuple[float, ...]
    note: str | None


@dataclass(frozen=True)
class MarlinSettings(Block):
    """``M493`` of Fixed-Time Motion V2 for the X axis."""

    firmware: str
    version: str
    documentation: tuple[str, ...]
    axis: str
    shaper_mode: int
    frequency_hz: float
    damping_ratio: float
    vibration_tolerance: float | None
    command: str
    command_v1: str  # the same before FTM V2: X<mode> picks X's shaper (bugfix-2.1.x 485fbf20, 2025-01-28)
    exact: bool
    residual_percent: float
    shaper_residual_percent: float
    other_modes_shaper_residual_percent: tuple[float, ...]
    note: str


@dataclass(frozen=True)
class FirmwareReport(Block):
    """``design.firmware``: each firmware's settings, or why it has none for this design."""

    axis: str
    design_frequency_hz: float
    design_damping_ratio: float
    klipper: KlipperSettings
    reprapfirmware: ReprapFirmwareSettings | None
    reprapfirmware_reason: str | None
    marlin: MarlinSettings | None
    marlin_reason: str | None


def shaper_residual_percent(impulses: ImpulseSequence, mode: Mode) -> float:
    """100 V(omega_n, zeta) of the impulses alone (Sec. 3.1): the percentage vibration on a plain step."""
    return 100.0 * float(percentage_vibration(impulses, mode.natural_frequency_rad_s, mode.damping_ratio))


def _residuals(settings: FirmwareSettings, design: ShaperDesign, residual: ResidualPercent) -> _Residuals:
    mode = design.modes[0]
    others = tuple(shaper_residual_percent(settings.impulses, m) for m in design.modes[1:])
    return _Residuals(
        exact=same(settings.impulses, design.impulses),
        residual_percent=residual(settings.impulses),
        shaper_residual_percent=shaper_residual_percent(settings.impulses, mode),
        other_modes_shaper_residual_percent=others,
    )


def _multi_mode_note(design: ShaperDesign) -> str:
    if len(design.modes) < 2:
        return ""
    return (
        f"The design convolves shapers for {len(design.modes)} modes; this firmware shaper is set for the first "
        "mode only; other_modes_shaper_residual_percent is what it leaves at the others."
    )


# ------------------------------------------------------------------------------------------
# The three blocks


def klipper_block(design: ShaperDesign, residual: ResidualPercent) -> KlipperSettings:
    """The ``[input_shaper]`` section for the X axis (Klipper applies it per axis: copy the three lines
    with _y for a Y axis of the same mode) with the closest built-in type: the design's own name where
    Klipper has it, else the type whose V curve is nearest."""
    mode = design.modes[0]
    frequency = rounded(mode.natural_frequency_hz)
    zeta = mode.damping_ratio
    options = valid_options(
        lambda kind: klipper_impulses(kind, frequency, min(rounded(zeta), KLIPPER_MAX_DAMPING[kind])),
        tuple(KLIPPER_MAX_DAMPING),
    )
    kind = design.name if design.name in options else closest(options, design.impulses, mode)
    damping = min(rounded(zeta), KLIPPER_MAX_DAMPING[kind])
    settings = FirmwareSettings(kind, frequency, damping, options[kind])
    section = (
        f"[input_shaper]\nshaper_type_{AXIS}: {kind}\nshaper_freq_{AXIS}: {fixed(frequency)}\n"
        f"damping_ratio_{AXIS}: {fixed(damping)}\n"
    )
    residuals = _residuals(settings, design, residual)
    notes = []
    if kind != design.name and design.name in KLIPPER_MAX_DAMPING:
        notes.append(
            f"Klipper's {design.name} is no shaper at this damping (its fit's times or amplitudes break down): "
            f"{kind} is the built-in type whose V curve is nearest."
        )
    elif kind != design.name:
        notes.append(f"Klipper has no {design.name} shaper: {kind} is the built-in type whose V curve is nearest.")
    elif not residuals["exact"] and len(design.modes) == 1:
        notes.append(f"Klipper's {kind} is a polynomial fit in the damping ratio, not the designed {kind}.")
    if damping < rounded(zeta):
        notes.append(f"Klipper's {kind} accepts damping_ratio up to {damping:g}; the design's is {zeta:.6g}.")
    if kind == "ei" and design.vibration_tolerance is not None and design.vibration_tolerance != KLIPPER_DEFAULT_V_TOL:
        notes.append(
            f"plain ei uses a 5 % tolerance; Klipper master also takes ei(v_tol={design.vibration_tolerance:g}) "
            "(not v0.13.0)."
        )
    if kind == "3hump_ei":
        notes.append("3hump_ei as here needs Klipper from 0d1445a (2026-03-31): its damped fit had a typo before.")
    notes.append(_multi_mode_note(design))
    return KlipperSettings(
        firmware="Klipper",
        version=KLIPPER_VERSION,
        documentation=KLIPPER_DOCUMENTATION,
        axis=AXIS,
        shaper_type=kind,
        shaper_freq_hz=frequency,
        damping_ratio=damping,
        section=section,
        **residuals,
        note=" ".join(n for n in notes if n) or None,
    )


def _rrf_custom(impulses: ImpulseSequence) -> tuple[str | None, str, ImpulseSequence]:
    """M593 P"custom" for 3.6 (individual amplitudes H of all but the last, cumulative delays T of all but
    the first) and for 3.4/3.5 (cumulative amplitudes, durations between impulses), and what 3.6 applies.

    Two impulses in 3.6: a single T is padded to four values (GCodeBuffer::GetFloatArray), and RRF answers "Number
    of delays must be same as number of amplitudes". Without T it delays the second impulse by half the damped
    period of F and S, so F = 1 / (2 t_2) with S0 places it (None where that F is outside M593's range)."""
    a = [rounded(x) for x in impulses.amplitudes[:-1]]
    t = [rounded(x) for x in impulses.times_s[1:]]
    h36 = ":".join(fixed(x) for x in a)
    cumulative = np.cumsum(impulses.amplitudes[:-1])
    h35 = ":".join(fixed(x) for x in cumulative)
    t35 = ":".join(fixed(x) for x in np.diff(impulses.times_s))
    command_35 = f'M593 P"custom" H{h35} T{t35}'
    if len(t) == 1:
        frequency = rounded(0.5 / t[0])
        applied = ImpulseSequence(np.array([a[0], 1.0 - a[0]]), np.array([0.0, 0.5 / frequency]))
        low, high = RRF_FREQUENCY_HZ
        command = f'M593 P"custom" F{fixed(frequency)} S0 H{h36}' if low <= frequency <= high else None
        return command, command_35, applied
    applied = ImpulseSequence(np.array([*a, 1.0 - sum(a)]), np.array([0.0, *t]))
    return f'M593 P"custom" H{h36} T{":".join(fixed(x) for x in t)}', command_35, applied


def reprapfirmware_block(
    design: ShaperDesign, residual: ResidualPercent
) -> tuple[ReprapFirmwareSettings | None, str | None]:
    """``M593``: a named type where RRF's impulses are the design's, else the design's own impulses as
    P"custom" (up to 5), else the nearest named type; one shaper for every axis. (None, reason) where
    the design frequency is outside what M593 F takes."""
    mode = design.modes[0]
    low, high = RRF_FREQUENCY_HZ
    if not low <= mode.natural_frequency_hz <= high:
        return None, (
            f"M593 F takes {low:.4g} Hz (Duet 3; {RRF_DUET2_MIN_FREQUENCY_HZ:.4g} Hz on Duet 2 and Maestro: the step "
            f"clock over 131070) to {high:g} Hz; the design frequency is {mode.natural_frequency_hz:.6g} Hz"
        )
    frequency, zeta = rounded(mode.natural_frequency_hz), min(rounded(mode.damping_ratio), RRF_MAX_DAMPING)
    options = valid_options(
        lambda kind: rrf_impulses(kind, frequency, zeta), ("zvd", "zvdd", "zvddd", "mzv", "ei2", "ei3")
    )
    named = [kind for kind, impulses in options.items() if same(impulses, design.impulses)]
    note = None
    if named and zeta == rounded(mode.damping_ratio):
        kind = named[0]
        command = command_35 = f'M593 P"{kind}" F{fixed(frequency)} S{fixed(zeta)}'
        settings = FirmwareSettings(kind, frequency, zeta, options[kind])
    elif design.impulses.count <= RRF_MAX_IMPULSES:
        kind = "custom"
        custom, command_35, applied = _rrf_custom(design.impulses)
        if custom is None:
            return None, (
                f"two impulses {design.impulses.times_s[1]:.6g} s apart: RRF 3.6 places the second at half the "
                f"damped period of F, and F = {0.5 / design.impulses.times_s[1]:.6g} Hz is outside {low:.4g} to "
                f"{high:g} Hz (3.4 and 3.5 take {command_35})"
            )
        command = custom
        settings = FirmwareSettings(kind, frequency, zeta, applied)
        note = f"RRF's own {RRF_NAMES[design.name]} differs from the design here." if design.name in RRF_NAMES else None
        if design.impulses.count == 2:
            note = (
                "RRF 3.6 pads a single T to four delays and refuses it: the second impulse is placed by F (half "
                "the damped period of F with S0)."
            )
    else:
        mapped = RRF_NAMES.get(design.name)
        kind = mapped if mapped in options else closest(options, design.impulses, mode)
        command = command_35 = f'M593 P"{kind}" F{fixed(frequency)} S{fixed(zeta)}'
        settings = FirmwareSettings(kind, frequency, zeta, options[kind])
        note = (
            f'the design has {design.impulses.count} impulses, more than the {RRF_MAX_IMPULSES} P"custom" takes: '
            f"{kind} is the nearest named type."
        )
    if frequency < RRF_DUET2_MIN_FREQUENCY_HZ:
        note = (note or "") + (
            f" F{fixed(frequency)} needs a Duet 3 board: Duet 2 and Maestro take F from "
            f"{RRF_DUET2_MIN_FREQUENCY_HZ:.4g} Hz."
        )
    notes = [note or "", "" if kind == "custom" else _multi_mode_note(design)]
    block = ReprapFirmwareSettings(
        firmware="RepRapFirmware",
        version=RRF_VERSION,
        documentation=RRF_DOCUMENTATION,
        shaper_type=kind,
        frequency_hz=frequency,
        damping_ratio=zeta,
        command=command,
        command_3_5=command_35,
        **_residuals(settings, design, residual),
        note=" ".join(n for n in notes if n) or None,
    )
    return block, None


def marlin_block(design: ShaperDesign, residual: ResidualPercent) -> tuple[MarlinSettings | None, str | None]:
    """``M493 S1 X C<mode> A<Hz> I<zeta> [Q<vtol>]`` for the X axis, or (None, reason) where FTM has no
    such shaper (one shaper per axis: no convolved multi-mode design; ZV to ZVDDD, EI types, MZV) or the
    frequency is outside [FTM_MIN_SHAPE_FREQ, FTM_FS / 2] of a default build."""
    mode = design.modes[0]
    if len(design.modes) > 1:
        return None, "Marlin's Fixed-Time Motion sets one shaper per axis: it cannot apply shapers convolved for modes"
    if design.name not in MARLIN_MODES:
        return None, f"Marlin's Fixed-Time Motion has {', '.join(MARLIN_MODES)}, not {design.name}"
    top = MARLIN_FTM_FS_HZ / 2.0
    if not MARLIN_MIN_SHAPE_FREQ_HZ <= mode.natural_frequency_hz <= top:
        return None, (
            f"M493 A takes FTM_MIN_SHAPE_FREQ ({MARLIN_MIN_SHAPE_FREQ_HZ:g} Hz by default) to FTM_FS / 2 ({top:g} Hz); "
            f"the design frequency is {mode.natural_frequency_hz:.6g} Hz"
        )
    frequency = rounded(mode.natural_frequency_hz)
    low, high = MARLIN_ZETA
    zeta = min(max(rounded(mode.damping_ratio), low), high)
    vtol = design.vibration_tolerance if design.name in ("ei", "2hump_ei", "3hump_ei") else None
    mode_code = MARLIN_MODES[design.name]
    command = f"M493 S1 {AXIS.upper()} C{mode_code} A{fixed(frequency)} I{fixed(zeta)}"
    command_v1 = f"M493 S1 {AXIS.upper()}{mode_code} A{fixed(frequency)} I{fixed(zeta)}"
    if vtol is not None:
        vtol = rounded(vtol)
        command += f" Q{fixed(vtol)}"
        command_v1 += f" Q{fixed(vtol)}"
    impulses = marlin_impulses(design.name, frequency, zeta, KLIPPER_DEFAULT_V_TOL if vtol is None else vtol)
    settings = FirmwareSettings(design.name, frequency, zeta, impulses)
    notes = [
        f"Marlin delays the impulses by whole {1e3 / MARLIN_FTM_FS_HZ:g} ms samples "
        f"(FTM_FS = {MARLIN_FTM_FS_HZ:g} Hz): "
        f"{', '.join(fixed(1e3 * t) for t in impulses.times_s)} ms."
    ]
    if zeta != rounded(mode.damping_ratio):
        notes.append(
            f"I is written within {low:g} to {high:g} (M493 takes 0.01 to 1; at 1 Marlin's shaper divides by zero); "
            f"the design's damping ratio is {mode.damping_ratio:.6g}."
        )
    if design.name in ("mzv", "ei", "2hump_ei", "3hump_ei") and mode.damping_ratio > 0.0:
        notes.append(f"Marlin's damped {design.name} scales the undamped amplitudes by powers of K.")
    block = MarlinSettings(
        firmware="Marlin",
        version=MARLIN_VERSION,
        documentation=MARLIN_DOCUMENTATION,
        axis=AXIS,
        shaper_mode=MARLIN_MODES[design.name],
        frequency_hz=frequency,
        damping_ratio=zeta,
        vibration_tolerance=vtol,
        command=command,
        command_v1=command_v1,
        **_residuals(settings, design, residual),
        note=" ".join(notes),
    )
    return block, None


def firmware_block(design: ShaperDesign, residual: ResidualPercent | None = None) -> FirmwareReport:
    """``design.firmware``: the Klipper section, the RepRapFirmware M593 and the Marlin M493 of a shaper
    design, each with the residual its shaper leaves at the design frequency (``residual``: the design's
    percentage vibration of a sequence of impulses; default 100 V of the impulses, the value on a step)."""
    mode = design.modes[0]
    measure: ResidualPercent = residual if residual is not None else (lambda i: shaper_residual_percent(i, mode))
    reprap, reprap_reason = reprapfirmware_block(design, measure)
    marlin, marlin_reason = marlin_block(design, measure)
    return FirmwareReport(
        axis=AXIS,
        design_frequency_hz=mode.natural_frequency_hz,
        design_damping_ratio=mode.damping_ratio,
        klipper=klipper_block(design, measure),
        reprapfirmware=reprap,
        reprapfirmware_reason=reprap_reason,
        marlin=marlin,
        marlin_reason=marlin_reason,
    )
