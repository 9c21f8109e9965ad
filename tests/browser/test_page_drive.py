"""The page with a drive (issue 26): the load through the drive beside the ideal motor's, a design for the
closed loop, a sampled drive's samples (Playwright with Debian's chromium, as tests/browser/test_page.py)."""

from __future__ import annotations

from playwright.sync_api import expect

from tests.browser.test_page import FIXED, plot_data, wait_until_done


def open_cusimano_shaft_move(page):
    """The page, ready (its schema loaded), with Cusimano's 8 Hz shaft (J_L = J_M) and a 0.5 rad move at 2 rad/s
    and 20 rad/s^2."""
    page.goto("/")
    expect(page.get_by_role("button", name="Design")).to_be_enabled()
    page.get_by_label("Plant", exact=True).select_option("two_inertia")
    page.fill("#plant-motor_inertia_kgm2", "0.005")
    page.fill("#plant-load_inertia_kgm2", "0.005")
    page.fill("#plant-stiffness_nm_per_rad", "12.633")
    page.get_by_label("Displacement").fill("0.5")
    page.get_by_label("Max velocity").fill("2")
    page.get_by_label("Max acceleration").fill("20")


def test_a_drive_adds_the_load_through_it_beside_the_ideal_one(page, screenshots):
    """Cusimano's 8 Hz shaft (J_L = J_M) under the page's default drive (a 20 Hz velocity loop: the machine rings
    at 7.53 Hz): each row's settling through the drive, the rows ranked by it, and the selected design's load and
    residual through the drive drawn beside the ideal motor's (the time-optimal command rings there, mrad)."""
    open_cusimano_shaft_move(page)
    expect(page.locator("#drive-inputs")).to_be_hidden()
    page.get_by_label("Predict through a servo drive").check()
    expect(page.get_by_label("Velocity loop (Hz)")).to_have_value("20")
    page.get_by_role("button", name="Design").click()
    wait_until_done(page)
    through = [cell.inner_text() for cell in page.locator("#compare-table tbody tr td:nth-child(4)").all()]
    assert len(through) >= 2 and all(FIXED.match(text) for text in through), through
    assert [float(t) for t in through] == sorted(float(t) for t in through)  # ranked by it
    page.locator("#compare-table tbody tr", has_text="Time-optimal").click()
    labels = page.evaluate("() => motionPlot.series.map(s => s.label)")
    assert labels[2:] == ["load position, ideal motor (mrad)", "load position, through the drive (mrad)"]
    _, ideal, drive = plot_data(page, "residualPlot")
    assert max(abs(v) for v in ideal) < 1e-6 < max(abs(v) for v in drive)  # mrad: round-off, and a ringing load
    page.locator("#results").screenshot(path=screenshots / "drive.png")


def test_designing_for_the_closed_loop_cancels_the_modes_the_machine_has(page, screenshots):
    """The same shaft and drive, designed for the closed loop (the API's closed_loop plant): every row's load is
    the load through the drive, so its settling there is its own, the plot says so, and the time-optimal command
    leaves round-off in the loop's modes (against mrad designed for the shaft, above). A drive the loop cannot run
    is refused next to the drive's fields (the API names plant.drive)."""
    open_cusimano_shaft_move(page)
    page.get_by_label("Predict through a servo drive").check()
    page.get_by_label("Design for the closed loop").check()
    expect(page.locator("#drive-design-note")).to_be_visible()
    page.get_by_role("button", name="Design").click()
    wait_until_done(page)
    rows = page.locator("#compare-table tbody tr")
    own = [cell.inner_text() for cell in page.locator("#compare-table tbody tr td:nth-child(3)").all()]
    through = [cell.inner_text() for cell in page.locator("#compare-table tbody tr td:nth-child(4)").all()]
    assert rows.count() >= 2 and through == own, (own, through)
    rows.filter(has_text="Time-optimal").first.click()
    labels = page.evaluate("() => motionPlot.series.map(s => s.label)")
    assert len(labels) == 3 and labels[2].startswith("load position, through the drive ("), labels
    # its residual vibration (the loop's oscillatory modes; its real poles' creep is no vibration): round-off
    assert page.evaluate("() => selected.residual_amplitude") < 1e-9 * 0.5
    page.locator("#results").screenshot(path=screenshots / "drive_design.png")
    page.get_by_label("Velocity loop (Hz)").fill("80")
    page.get_by_label("Position loop (Hz)").fill("15")
    page.get_by_role("button", name="Design").click()
    expect(page.locator("#err-drive")).to_contain_text("unstable")


def test_a_sampled_drive_is_drawn_from_its_samples(page):
    """A drive whose loops run every 2 ms: its closed-loop arrays are at its samples, not the profile's times. The
    dashed series is drawn on the profile's times, equal to the drive's own values wherever the two grids meet
    and between them on the line joining its samples."""
    open_cusimano_shaft_move(page)
    page.get_by_label("Predict through a servo drive").check()
    page.get_by_label("Sample period of the position and velocity loops (s; empty: continuous)").fill("0.002")
    page.get_by_role("button", name="Design").click()
    wait_until_done(page)
    page.locator("#compare-table tbody tr", has_text="Time-optimal").first.click()
    check = page.evaluate(
        """() => {
        const closed = selected.curves.closed_loop_load, profile = selected.curves.profile.time_s;
        const drawn = motionPlot.data[3], factor = motionPlot.unitScale.factor;
        let worst = 0, met = 0, drawnCount = 0;
        for (let i = 0; i < profile.length; i++) {
          if (drawn[i] !== null) drawnCount += 1;
          const j = closed.time_s.indexOf(profile[i]);
          if (j >= 0 && drawn[i] !== null) {
            met += 1;
            worst = Math.max(worst, Math.abs(drawn[i] / factor - closed.position[j]));
          }
        }
        const step = closed.time_s[1] - closed.time_s[0];
        return { worst, met, drawnCount, samples: closed.time_s.length, step, profile: profile.length };
    }"""
    )
    assert abs(check["step"] - 0.002) < 1e-12 and check["samples"] != check["profile"], check
    assert check["met"] >= 10 and check["worst"] <= 1e-12 and check["drawnCount"] >= check["profile"] - 1, check
