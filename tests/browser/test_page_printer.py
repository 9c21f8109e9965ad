"""The printer page (/printer, issue 27): a Klipper resonance test to the [input_shaper] section, with the spectrum
and each shaper's response drawn, and a bad setting shown next to its field (Playwright with Debian's chromium,
as tests/browser/test_page.py)."""

from __future__ import annotations

import numpy as np
from playwright.sync_api import expect

from tests.printer_records import chirp, raw_csv, raw_record

RATE_HZ = 1600.0


def _resonance_test(tmp_path):
    """A 25-95 Hz resonance test at 5 Hz/s on the issue's axis (42 Hz and 71 Hz), as Klipper writes it."""
    table = np.round(
        raw_record(chirp(RATE_HZ, 25.0, 95.0, hz_per_sec=5.0), np.random.default_rng(7), rate_hz=RATE_HZ), 6
    )
    path = tmp_path / "raw_data_x_20261205.csv"
    path.write_text(raw_csv(table))
    return path


def test_a_resonance_test_gives_the_section_to_paste_and_the_spectrum(page, tmp_path, screenshots):
    page.goto("/")
    page.get_by_role("link", name="Tune a printer's input shaper").click()
    page.wait_for_url("**/printer")
    page.get_by_label("Accelerometer or resonance file (CSV)").set_input_files(_resonance_test(tmp_path))
    page.get_by_label("Firmware", exact=True).select_option("klipper")
    page.get_by_role("button", name="Analyse").click()
    setting = page.locator("#firmware-text")
    expect(setting).to_contain_text("[input_shaper]", timeout=30_000)
    text = setting.inner_text()
    assert "shaper_type_x: " in text and "shaper_freq_x: " in text
    rows = page.locator("#shaper-table tbody tr")
    expect(rows).to_have_count(2)
    recommended = [c.inner_text() for c in rows.nth(0).locator("td").all()]
    klipper = [c.inner_text() for c in rows.nth(1).locator("td").all()]
    assert f"shaper_type_x: {recommended[0]}" in text and f"shaper_freq_x: {recommended[1]}" in text
    assert float(recommended[2]) <= float(klipper[2]) and float(recommended[4]) >= float(klipper[4])
    labels = page.evaluate("() => spectrumPlot.series.map(s => s.label)")
    assert labels[1] == "measured PSD" and "(recommended)" in labels[2] and "Klipper's calibration" in labels[3]
    peaks = page.locator("#resonances li").all_inner_texts()
    assert len(peaks) == 2 and peaks[0].startswith(("41.", "42.")), peaks
    page.locator("#printer-results").screenshot(path=screenshots / "printer.png")
    page.get_by_label("Firmware", exact=True).select_option("marlin")
    page.get_by_role("button", name="Analyse").click()
    expect(setting).to_contain_text("M493 S1 X C", timeout=30_000)
    page.get_by_label("Max smoothing (mm)").fill("0.01")  # under Klipper's 0.05: refused next to the field
    page.get_by_role("button", name="Analyse").click()
    expect(page.locator("#err-max_smoothing")).to_contain_text("max_smoothing", timeout=30_000)


def test_a_bad_setting_is_shown_next_to_its_field(page, tmp_path):
    page.goto("/printer")
    page.get_by_label("Accelerometer or resonance file (CSV)").set_input_files(_resonance_test(tmp_path))
    page.get_by_label("Frequency tolerance (%)").fill("90")
    page.get_by_role("button", name="Analyse").click()
    error = page.locator("#err-frequency_tolerance")
    expect(error).to_contain_text("frequency_tolerance", timeout=30_000)
    expect(page.get_by_label("Frequency tolerance (%)")).to_have_attribute("aria-invalid", "true")
    expect(page.locator("#printer-results")).to_be_hidden()
