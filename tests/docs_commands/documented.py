"""What the docs describe in prose or list as data: the inputs the commands read, and the answers they show."""

from __future__ import annotations

import json
import re
from decimal import Decimal
from typing import Any

from tests.docs_commands.extract import ROOT, blocks, commands

SWEEP_POINTS, SWEEP_REFINED = 3, 1  # sweep.json: docs/sweeps.md's body with fewer points (82 designs take 48 s)


def documented_request() -> str:
    """The example below the command-line block: ``request.json`` is the endpoint's request body, e.g. ..."""
    text = (ROOT / "docs" / "cli-and-python.md").read_text()
    (body,) = re.findall(r"`request\.json` is the endpoint's request body.*?e\.g\.\s*`(\{.*?\})`", text, re.S)
    assert body in (ROOT / "README.md").read_text()
    return body


def documented_sweep(points: int, refined: int) -> dict:
    """docs/sweeps.md's body (``sweep.json`` is the body above), with ``points`` points and ``refined`` added."""
    (body,) = [b.body for b in blocks() if b.document == "docs/sweeps.md" and b.language == "json"]
    sweep = json.loads(body)
    (axis,) = sweep["axes"]
    assert axis["num"] >= points and sweep["max_refined_points"] >= refined
    axis["num"], sweep["max_refined_points"] = points, refined
    return sweep


def documented_program() -> str:
    """docs/programs.md's body (``program.json``: the program above)."""
    (body,) = [b.body for b in blocks() if b.document == "docs/programs.md" and b.language == "json"]
    return body


def documented_table_columns() -> list[str]:
    """docs/sweeps.md: the table's columns after the axes' values."""
    text = (ROOT / "docs" / "sweeps.md").read_text()
    (columns,) = re.findall(r"the axes' values, then (.*?)\. The check", text, re.S)
    return re.findall(r"`(\w+)`", columns)


def identification_record_script() -> str:
    (command,) = [
        c
        for b in blocks()
        if b.document == "docs/identification.md" and b.language == "sh"
        for c in commands(b.body, "sh")
        if c.startswith("python3 - <<'EOF'")  # (the record of the first example; the resonance test's is 'KLIPPER')
    ]
    return command.split("\n", 1)[1].rsplit("\n", 1)[0]


def documented_identification_answer() -> dict:
    (body,) = [b.body for b in blocks() if b.document == "docs/identification.md" and b.language == "json"]
    return json.loads(body, parse_float=Decimal)


def matches_listing(listing: Any, answer: Any, where: str = "answer") -> None:
    """A shortened listing (``"...": "..."`` keys, ``["..."]`` lists) agrees with the answer: its keys are there,
    its strings equal, its numbers equal to the digits printed."""
    if isinstance(listing, dict):
        assert isinstance(answer, dict), where
        for name, value in listing.items():
            if name != "...":
                assert name in answer, f"{where}.{name} is not in the answer"
                matches_listing(value, answer[name], f"{where}.{name}")
    elif isinstance(listing, list):
        assert isinstance(answer, list), where
        if not (len(listing) == 1 and isinstance(listing[0], str) and listing[0].startswith("...")):
            assert len(listing) == len(answer), where
            for n, (value, actual) in enumerate(zip(listing, answer, strict=True)):
                matches_listing(value, actual, f"{where}[{n}]")
    elif isinstance(listing, Decimal):
        exponent = listing.as_tuple().exponent
        assert isinstance(exponent, int)
        assert abs(Decimal(repr(answer)) - listing) <= Decimal(5).scaleb(exponent - 1), (where, answer, listing)
    else:
        assert answer == listing, (where, answer, listing)
