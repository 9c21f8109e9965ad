"""The CLI's human summaries of an answer (on stderr beside the JSON or the table): a design, a compare ranking,
an identification and its recommendation."""

from __future__ import annotations

from typing import Any

import orjson


def number(value: Any, unit: str = "") -> str:
    if value is None:
        return "-"
    text = f"{value:.4g}"
    return f"{text} {unit}".rstrip()


def band_text(band: Any) -> str:
    if not band:
        return "none"
    lo, hi = band
    return f"{number(lo)}..{number(hi)} x f_n"


def design_summary(family: str, answer: dict[str, Any]) -> str:
    """Duration, settling, residual and band of one design, a line each."""
    m = answer["metrics"]
    sensitivity = answer.get("sensitivity") or {}
    broken = "; ".join(answer.get("limit_violations", []))
    settling = number(m.get("settling_time_s"), "s") if m.get("settled") else "never (an undamped mode rings)"
    percent = number(m.get("percentage_vibration"), "%")
    band = band_text(sensitivity.get("band_5_percent")) if sensitivity else "(ask sensitivity to compute it)"
    lines = [
        f"{family}: {'limits met' if answer.get('limits_met') else 'LIMITS BROKEN: ' + broken}",
        f"  duration  {number(m.get('motion_time_s'), 's')}",
        f"  settling  {settling}",
        f"  residual  {number(m.get('residual_amplitude'))} (load units), V = {percent}",
        f"  band 5 %  {band}",
    ]
    lines += [f"  warning: {w}" for w in answer.get("warnings", [])]
    return "\n".join(lines)


def compare_summary(answer: dict[str, Any]) -> str:
    """One line per row, in the ranking's order, then what could not run."""
    head = f"{'design':28s} {'settling':>11s} {'duration':>11s} {'V %':>9s}  band 5 %"
    lines = [head]
    for row in answer["rows"]:
        settling = number(row["settling_time_s"], "s") if row["settling_time_s"] is not None else "never"
        lines.append(
            f"{row['label']:28s} {settling:>11s} {number(row['motion_time_s'], 's'):>11s} "
            f"{number(row['percentage_vibration']):>9s}  {band_text(row['band_5_percent'])}"
        )
    lines += [f"unavailable: {u['family']}: {u['reason']}" for u in answer.get("unavailable", [])]
    return "\n".join(lines)


def identify_summary(answer: dict[str, Any]) -> str:
    """The modes with their 95 % intervals, and the recommendation."""
    lines = []
    for mode in answer.get("modes") or []:
        lo, hi = mode.get("natural_frequency_ci_hz") or (None, None)
        zlo, zhi = mode.get("damping_ratio_ci") or (None, None)
        lines.append(
            f"mode {precise(mode['natural_frequency_hz'])} Hz (95 %: {precise(lo)}..{precise(hi)} Hz), "
            f"zeta {precise(mode['damping_ratio'])} (95 %: {precise(zlo)}..{precise(zhi)})"
        )
    for peak in [] if answer.get("modes") else answer.get("peaks") or []:
        lo, hi = peak["frequency_interval_hz"]
        lines.append(
            f"peak {precise(peak['frequency_hz'])} Hz ({precise(lo)}..{precise(hi)} Hz), "
            f"zeta ~ {precise(peak['damping_ratio_half_power'])} (half-power width)"
        )
    lines += [f"warning: {w}" for w in answer.get("warnings", [])]
    recommended = answer.get("recommended")
    recommendation = answer.get("recommendation") or {}
    reason = recommendation.get("reason", "")
    if recommendation.get("shaper"):
        lines += _shaper_lines(recommendation)
        if not recommended:
            return "\n".join(lines)
    if recommended:
        lines.append(
            f"recommended: {recommended.get('label', recommended['endpoint'])}, settling "
            f"{number(recommended.get('settling_time_s'), 's')}, "
            f"band 5 % {band_text(recommended.get('band_5_percent'))}"
        )
        lines.append(f"  ({reason})")
        lines.append(f"  POST {recommended['endpoint']}")
        lines.append("  " + orjson.dumps(recommended["request"]).decode())
    else:
        lines.append(f"no recommendation: {reason or 'give the move (--displacement or --target-velocity)'}")
    return "\n".join(lines)


def _shaper_lines(recommendation: dict[str, Any]) -> list[str]:
    """The firmware's shaper, Klipper's own pick beside it, and the text to paste."""
    shaper, klipper = recommendation["shaper"], recommendation["klipper_calibration"]
    blocks = recommendation["firmware"]
    text = {
        "klipper": (blocks.get("klipper") or {}).get("section"),
        "reprapfirmware": (blocks.get("reprapfirmware") or {}).get("command"),
        "marlin": (blocks.get("marlin") or {}).get("command"),
    }[recommendation["target"]]
    reason = blocks.get(f"{recommendation['target']}_reason")
    return [
        f"{recommendation['target']}: {shaper['type']} at {shaper['frequency_hz']:.1f} Hz (damping "
        f"{shaper['damping_ratio']:g}), max_accel {recommendation['max_acceleration']:.0f} mm/s^2, remaining "
        f"vibrations {recommendation['remaining_vibration_percent']:.2f} % "
        f"({recommendation['robust_remaining_vibration_percent']:.2f} % at worst over "
        f"{band_text(recommendation['robust_over']['frequency_ratio_interval'])}), smoothing "
        f"{recommendation['smoothing']:.3f} mm",
        f"  Klipper's calibration picks {klipper['type']} at {klipper['frequency_hz']:.1f} Hz: max_accel "
        f"{klipper['max_acceleration']:.0f} mm/s^2, remaining vibrations "
        f"{klipper['remaining_vibration_percent']:.2f} %",
        f"  ({recommendation['reason']})",
        (text or f"  (no {recommendation['target']} setting: {reason})").rstrip("\n"),
    ]


def precise(value: Any) -> str:
    return "-" if value is None else f"{value:.6g}"


def program_summary(answer: dict[str, Any]) -> str:
    """The cycle time, one line per move (its duration and each axis's residual at the stop, of its move), the
    recipes' cycle times, the warnings."""
    lines = [f"cycle {number(answer['cycle_time_s'], 's')}"]
    for move in answer["moves"]:
        residuals = ", ".join(f"{name} {_fraction(a['stop_residual_fraction'])}" for name, a in move["axes"].items())
        lines.append(
            f"move {move['index']:>3d} {move['coordination']:14s} {number(move['duration_s'], 's'):>11s}  "
            f"residual at the stop: {residuals}"
        )
    for row in answer.get("comparison", []):
        if row["cycle_time_s"] is None:
            lines.append(f"{row['method']:12s} no answer: {row['reason']}")
        else:
            lines.append(
                f"{row['method']:12s} cycle {number(row['cycle_time_s'], 's')} ({row['cycle_time_ratio']:.3f} x)"
            )
    lines += [f"warning: {w}" for w in answer.get("warnings", [])]
    return "\n".join(lines)


def _fraction(value: float | None) -> str:
    return "stays" if value is None else f"{value:.1e}"
