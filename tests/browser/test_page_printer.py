"""The printer page (/printer, issue 27): a Klipper resonance test to the [input_shaper] section, with the spectrum
and each shaper's response drawn, and a bad setting shown next to its field (Playwright with Debian's chromium,
as tests/browser/test_page.py)."""

from __future__ import annotations

import numpy as np
from playwright.sync_api import expect

from tests.printer_records import chirp_switches, held_record, raw_csv

RATE_HZ = 1600.0
TEST = {"Start frequency (Hz)": "35", "End frequency (Hz)": "80", "Sweep rate (Hz/s)": "2", "Sweeping period": "0"}


def _resonance_test(tmp_path):
    """A 35-80 Hz resonance test at 2 Hz/s without the sweeping overlay on the issue's axis (42 Hz and 71 Hz), as
    Klipper writes it."""
    switches = chirp_switches(35.0, 80.0, hz_per_sec=2.0)
    table = np.round(held_record(switches, np.random.default_rng(7), rate_hz=RATE_HZ), 6)
    path = tmp_path / "raw_data_x_20261205.csv"
    path.write_text(raw_csv(table))
    return path


def _fill_test(page):
    for label, value in TEST.items():
        page.get_by_label(label).fill(value)


def test_a_resonance_test_gives_the_section_to_paste_and_the_spectrum(page, tmp_path, screenshots):
    page.goto("/")
    page.get_by_role("link", name="Tune a printer's input shaper").click()
    page.wait_for_url("**/printer")
    page.get_by_label("Accelerometer or resonance file (CSV)").set_input_files(_resonance_test(tmp_path))
    page.get_by_label("Firmware", exact=True).select_option("klipper")
    _fill_test(page)
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
    modes = page.locator("#resonances li").all_inner_texts()  # the fitted modes, with their 95 % intervals
    assert len(modes) == 2, modes
    for text_, truth in zip(modes, (42.0, 71.0), strict=True):
        lo, hi = (float(v) for v in text_.split("(95 %: ")[1].split(" Hz)")[0].split(" to "))
        assert lo <= truth <= hi, text_
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
    page.get_by_label("Frequency tolerance (%)").fill("")
    page.get_by_label("Sweep rate (Hz/s)").fill("3")  # Klipper's HZ_PER_SEC is at most 2
    page.get_by_role("button", name="Analyse").click()
    expect(page.locator("#err-sweep_hz_per_sec")).to_contain_text("sweep_hz_per_sec", timeout=30_000)
    expect(page.locator("#printer-results")).to_be_hidden()
