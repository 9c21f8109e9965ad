"""The design page in a real browser: fill the form, see the plot and the table, download a CSV; the
time-optimal rows, a robustness band on the sensitivity plot and the trade-off curve."""

from __future__ import annotations

import numpy as np
import pytest
from playwright.sync_api import expect

CANVAS_BLANK = (
    "(selector) => { const c = document.querySelector(selector);"
    " const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;"
    " for (let i = 3; i < d.length; i += 4) if (d[i] !== 0) return false; return true; }"
)


def design_cells(page):
    return page.locator("#compare-table tbody tr td:first-child")


def fill_plant_and_limits(page):
    page.get_by_label("Plant", exact=True).select_option("mode")
    page.get_by_label("Natural frequency").fill("5")
    page.get_by_label("Damping ratio").fill("0.02")
    page.get_by_label("Displacement").fill("1")
    page.get_by_label("Max velocity").fill("4")
    page.get_by_label("Max acceleration").fill("40")


def ask_band(page, percent="10", vmax="5"):
    page.get_by_label("Robustness", exact=True).select_option("band")
    page.get_by_label("Band half-width X").fill(percent)
    page.get_by_label("V max (%)").fill(vmax)


def test_design_plot_compare_and_csv(page, tmp_path):
    page.goto("/")
    expect(page.get_by_role("heading", name="Vibration-free motion profiles")).to_be_visible()
    page.get_by_label("Plant", exact=True).select_option("mode")
    page.get_by_label("Natural frequency").fill("5")
    page.get_by_label("Damping ratio").fill("0.02")
    page.get_by_label("Displacement").fill("1")
    page.get_by_label("Max velocity").fill("4")
    page.get_by_label("Max acceleration").fill("40")
    # Keyboard only: focus the Design button and press Enter.
    page.get_by_role("button", name="Design").focus()
    page.keyboard.press("Enter")
    rows = page.locator("#compare-table tbody tr")
    expect(rows.first).to_be_visible(timeout=90_000)
    assert rows.count() >= 1
    # The time-optimal family is a row of compare like the others (no robustness band asked: no robust row).
    expect(design_cells(page).filter(has_text="Time-optimal")).to_have_text(["Time-optimal"])
    expect(page.locator("#motion-plot canvas")).to_have_count(1)
    expect(page.locator("#sensitivity-plot canvas")).to_have_count(1)
    # The plot really drew: the canvas is not blank.
    blank = page.evaluate(
        "() => { const c = document.querySelector('#motion-plot canvas');"
        " const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;"
        " for (let i = 3; i < d.length; i += 4) if (d[i] !== 0) return false; return true; }"
    )
    assert not blank
    with page.expect_download() as download_info:
        page.get_by_role("button", name="Download CSV").click()
    path = tmp_path / "profile.csv"
    download_info.value.save_as(path)
    lines = path.read_text().splitlines()
    assert lines[0].startswith("#") and lines[1] == "time_s,position,velocity,acceleration,jerk"
    table = np.loadtxt(lines[2:], delimiter=",")
    assert table.shape[1] == 5 and table.shape[0] > 10
    assert np.all(np.diff(table[:, 0]) > 0)
    assert table[-1, 1] == np.float64(1.0) or abs(table[-1, 1] - 1.0) < 1e-9  # the move ends at the displacement


def test_api_errors_appear_next_to_their_field(page):
    page.goto("/")
    page.get_by_label("Plant", exact=True).select_option("mode")
    page.get_by_label("Natural frequency").fill("-3")
    page.get_by_role("button", name="Design").click()
    message = page.locator("[id='err-plant.natural_frequency_hz']")
    expect(message).to_contain_text("greater than or equal to", timeout=30_000)
    expect(page.get_by_label("Natural frequency")).to_have_attribute("aria-invalid", "true")
    expect(page.get_by_label("Natural frequency")).to_be_focused()


def test_robust_band_is_a_row_and_is_drawn_on_the_sensitivity_plot(page):
    page.goto("/")
    fill_plant_and_limits(page)
    ask_band(page)
    page.get_by_role("button", name="Design").click()
    robust = page.locator("#compare-table tbody tr", has_text="Time-optimal: robust ±10 %")
    expect(robust).to_have_count(1, timeout=90_000)
    # Both time-optimal designs are rows; the robust one is selected and plotted.
    names = ["Time-optimal", "Time-optimal: robust ±10 %"]
    expect(design_cells(page).filter(has_text="Time-optimal")).to_have_text(names)
    expect(robust).to_have_attribute("aria-selected", "true")
    expect(page.locator("#plot-title")).to_have_text("Motor and load: Time-optimal: robust ±10 %")
    assert not page.evaluate(CANVAS_BLANK, "#sensitivity-plot canvas")

    # The requested band is shaded over the plot where the x axis has 0.9 .. 1.1 (the axis spans 0.5 .. 1.5).
    over = page.locator("#sensitivity-plot .u-over").bounding_box()
    requested = page.locator("#sensitivity-plot .band-requested")
    expect(requested).to_have_count(1)
    box = requested.bounding_box()
    assert abs((box["x"] - over["x"]) / over["width"] - 0.4) < 0.01
    assert abs(box["width"] / over["width"] - 0.2) < 0.01
    # Its V max as a line, and the achieved band (which covers the request) as two lines.
    expect(page.locator("#sensitivity-plot .band-vmax")).to_have_count(1)
    achieved = page.locator("#sensitivity-plot .band-achieved")
    expect(achieved).to_have_count(2)
    low, high = (float(v) for v in achieved.evaluate_all("els => els.map(e => e.dataset.value)"))
    assert 0.5 <= low <= 0.9 + 1e-6 and 1.1 - 1e-6 <= high <= 1.5
    expect(page.locator("#sensitivity-note")).to_contain_text("requested band 0.9 – 1.1")

    # Another design selected: the requested band stays as a reference, the achieved one is the robust design's.
    design_cells(page).filter(has_text="Input shaping").first.click()
    expect(requested).to_have_count(1)
    expect(achieved).to_have_count(0)


def test_robustness_errors_appear_next_to_the_inputs_and_clear_the_robust_design(page):
    page.goto("/")
    fill_plant_and_limits(page)
    ask_band(page)
    page.get_by_role("button", name="Design").click()
    robust = page.locator("#compare-table tbody tr", has_text="robust")
    expect(robust).to_have_count(1, timeout=90_000)
    page.get_by_label("V max (%)").fill("0")
    page.get_by_role("button", name="Design").click()
    expect(page.locator("[id='err-robustness.max_percentage_vibration']")).to_contain_text(
        "greater than 0", timeout=30_000
    )
    expect(page.get_by_label("V max (%)")).to_have_attribute("aria-invalid", "true")
    # The stale robust design is gone from the table and the plots; compare's rows remain.
    expect(robust).to_have_count(0)
    expect(design_cells(page).filter(has_text="Time-optimal")).to_have_text(["Time-optimal"])
    expect(page.locator("#sensitivity-plot .band-mark")).to_have_count(0)


@pytest.mark.slow
def test_tradeoff_button_draws_what_robustness_costs(page):
    page.goto("/")
    fill_plant_and_limits(page)
    button = page.get_by_role("button", name="Trade-off")
    button.click()
    expect(button).to_be_disabled()
    expect(page.locator("#tradeoff-progress")).to_be_visible()
    rows = page.locator("#tradeoff-table tbody tr")
    expect(rows).to_have_count(5, timeout=90_000)
    expect(button).to_be_enabled()
    expect(page.locator("#tradeoff-progress")).to_be_hidden()
    expect(page.locator("#tradeoff-plot canvas")).to_have_count(1)
    assert not page.evaluate(CANVAS_BLANK, "#tradeoff-plot canvas")
    # Five points: x the half-width in %, the minimum duration and its lower bound in ms.
    x, duration, bound = page.evaluate("() => tradeoffPlot.data")
    assert x == [0, 5, 10, 15, 20]
    assert all(d is not None and b is not None and 0 < b <= d for d, b in zip(duration, bound, strict=True))
    expect(rows.first).to_contain_text("ok")
