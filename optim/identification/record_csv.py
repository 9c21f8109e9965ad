"""A measured record from CSV text: a header row, a time column and one or more signal columns.

The header is the first non-blank line (a leading ``#`` is dropped, as in accelerometer dumps whose header
reads ``#time,accel_x,accel_y,accel_z``); later lines starting with ``#`` are comments. The time column is
``time_s`` when present, else the first column (seconds). A column named ``command`` (or the name given)
is the known command the record responds to; every other column is a signal. Each broken rule is an
``InvalidParameter`` naming the column and row (``accel_x[12]``: data row 12, counted from 0) and the rule.
"""

from __future__ import annotations

import csv
import math

import numpy as np
from numpy.typing import NDArray

from models.errors import InvalidParameter
from optim.identification.record import Record

__all__ = ["MAX_EXTRA_LINES", "MAX_SIGNAL_COLUMNS", "MAX_TIME_S", "MAX_VALUE", "parse_record_csv"]

MAX_SIGNAL_COLUMNS = 16
MAX_VALUE = 1e12
MAX_TIME_S = 1e9  # uptime clocks in seconds (a printer's host clock after years) stay below it
MAX_NAME_CHARS = 64
MAX_EXTRA_LINES = 10_000  # blank and comment lines allowed beside the data rows
MAX_CELL_CHARS = 64  # a float written in full ("-1.2345678901234567e-123") with quotes and spaces fits


def _fast_table(lines: list[str], width: int) -> NDArray[np.float64] | None:
    """Every data row as a (rows, columns) array, read by numpy's C reader (6x the csv module's speed on 200k
    rows); None where a row does not parse as ``width`` plain numbers (quoted cells, a short row, text)."""
    if len(lines) < 2:
        return None
    try:
        table = np.loadtxt(lines, delimiter=",", comments=None, ndmin=2, dtype=float)
    except ValueError:
        return None
    return table if table.shape[1] == width else None


def _lines(text: str, max_lines: int) -> list[str]:
    """The text's lines (LF, CRLF or CR endings), refused before the split when there are more than ``max_lines``:
    counting is one pass of C over the text, where a split of a body of line breaks would hold tens of millions
    of strings."""
    newline = "\n" if "\n" in text else "\r"
    count = text.count(newline) + 1
    if count > max_lines:
        raise InvalidParameter(
            "body",
            f"{count} lines",
            f"at most {max_lines} lines are accepted (VIBFREE_IDENTIFY_MAX_ROWS data rows and {MAX_EXTRA_LINES} blank "
            "or comment lines)",
        )
    lines = text.split(newline)
    return [line.removesuffix("\r") for line in lines] if newline == "\n" else lines


def _header_names(header_text: str, header_line: int, max_columns: int) -> list[str]:
    """The header's column names: its length is checked before it is split (so the split is bounded), the
    column count before any work per column, uniqueness with a set (linear in the columns)."""
    most = max_columns * (MAX_NAME_CHARS + 3)  # every name at its longest, quoted, and a comma
    if len(header_text) > most:
        raise InvalidParameter(
            "header",
            f"{len(header_text)} characters",
            f"at most {most} characters ({max_columns} columns of names "
            f"of at most {MAX_NAME_CHARS} characters: time, command and {max_columns - 2} signals)",
        )
    names = [name.strip() for name in next(csv.reader([header_text]))]
    if len(names) < 2:
        raise InvalidParameter(
            "header", header_text[:80], "needs a time column and at least one signal column, comma-separated"
        )
    for name in names:
        if not name or len(name) > MAX_NAME_CHARS:
            raise InvalidParameter(
                "header", name[:80], f"every column needs a name of 1 to {MAX_NAME_CHARS} characters"
            )
        try:
            float(name)
        except ValueError:
            continue
        raise InvalidParameter("header", name, f"line {header_line} must be a header row of column names, not data")
    seen: set[str] = set()
    for name in names:
        if name in seen:
            raise InvalidParameter("header", name, "column names must be unique")
        seen.add(name)
    return names


def _check_line_lengths(data: list[tuple[int, str]], width: int) -> None:
    """No data line longer than ``width`` cells of ``MAX_CELL_CHARS``: a row's parse then holds a bounded number
    of cells whatever the body."""
    most = width * MAX_CELL_CHARS
    lengths = np.fromiter((len(line) for _, line in data), dtype=np.int64, count=len(data))
    long = np.flatnonzero(lengths > most)
    if long.size:
        k = int(long[0])
        raise InvalidParameter(
            f"row[{k}]",
            f"{int(lengths[k])} characters",
            f"line {data[k][0]} is longer than {most} characters ({width} cells of at most {MAX_CELL_CHARS})",
        )


def parse_record_csv(
    text: str,
    *,
    max_rows: int,
    max_signals: int = MAX_SIGNAL_COLUMNS,
    command_column: str = "command",
) -> Record:
    """The record of a CSV text (see the module): at most ``max_rows`` data rows and ``max_signals`` signals.

    Linear in the text and bounded before each step: the lines are counted before they are split, the header's
    columns before any per-column work, each row's length before it is parsed."""
    text = text.removeprefix("\ufeff")
    lines = _lines(text, max_rows + MAX_EXTRA_LINES)
    numbered = [(i + 1, line) for i, line in enumerate(lines) if line.strip()]
    if not numbered:
        raise InvalidParameter("body", "empty", "the CSV is empty: a header row and data rows are needed")
    header_line, header_text = numbered[0]
    header_text = header_text.lstrip().removeprefix("#")
    data = [(n, line) for n, line in numbered[1:] if not line.lstrip().startswith("#")]
    if len(data) > max_rows:
        raise InvalidParameter("body", f"{len(data)} rows", f"at most {max_rows} data rows are accepted")
    names = _header_names(header_text, header_line, max_signals + 2)
    time_name = "time_s" if "time_s" in names else names[0]
    command_name = command_column if command_column in names and command_column != time_name else None
    signal_names = [n for n in names if n not in (time_name, command_name)]
    if not signal_names:
        raise InvalidParameter("header", header_text[:80], "needs at least one signal column besides time and command")
    if len(signal_names) > max_signals:
        raise InvalidParameter("header", f"{len(signal_names)} signals", f"at most {max_signals} signal columns")
    _check_line_lengths(data, len(names))
    line_numbers = [n for n, _ in data]
    table = _fast_table([line for _, line in data], len(names))
    if table is None:  # the csv module reads it, and names the row or cell that breaks a rule
        table = _table_by_csv(data, names, line_numbers)
    _check_values(table, names, line_numbers)
    columns = {name: table[:, i] for i, name in enumerate(names)}
    time_s = columns[time_name]
    if np.max(np.abs(time_s)) > MAX_TIME_S:
        k = int(np.argmax(np.abs(time_s) > MAX_TIME_S))
        raise InvalidParameter(f"{time_name}[{k}]", float(time_s[k]), f"times must lie within +-{MAX_TIME_S:g} s")
    steps = np.diff(time_s)
    bad = np.flatnonzero(~(steps > 0))
    if bad.size:
        k = int(bad[0]) + 1
        raise InvalidParameter(
            f"{time_name}[{k}]",
            float(time_s[k]),
            f"times must increase strictly (line {line_numbers[k]} of the CSV)",
        )
    signals = np.vstack([columns[n] for n in signal_names])
    command = columns[command_name] if command_name is not None else None
    if not math.isfinite(float(time_s[-1] - time_s[0])):
        raise InvalidParameter(time_name, "?", "times must be finite")
    return Record(time_s, signals, tuple(signal_names), command, command_name)


def _table_by_csv(data: list[tuple[int, str]], names: list[str], line_numbers: list[int]) -> NDArray[np.float64]:
    """The data rows read one by one by the csv module (quoted cells) into one preallocated table, each broken rule
    named by row and column at the first row that breaks it (memory: the table, whatever the cells)."""
    width = len(names)
    table = np.empty((len(data), width))
    for k, row in enumerate(csv.reader(line for _, line in data)):
        if len(row) != width:
            raise InvalidParameter(
                f"row[{k}]",
                f"{len(row)} fields",
                f"line {line_numbers[k]} has {len(row)} fields; the header has {width}",
            )
        try:
            table[k] = [float(cell) for cell in row]
        except ValueError:
            i = next(i for i, cell in enumerate(row) if not _is_number(cell))
            rule = f"must be a number (line {line_numbers[k]} of the CSV)"
            raise InvalidParameter(f"{names[i]}[{k}]", row[i], rule) from None
    if len(data) < 2:
        raise InvalidParameter("body", f"{len(data)} rows", "needs at least 2 data rows")
    return table


def _check_values(table: NDArray[np.float64], names: list[str], line_numbers: list[int]) -> None:
    """Every cell finite and within +-MAX_VALUE, else the first bad one in reading order, by column and row."""
    bad = np.flatnonzero(~np.isfinite(table) | (np.abs(table) > MAX_VALUE))
    if bad.size:
        k, i = divmod(int(bad[0]), table.shape[1])
        rule = f"must be a finite number within +-{MAX_VALUE:g} (line {line_numbers[k]} of the CSV)"
        raise InvalidParameter(f"{names[i]}[{k}]", repr(float(table[k, i])), rule)


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True
