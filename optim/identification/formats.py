"""The CSV formats a printer's user has, told from the header (or named), and Klipper's resonance CSV read.

- ``klipper_raw``: Klipper's accelerometer record, ``#time,accel_x,accel_y,accel_z`` (ACCELEROMETER_MEASURE, and
  the raw data TEST_RESONANCES writes with ``RAW_DATA``: klippy/extras/adxl345.py, ``write_to_file``), times in s
  printed ``%.6f``, accelerations in mm/s^2: a time record (optim.identification.record_csv).
- ``klipper_psd``: the resonance test's output, ``freq,psd_x,psd_y,psd_z,psd_xyz`` and one ``name(freq)`` column
  per shaper it tried (klippy/extras/shaper_calibrate.py, ``save_calibration_data``): the power spectral density
  of the measured acceleration, (mm/s^2)^2/Hz, per axis and summed.
- ``rrf_accelerometer``: RepRapFirmware's accelerometer CSV (M956: src/Accelerometers/Accelerometers.cpp, 3.5 and
  3.6): ``Sample,X,Y,Z`` (the axes recorded), rows ``n,x,y,z`` in g numbered from 0, and a last line
  ``Rate <samples/s>, overflows <count>`` (the rate measured): a time record, t = n / rate, in mm/s^2.
- ``generic``: a time column (``time_s`` or the first) and signal columns.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from models.errors import InvalidParameter
from optim.identification.record import Record
from optim.identification.record_csv import parse_record_csv

__all__ = ["FORMATS", "PsdRecord", "RecordFormat", "detect_format", "parse_psd_csv", "parse_rrf_csv"]

RecordFormat = Literal["generic", "klipper_raw", "klipper_psd", "rrf_accelerometer"]
FORMATS: tuple[str, ...] = ("auto", "generic", "klipper_raw", "klipper_psd", "rrf_accelerometer")
G_MM_S2 = 9806.65  # standard gravity, mm/s^2 (Klipper's accelerometers' unit)
TAIL_CHARS = 200  # RRF's last line is looked for within this many characters of the end
_RRF_RATE = re.compile(r"Rate\s+(\d+)\s*,\s*overflows\s+(\d+)\s*$")
_RRF_FAILURES = ("Failed to", "Received bad data", "Received mismatched data")
PSD_AXES = ("psd_x", "psd_y", "psd_z")
RAW_COLUMNS = ("time", "accel_x", "accel_y", "accel_z")
MAX_HEADER_CHARS = 4096  # the header is looked at within this many characters of the body's start


@dataclass(frozen=True)
class PsdRecord:
    """A measured power spectral density: frequencies (Hz, increasing), the sum over the axes, and each axis."""

    frequency_hz: NDArray[np.float64]
    psd: NDArray[np.float64]  # summed over the axes, (signal units)^2 / Hz
    axes: dict[str, NDArray[np.float64]]
    normalized: bool  # written normalised to frequencies (SHAPER_CALIBRATE's file: it has the shapers' columns)


def _header_names(text: str) -> list[str]:
    head = text[:MAX_HEADER_CHARS].removeprefix("\ufeff")
    for line in head.splitlines():
        if line.strip():
            return [name.strip().lower() for name in line.strip().removeprefix("#").split(",")]
    return []


def detect_format(text: str) -> RecordFormat:
    """The format of a CSV body from its header: ``freq`` then other columns is Klipper's resonance CSV,
    ``time,accel_x,accel_y,accel_z`` its accelerometer record, anything else generic."""
    names = _header_names(text)
    if names[:1] == ["freq"] and len(names) > 1:
        return "klipper_psd"
    if tuple(names[:4]) == RAW_COLUMNS:
        return "klipper_raw"
    if names[:1] == ["sample"] and 1 < len(names) <= 4 and set(names[1:]) <= {"x", "y", "z"}:
        return "rrf_accelerometer"
    return "generic"


def _without_shapers(text: str) -> tuple[str, bool]:
    """The CSV without the shapers' columns Klipper appends (master: a ``shapers:`` column, empty, then one per
    shaper; v0.13.0: the ``name(freq)`` columns alone), and whether it had any (the file is then SHAPER_CALIBRATE's,
    its PSD normalised)."""
    names = _header_names(text)
    first = next((k for k, name in enumerate(names) if name == "shapers:" or "(" in name), None)
    if first is None:
        return text, False
    lines = text.removeprefix("\ufeff").splitlines()
    return "\n".join(",".join(line.split(",", first)[:first]) for line in lines), True


def parse_psd_csv(text: str, *, max_rows: int) -> PsdRecord:
    """Klipper's resonance CSV (see the module): the frequency column and the PSD columns (the shapers' columns
    are the shapers Klipper tried: not read). The total is ``psd_xyz`` where given (Klipper's psd_sum), else the sum
    of the axes given. Every PSD must be >= 0 and the frequencies increase strictly (named by column and row)."""
    text, normalized = _without_shapers(text)
    record = parse_record_csv(text, max_rows=max_rows, max_signals=64, command_column="")
    names = [name.lower() for name in record.names]
    columns = {name: record.signals[i] for i, name in enumerate(names)}
    axes = {name: columns[name] for name in PSD_AXES if name in columns}
    total = columns.get("psd_xyz")
    if total is None and not axes:
        raise InvalidParameter(
            "header",
            ",".join(record.names)[:80],
            "a PSD CSV needs psd_xyz or psd_x, psd_y, psd_z (a calibration CSV of several datasets, one column "
            "each, is not read: send each dataset's own CSV)",
        )
    for name, values in {**axes, **({"psd_xyz": total} if total is not None else {})}.items():
        negative = np.flatnonzero(values < 0)
        if negative.size:
            k = int(negative[0])
            raise InvalidParameter(f"{name}[{k}]", float(values[k]), "a power spectral density must be >= 0")
    if float(record.time_s[0]) < 0:
        raise InvalidParameter("freq[0]", float(record.time_s[0]), "frequencies must be >= 0 Hz")
    psd = total if total is not None else np.sum(np.vstack(list(axes.values())), axis=0)
    return PsdRecord(np.asarray(record.time_s, float), np.asarray(psd, float), axes, normalized)


def parse_rrf_csv(text: str, *, max_rows: int) -> tuple[Record, list[str]]:
    """RepRapFirmware's accelerometer CSV (see the module) as a record, t = n / rate (the rate of its last line),
    accelerations in mm/s^2 (x 9806.65); warnings (FIFO overflows: samples lost, their times off)."""
    body = text.rstrip()
    tail = body[-TAIL_CHARS:]
    failure = next((f for f in _RRF_FAILURES if f in tail), None)
    if failure is not None:
        line = tail[tail.index(failure) :].splitlines()[0]
        raise InvalidParameter("body", line[:80], "RepRapFirmware reported that the recording failed")
    match = _RRF_RATE.search(tail)
    if match is None:
        raise InvalidParameter(
            "body", tail[-40:], "RepRapFirmware's accelerometer CSV ends with 'Rate <samples/s>, overflows <n>'"
        )
    rate, overflows = int(match.group(1)), int(match.group(2))
    if rate <= 0:
        raise InvalidParameter("body", match.group(0), "the recorded rate is 0: the accelerometer measured nothing")
    start = len(body) - len(tail) + match.start()
    record = parse_record_csv(body[:start], max_rows=max_rows, command_column="")
    names = tuple(f"accel_{name.lower()}" for name in record.names)
    time_s = np.asarray(record.time_s, float) / rate
    warnings = []
    if overflows:
        warnings.append(
            f"the accelerometer's FIFO overflowed {overflows} times: samples were lost, and the times of those after "
            "them are early"
        )
    return Record(time_s, np.asarray(record.signals, float) * G_MM_S2, names), warnings
