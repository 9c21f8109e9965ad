"""The programs page (/programs, issue 28): a two-axis program designed, its path drawn in the plane with the
stops, its axes against time, each stop's residual and the recipes' cycle times; a bad program's problem shown
under the text box (Playwright with Debian's chromium, as tests/browser/test_page.py)."""

from __future__ import annotations

import json
import re

from playwright.sync_api import expect


def test_a_program_is_drawn_with_its_stops_and_recipes(page, screenshots):
    page.goto("/")
    page.get_by_role("link", name="Design a machine program").click()
    page.wait_for_url("**/programs")
    expect(page.get_by_label("Axes, start, moves")).to_have_value(re.compile('"coordinate": "x"'))  # the example
    page.get_by_role("button", name="Load the straight-line example").click()
    page.get_by_role("button", name="Design").click()
    expect(page.locator("#cycle-summary")).to_contain_text("Cycle time", timeout=60_000)
    rows = page.locator("#comparison-table tbody tr")
    expect(rows).to_have_count(5)  # this program and the four recipes
    assert [r.locator("th").inner_text() for r in rows.all()][1:] == [
        "ruckig_zv",
        "ruckig_zvd",
        "klipper_mzv",
        "klipper_ei",
    ]
    stops = page.locator("#stops-table tbody tr")
    expect(stops).to_have_count(2)
    for row in stops.all():  # every stop still: residuals at round-off
        for text in [c.inner_text() for c in row.locator("td").all()][-2:]:
            assert float(text) < 1e-9, text
    assert page.locator("#path-plot svg polyline").count() == 2  # the motor and the load
    assert page.locator("#path-plot svg circle").count() == 2  # the start, where move 1 ends too, and stop 0
    assert page.locator("#path-plot svg text").all_text_contents() == ["start, 1", "0"]
    labels = page.evaluate("() => timePlot.series.map(s => s.label)")
    assert labels[1:] == ["x motor", "x load", "y motor", "y load"]
    page.locator("#program-results").screenshot(path=screenshots / "programs.png")


def test_a_bad_program_names_the_field(page):
    page.goto("/programs")
    page.get_by_role("button", name="Load the straight-line example").click()  # (at once: before the examples
    box = page.get_by_label("Axes, start, moves")  # arrive, the click fills the box when they do)
    expect(box).to_have_value(re.compile('"coordination": "straight_line"'))
    body = json.loads(page.get_by_label("Axes, start, moves").input_value())
    body["axes"][1]["name"] = "x"
    page.get_by_label("Axes, start, moves").fill(json.dumps(body))
    page.get_by_role("button", name="Design").click()
    expect(page.locator("#err-body")).to_contain_text("axes[1].name", timeout=30_000)
    expect(page.get_by_label("Axes, start, moves")).to_have_attribute("aria-invalid", "true")
    expect(page.locator("#program-results")).to_be_hidden()
