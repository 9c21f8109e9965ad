"""Issue 23: the CSV parser is linear in its input and bounded before each step.

Each pathological body is refused with the field that makes it too large, and the parse's peak of traced memory
(tracemalloc sees Python objects and numpy's buffers) stays within a small multiple of the text itself: the
proof that no step made an object per column, per line break or per comma before the cap was checked. Memory
is a count of work, the same on a loaded machine; the wall time of these cases is in bench/bounded_work.py.
On the parser before the issue the 1M-column header held a list of a million names (over 50 MB) and counted
each against all others (hours), and a body of line breaks held a string object per line.
"""

from __future__ import annotations

import tracemalloc

import pytest

from models.errors import InvalidParameter
from optim.identification.record_csv import MAX_CELL_CHARS, MAX_EXTRA_LINES, parse_record_csv

MAX_ROWS = 200_000  # the service's default VIBFREE_MAX_SAMPLES


def refused(text: str) -> tuple[InvalidParameter, int]:
    """The parser's refusal and the peak of memory it traced beyond the text."""
    tracemalloc.start()
    try:
        with pytest.raises(InvalidParameter) as info:
            parse_record_csv(text, max_rows=MAX_ROWS)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return info.value, peak


def header_of(columns: int) -> str:
    return ",".join(f"c{i}" for i in range(columns)) + "\n0" + ",0" * (columns - 1) + "\n"


@pytest.mark.parametrize("columns", [40_000, 1_000_000])
def test_a_header_of_many_columns_is_refused_before_any_work_per_column(columns):
    text = header_of(columns)
    error, peak = refused(text)
    assert error.field == "header" and "at most" in error.rule
    assert peak < 2 * len(text) + 1_000_000  # no list of names (a million names hold over 50 MB)


def test_a_body_of_line_breaks_is_refused_before_it_is_split():
    text = "time_s,a\n" + "\n" * 4_000_000
    error, peak = refused(text)
    assert error.field == "body" and f"{MAX_ROWS + MAX_EXTRA_LINES} lines" in error.rule
    assert peak < 1_000_000  # counted, not split: a split would hold a list of 4M entries (32 MB)


def test_more_data_rows_than_the_cap_are_refused():
    text = "time_s,a\n" + "0,1\n" * (MAX_ROWS + 1)
    error, _ = refused(text)
    assert error.field == "body" and f"at most {MAX_ROWS} data rows" in error.rule


@pytest.mark.parametrize("line", [",".join(["0"] * 1_000_000), '"0",' * 1_000_000])
def test_a_row_of_a_million_cells_is_refused_by_its_length(line):
    text = f"time_s,a\n0,1\n{line}\n0.002,3\n"
    error, peak = refused(text)
    assert error.field == "row[1]" and f"longer than {2 * MAX_CELL_CHARS} characters" in error.rule
    assert peak < 2 * len(text) + 1_000_000  # no million cells parsed (as floats: 8 MB; as strings: 50 MB)


def test_quoted_rows_are_read_into_one_table_and_name_the_first_bad_cell():
    good = 'time_s,a\n"0","1"\n"0.001","2"\n'
    record = parse_record_csv(good, max_rows=10)
    assert record.signals.tolist() == [[1.0, 2.0]]
    for text, field, words in [
        ('time_s,a\n"0","1"\n"0.001","x"\n', "a[1]", "number"),
        ('time_s,a\n"0","1"\n"0.001","inf"\n', "a[1]", "finite"),
        ('time_s,a\n"0","1","2"\n"0.001","2"\n', "row[0]", "fields"),
        ('time_s,a\n"0","1"\n', "body", "2 data rows"),
    ]:
        with pytest.raises(InvalidParameter) as info:
            parse_record_csv(text, max_rows=10)
        assert info.value.field == field and words in info.value.rule, (text, info.value)


def test_line_endings_of_every_kind_give_the_same_record():
    rows = ["time_s,a", "0,1", "0.001,2", "0.002,3"]
    records = [parse_record_csv(end.join(rows) + end, max_rows=10) for end in ("\n", "\r\n", "\r")]
    for record in records[1:]:
        assert record.time_s.tolist() == records[0].time_s.tolist()
        assert record.signals.tolist() == records[0].signals.tolist()
