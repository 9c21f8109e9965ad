"""The design page in a real browser: fill the form, see the plot and the table, download a CSV."""

from __future__ import annotations

import numpy as np
from playwright.sync_api import expect


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
