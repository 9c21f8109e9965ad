"""The design page in a real browser (Debian's chromium): fill the form, see the plots and the table,
download a CSV; the default design's speed, units, the residual view, the sensitivity overlay with the
5 % line, stale results cleared on error, presets from the OpenAPI examples, shapers from the catalogue;
the time-optimal rows, a robustness band on the sensitivity plot and the trade-off curve."""

from __future__ import annotations

import re
import time

import httpx2 as httpx  # the test client library (a test dependency)
import numpy as np
import pytest
from playwright.sync_api import expect

CANVAS_BLANK = (
    "(selector) => { const c = document.querySelector(selector);"
    " const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;"
    " for (let i = 3; i < d.length; i += 4) if (d[i] !== 0) return false; return true; }"
)
# A solver row (time-optimal, pseudo-polynomial, robust) can take tens of seconds on a loaded 2-core machine.
SLOW_MS = 90_000
# Every number in the table: 4 significant digits, fixed between 1e-3 and 1e4, else d.ddde±x; or an exact 0.
FIXED = re.compile(r"^-?\d+(\.\d+)?$")
SCIENTIFIC = re.compile(r"^-?\d\.\d{3}e-?\d+$")


def design_cells(page):
    return page.locator("#compare-table tbody tr td:first-child")


def plot_data(page, name):
    """The arrays a uPlot instance draws (x first), read from the page."""
    return page.evaluate(f"() => {name} && {name}.data")


def wait_until_done(page):
    """Every job of the last Design has answered: no progress line left."""
    page.wait_for_function("() => document.querySelector('#pending').children.length === 0", timeout=SLOW_MS)


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


def significant_digits(text):
    return len(text.lstrip("-").replace(".", "").lstrip("0"))


@pytest.mark.serial  # the first plot within 2 s of the click (tests/conftest.py)
def test_default_design_appears_fast_with_units_residual_and_sensitivity(page, screenshots):
    page.goto("/")
    button = page.get_by_role("button", name="Design")
    expect(button).to_be_enabled()
    # Warm the server's first request (imports, caches), as a user's second Design would find it.
    button.click()
    wait_until_done(page)

    started = time.monotonic()
    button.click()
    expect(page.locator("#motion-plot canvas")).to_have_count(1)
    seconds = time.monotonic() - started
    in_page_ms = page.evaluate(
        "() => performance.getEntriesByName('vibfree:first-plot').pop().startTime"
        " - performance.getEntriesByName('vibfree:design-start').pop().startTime"
    )
    print(f"default design: first plotted row {seconds:.3f} s from the click (in the page: {in_page_ms:.0f} ms)")
    # The requirement: the default design on screen within 2 s (it took 34 s with one compare of
    # every family); the wall time seen from the test includes Playwright's polling, so it bounds the page's.
    assert seconds < 2.0
    assert in_page_ms < 2000
    # The solver rows arrive later, each with a progress line while it runs.
    wait_until_done(page)
    names = design_cells(page).all_text_contents()
    assert "Time-optimal" in names and "Pseudo-polynomial (Incerti)" in names
    assert sum(name.startswith("Input shaping") for name in names) == 4  # compare's ZV, MZV, ZVD, EI

    # Motor and load on one axis, in the plant's coordinate (a mode: metres by default), ticks distinct.
    axes = page.evaluate("() => motionPlot.axes.map(a => a.label)")
    assert axes == ["time (s)", "position (m)"]
    series = page.evaluate("() => motionPlot.series.map(s => s.label)")
    assert series[1:] == ["motor position (m)", "load position (m)"]
    assert all(s.get("scale", "y") == "y" for s in page.evaluate("() => motionPlot.series.slice(1)"))
    ticks = page.evaluate("() => motionPlot.axes[1]._values")
    assert ticks and len(set(ticks)) == len(ticks), ticks
    assert not page.evaluate(CANVAS_BLANK, "#motion-plot canvas")

    # The table: units in the headers, one number format.
    headers = page.locator("#compare-table thead th").all_text_contents()
    assert "Peak velocity (m/s)" in headers and "Peak acceleration (m/s²)" in headers and "Residual (m)" in headers
    for text in page.locator("#compare-table tbody td:not(:first-child)").all_text_contents():
        if text in ("–", "yes", "no") or "–" in text:
            continue
        if text == "0":
            continue
        if SCIENTIFIC.match(text):
            assert not 1e-3 <= abs(float(text)) < 1e4, text
        else:
            assert FIXED.match(text) and 1e-3 <= abs(float(text)) < 1e4 and significant_digits(text) == 4, text

    # Every design's sensitivity on one plot, with the 5 % line and ratio 1 marked.
    sensitivity = page.evaluate("() => sensitivityPlot.series.map(s => s.label)")
    assert sensitivity[-1] == "5 % line" and len(sensitivity) == len(names) + 2
    x, *curves, line = plot_data(page, "sensitivityPlot")
    assert line == [5] * len(x) and min(x) == 0.5 and max(x) == 1.5
    assert all(len(c) == len(x) for c in curves)
    expect(page.locator("#sensitivity-plot .ratio-one")).to_have_count(1)
    assert page.evaluate("() => sensitivityPlot.axes[1].label") == "percentage vibration V (%)"
    page.screenshot(path=screenshots / "default-design.png", full_page=True)

    # The residual view: STAP's closed form leaves micrometres of ringing on this 1 m move (6.2e-6 m, from
    # compare's residual_amplitude); zoomed after the move it fills the plot, in micrometres.
    design_cells(page).filter(has_text="STAP").click()
    expect(page.locator("#residual-title")).to_contain_text("STAP")
    assert page.evaluate("() => residualPlot.axes[1].label") == "load − target (µm)"
    t, residual = plot_data(page, "residualPlot")
    motion_time = page.evaluate("() => selected.motion_time_s")
    assert min(t) > motion_time  # after the command's end only
    spread = max(residual) - min(residual)
    assert 1 <= spread < 1000  # micrometres: the ringing spans the axis, not a flat line at 0
    ticks = page.evaluate("() => residualPlot.axes[1]._values")
    assert ticks and len(set(ticks)) == len(ticks), ticks  # no "0.001, 0.001, 0"
    assert not page.evaluate(CANVAS_BLANK, "#residual-plot canvas")
    page.screenshot(path=screenshots / "default-design-stap-residual.png", full_page=True)
    # The thick curve is the selected design's.
    widths = page.evaluate("() => sensitivityPlot.series.slice(1, -1).map(s => s.width)")
    assert sorted(widths)[-1] == 3 and widths.count(3) == 1


def test_solver_rows_show_progress_while_the_closed_forms_are_plotted(page):
    # Hold the solver families' answers (time-optimal, pseudo-polynomial) until the test lets them through:
    # the closed-form rows must be plotted meanwhile, with a progress line per held row.
    held = []

    def hold_solver_compares(route):
        body = route.request.post_data_json or {}
        if set(body.get("families") or []) & {"time_optimal", "pseudo_polynomial"}:
            held.append(route)
        else:
            route.continue_()

    page.route("**/v1/compare", hold_solver_compares)
    page.goto("/")
    page.get_by_role("button", name="Design").click()
    expect(page.locator("#motion-plot canvas")).to_have_count(1, timeout=SLOW_MS)
    progress = page.locator("#pending li")
    expect(progress).to_have_count(2)
    expect(progress.filter(has_text="Time-optimal: designing")).to_have_count(1)
    expect(progress.locator("progress")).to_have_count(2)
    expect(page.locator("#design-progress")).to_be_visible()
    expect(page.locator("#compare-table tbody tr")).to_have_count(6)  # ZV, MZV, ZVD, EI, STAP, smoother
    assert len(held) == 2
    for route in held:
        route.continue_()
    expect(progress).to_have_count(0, timeout=SLOW_MS)
    expect(page.locator("#design-progress")).to_be_hidden()
    expect(page.locator("#compare-table tbody tr")).to_have_count(8)


def test_design_plot_compare_and_csv(page, tmp_path):
    page.goto("/")
    expect(page.get_by_role("heading", name="Vibration-free motion profiles")).to_be_visible()
    fill_plant_and_limits(page)
    # Keyboard only: focus the Design button and press Enter.
    button = page.get_by_role("button", name="Design")
    expect(button).to_be_enabled()
    button.focus()
    page.keyboard.press("Enter")
    rows = page.locator("#compare-table tbody tr")
    expect(rows.first).to_be_visible(timeout=SLOW_MS)
    # The time-optimal family is a row of compare like the others (no robustness band asked: no robust row).
    expect(design_cells(page).filter(has_text="Time-optimal")).to_have_text(["Time-optimal"], timeout=SLOW_MS)
    expect(page.locator("#motion-plot canvas")).to_have_count(1)
    expect(page.locator("#sensitivity-plot canvas")).to_have_count(1)
    assert not page.evaluate(CANVAS_BLANK, "#motion-plot canvas")
    with page.expect_download() as download_info:
        page.get_by_role("button", name="Download CSV").click()
    path = tmp_path / "profile.csv"
    download_info.value.save_as(path)
    # Comment lines (units, metadata) may come before or not at all: the header is the first other line.
    lines = [line for line in path.read_text().splitlines() if not line.startswith("#")]
    assert lines[0].startswith("time_s,position,velocity,acceleration,jerk")
    table = np.loadtxt(lines[1:], delimiter=",")
    assert table.shape[1] >= 5 and table.shape[0] > 10
    assert np.all(np.diff(table[:, 0]) > 0)
    assert abs(table[-1, 1] - 1.0) < 1e-9  # the move ends at the displacement


def test_bad_input_shows_its_error_and_clears_the_stale_design(page, screenshots):
    page.goto("/")
    page.get_by_role("button", name="Design").click()
    expect(page.locator("#compare-table tbody tr").first).to_be_visible(timeout=SLOW_MS)
    expect(page.locator("#motion-plot canvas")).to_have_count(1)
    expect(page.get_by_role("button", name="Download CSV")).to_be_enabled()
    page.get_by_label("Natural frequency").fill("-3")
    page.get_by_role("button", name="Design").click()
    message = page.locator("[id='err-plant.natural_frequency_hz']")
    expect(message).to_contain_text("greater than or equal to", timeout=30_000)
    expect(page.get_by_label("Natural frequency")).to_have_attribute("aria-invalid", "true")
    expect(page.get_by_label("Natural frequency")).to_be_focused()
    # Nothing of the previous design is left: no rows, no plots, no CSV of it, no progress line.
    expect(page.locator("#compare-table tbody tr")).to_have_count(0)
    for plot in ("motion", "residual", "sensitivity"):
        expect(page.locator(f"#{plot}-plot canvas")).to_have_count(0)
    expect(page.get_by_role("button", name="Download CSV")).to_be_disabled()
    expect(page.locator("#pending li")).to_have_count(0)
    page.screenshot(path=screenshots / "bad-input.png", full_page=True)


def test_preset_fills_in_and_shows_the_papers_plant_move_and_limits(page, live_server, screenshots):
    # The paper's case as the service documents it: compare's OpenAPI example (Incerti Table III).
    spec = httpx.get(live_server + "/openapi.json").json()
    examples = spec["paths"]["/v1/compare"]["post"]["requestBody"]["content"]["application/json"]["examples"]
    example = examples["incerti_rest_to_rest"]
    page.goto("/")
    page.get_by_label("Paper's example").select_option(label=example["summary"])
    value = example["value"]
    expect(page.get_by_label("Plant", exact=True)).to_have_value("belt_platform")
    for key, number in value["plant"].items():
        if key == "kind":
            continue
        field = page.locator(f"#plant-{key}")
        expect(field).to_be_visible()
        assert float(field.input_value()) == number, key
    expect(page.get_by_label("Rest to rest")).to_be_checked()
    assert float(page.get_by_label("Displacement").input_value()) == value["displacement"]
    assert float(page.get_by_label("Max velocity").input_value()) == value["limits"]["max_velocity"]
    assert float(page.get_by_label("Max acceleration").input_value()) == value["limits"]["max_acceleration"]
    assert page.get_by_label("Max jerk").input_value() == ""
    expect(page.get_by_label("Max velocity")).to_be_visible()
    # The plant's modes are shown: Incerti's omega_n = 31.1769 rad/s (the analyze example's description).
    expect(page.locator("#plant-modes")).to_contain_text("31.18 rad/s")
    # Rotary: the platform turns, units in rad.
    expect(page.locator("#move-label")).to_have_text("Displacement (rad)")
    page.get_by_role("button", name="Design").click()
    expect(page.locator("#motion-plot canvas")).to_have_count(1, timeout=SLOW_MS)
    wait_until_done(page)
    assert page.evaluate("() => motionPlot.axes[1].label") == "position (rad)"
    # The motor is referred to the load: times G(0) = lambda = 1/30, so both end at 94.25 / 30 = pi rad.
    expect(page.locator("#motion-note")).to_contain_text("G(0) = 0.03333")
    _, motor, load = plot_data(page, "motionPlot")
    assert abs(motor[-1] - np.pi) < 1e-6 and abs(load[-1] - np.pi) < 1e-4
    page.screenshot(path=screenshots / "preset-incerti.png", full_page=True)


def test_preset_with_its_own_options_adds_the_papers_row(page, live_server):
    # Cusimano Fig. 16 (k_j = 3): jerk_periods is STAP's own option; the page sends it with the example's row.
    spec = httpx.get(live_server + "/openapi.json").json()
    example = spec["paths"]["/v1/profiles/stap"]["post"]["requestBody"]["content"]["application/json"]["examples"][
        "section_3_k3"
    ]
    page.goto("/")
    page.get_by_label("Paper's example").select_option(label=example["summary"])
    expect(page.locator("#preset-note")).to_contain_text("jerk_periods = 3")
    expect(page.get_by_label("Rest to velocity")).to_be_checked()
    expect(page.locator("#move-label")).to_contain_text("Target velocity")
    page.get_by_role("button", name="Design").click()
    paper = design_cells(page).filter(has_text="paper's example (section_3_k3)")
    expect(paper).to_have_count(1, timeout=SLOW_MS)
    request = page.evaluate("() => lastResult.rows.find(r => r.label.includes('paper')).request")
    assert request["jerk_periods"] == 3 and request["target_velocity"] == 150
    # The row is the endpoint's answer to the example itself (the form sends the example's own values).
    expected = httpx.post(live_server + "/v1/profiles/stap", json=example["value"], timeout=60).json()
    motion = page.evaluate("() => lastResult.rows.find(r => r.label.includes('paper')).motion_time_s")
    assert motion == pytest.approx(expected["metrics"]["motion_time_s"], rel=1e-12)


def test_shaper_is_chosen_from_the_catalogue(page, live_server):
    catalogue = httpx.get(live_server + "/v1/shapers").json()
    page.goto("/")
    expect(page.get_by_role("button", name="Design")).to_be_enabled()  # the page has read the catalogue
    options = page.locator("#shaper option").evaluate_all("els => els.map(e => e.value)")
    assert options == ["", *(s["name"] for s in catalogue["shapers"])]
    page.get_by_label("Design with").select_option("input_shaped")
    page.get_by_label("Input shaper").select_option("zvdd")
    page.get_by_role("button", name="Design").click()
    expect(design_cells(page)).to_have_text(["Input shaping (Chatlatanagulchai): ZVDD"], timeout=SLOW_MS)
    row = page.evaluate("() => ({ request: lastResult.rows[0].request, shaper: lastResult.rows[0].design.shaper })")
    assert row["request"]["shaper"] == "zvdd"
    # ZVDD is four impulses over 1.5 damped periods (the catalogue's entry).
    entry = next(s for s in catalogue["shapers"] if s["name"] == "zvdd")
    assert row["shaper"]["impulse_count"] == entry["impulse_count"] == 4
    expect(page.locator("#motion-plot canvas")).to_have_count(1)


def test_robust_band_is_a_row_and_is_drawn_on_the_sensitivity_plot(page):
    page.goto("/")
    fill_plant_and_limits(page)
    ask_band(page)
    page.get_by_role("button", name="Design").click()
    robust = page.locator("#compare-table tbody tr", has_text="Time-optimal: robust ±10 %")
    expect(robust).to_have_count(1, timeout=SLOW_MS)
    # Both time-optimal designs are rows; the robust one is selected and plotted.
    names = ["Time-optimal", "Time-optimal: robust ±10 %"]
    expect(design_cells(page).filter(has_text="Time-optimal")).to_have_text(names, timeout=SLOW_MS)
    expect(robust).to_have_attribute("aria-selected", "true")
    expect(page.locator("#plot-title")).to_have_text("Motor and load: Time-optimal: robust ±10 %")
    wait_until_done(page)
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
    expect(robust).to_have_count(1, timeout=SLOW_MS)
    page.get_by_label("V max (%)").fill("0")
    page.get_by_role("button", name="Design").click()
    expect(page.locator("[id='err-robustness.max_percentage_vibration']")).to_contain_text(
        "greater than or equal to 0.000001", timeout=SLOW_MS
    )
    expect(page.get_by_label("V max (%)")).to_have_attribute("aria-invalid", "true")
    # The stale robust design is gone from the table and the plots; compare's rows remain.
    expect(robust).to_have_count(0)
    expect(design_cells(page).filter(has_text="Time-optimal")).to_have_text(["Time-optimal"], timeout=SLOW_MS)
    expect(page.locator("#sensitivity-plot .band-mark:not(.ratio-one)")).to_have_count(0)


@pytest.mark.slow
def test_tradeoff_button_draws_what_robustness_costs(page):
    page.goto("/")
    fill_plant_and_limits(page)
    button = page.get_by_role("button", name="Trade-off")
    button.click()
    expect(button).to_be_disabled()
    expect(page.locator("#tradeoff-progress")).to_be_visible()
    rows = page.locator("#tradeoff-table tbody tr")
    expect(rows).to_have_count(5, timeout=SLOW_MS)
    expect(button).to_be_enabled()
    expect(page.locator("#tradeoff-progress")).to_be_hidden()
    expect(page.locator("#tradeoff-plot canvas")).to_have_count(1)
    assert not page.evaluate(CANVAS_BLANK, "#tradeoff-plot canvas")
    # Five points: x the half-width in %, the minimum duration and its lower bound in ms.
    x, duration, bound = page.evaluate("() => tradeoffPlot.data")
    assert x == [0, 5, 10, 15, 20]
    table = page.locator("#tradeoff-table tbody").inner_text()
    assert all(d is not None and b is not None and 0 < b <= d for d, b in zip(duration, bound, strict=True)), table
    expect(rows.first).to_contain_text("ok")


def test_the_page_loads_without_console_errors_or_failed_requests(page):
    # Every asset the page asks for is served (its icon included: browsers ask /favicon.ico without one).
    errors, failed = [], []
    page.on("console", lambda message: errors.append(message.text) if message.type == "error" else None)
    page.on("response", lambda response: failed.append(response.url) if response.status >= 400 else None)
    page.goto("/")
    page.wait_for_load_state("networkidle")
    assert not errors and not failed, (errors, failed)
