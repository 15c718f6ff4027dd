"""The page in a real browser (Playwright driving Debian's Chromium): it loads, the regulator
and a dimension move the stitch length and the drawing, a bad file shows its located error and
the page keeps working; a screenshot is saved."""

from __future__ import annotations

import base64
from pathlib import Path

import pytest
from sewmech.feed import feed_cycles

import sewmech
from browser_helpers import CHROMIUM_ARGS, chromium_path
from serve_helpers import running_server


@pytest.fixture(scope="module")
def page():
    exe = chromium_path()
    from playwright.sync_api import sync_playwright

    with running_server() as url, sync_playwright() as p:
        browser = p.chromium.launch(executable_path=exe, args=CHROMIUM_ARGS)
        try:
            pg = browser.new_page(viewport={"width": 1500, "height": 1000})
            errors = []
            pg.on("pageerror", lambda e: errors.append(str(e)))
            pg.goto(url)
            pg.wait_for_function("window.sewmech && window.sewmech.turn && window.sewmech.checks",
                                 timeout=30000)
            pg.click("#play")  # pause: the drawing then changes only when the design does
            pg.errors = errors
            yield pg
        finally:
            browser.close()


def _drawing(pg) -> bytes:
    return base64.b64decode(pg.evaluate(
        "document.getElementById('mechanism').toDataURL('image/png')").split(",")[1])


def _redraws_after(pg, n: int):
    pg.wait_for_function(f"window.sewmech.redraws > {n} && !window.sewmech.inFlight",
                         timeout=20000)


def test_the_regulator_and_a_dimension_move_the_stitch_and_the_drawing(page, tmp_path):
    pg = page
    # the page opens at the machine's working setting, the longest forward stitch
    working = float(feed_cycles(sewmech.load_machine("jb1-3"), 30.0).stitch_mm)
    assert pg.text_content("#stitch") == f"{working:.2f} mm" and working > 4.0
    assert pg.locator("#checks tbody tr").count() >= 10
    before = _drawing(pg)
    n = pg.evaluate("window.sewmech.redraws")
    slider = pg.locator("#setting input[type=range]")
    box = slider.bounding_box()
    slider.click(position={"x": box["width"] * 0.85, "y": box["height"] / 2})  # as a user does
    _redraws_after(pg, n)
    setting = float(pg.input_value("#setting input[type=number]"))
    assert setting > 10
    want = float(feed_cycles(sewmech.load_machine("jb1-3"), setting).stitch_mm)
    pg.wait_for_function(f"window.sewmech.turnValues['input.regulator'] === {setting}")
    assert pg.text_content("#stitch") == f"{want:.2f} mm"
    after_regulator = _drawing(pg)
    assert after_regulator != before  # the feed dog moved

    n = pg.evaluate("window.sewmech.redraws")
    box = pg.locator('.param[data-name="needle_bar.length"] input[type=number]')
    box.fill("47")
    box.press("Enter")
    _redraws_after(pg, n)
    assert pg.evaluate("window.sewmech.turnValues['needle_bar.length']") == 47
    assert _drawing(pg) != after_regulator  # the needle bar is longer
    assert pg.locator('.param[data-name="needle_bar.length"]').get_attribute("class").endswith(
        "changed")
    with pg.expect_download() as dl:  # the edited file: the shipped text with the new values
        pg.click("#export-toml")
    text = Path(dl.value.path()).read_text(encoding="utf-8")
    assert dl.value.suggested_filename == "jb1-3-edited.toml"
    assert "length = 47.0" in text and f"default_deg = {setting}" in text
    with pg.expect_download() as dl:
        pg.click("#export-csv")
    assert Path(dl.value.path()).read_text(encoding="utf-8").startswith("phi_deg,")
    pg.screenshot(path=str(tmp_path / "serve.png"), full_page=True)
    assert (tmp_path / "serve.png").stat().st_size > 10_000
    assert pg.errors == []


def test_every_parameter_is_reachable_through_the_filter(page):
    pg = page
    pg.fill("#filter", "Q.y")
    assert pg.locator('.param[data-name="Q.y"]').count() == 1
    pg.fill("#filter", "")
    assert pg.locator('.param[data-name="Q.y"]').count() == 0  # not a main dimension


def test_a_bad_file_shows_its_located_error_and_the_page_keeps_working(page):
    pg = page
    stitch = pg.text_content("#stitch")
    pg.set_input_files("#upload", files=[{"name": "broken.toml", "mimeType": "text/plain",
                                          "buffer": b"[machine]\nname = 3\n"}])
    pg.wait_for_selector("#error:not([hidden])", timeout=20000)
    assert pg.text_content("#error-where") == "broken.toml: [machine] name:"
    assert "valid string" in pg.text_content("#error-what")
    assert pg.text_content("#stitch") == stitch  # the last good state stays
    # a design that cannot assemble: where and why, and the last good drawing stays
    n = pg.evaluate("window.sewmech.redraws")
    drawing = _drawing(pg)
    box = pg.locator('#setting input[type=number]')
    pg.fill("#filter", "take_up.length2")
    rod = pg.locator('.param[data-name="take_up.length2"] input[type=number]')
    rod.fill("2")
    rod.press("Enter")
    pg.wait_for_function("document.getElementById('error-where').textContent.includes('take_up')",
                         timeout=20000)
    assert "cannot be assembled" in pg.text_content("#error-what")
    assert "lengths" in pg.text_content("#error-hint")
    assert _drawing(pg) == drawing and pg.evaluate("window.sewmech.redraws") == n
    rod.fill("20.1")
    rod.press("Enter")
    _redraws_after(pg, n)
    assert pg.is_hidden("#error")
    assert box.input_value()


@pytest.mark.parametrize("name", ["fourbar-benchmark", "bartack-1820", "jb1-3"])
def test_every_shipped_kind_of_machine_opens(page, name):
    pg = page
    n = pg.evaluate("window.sewmech.redraws")
    pg.select_option("#machine", name)
    _redraws_after(pg, n)
    assert pg.evaluate("window.sewmech.machine.name") == name
    assert pg.is_hidden("#error")
    assert pg.errors == []
