"""The page's DXF export in a real browser (Playwright driving Debian's Chromium, as
test_serve_browser): the button downloads the mechanism at the angle the page shows, with the
page's values, and ezdxf reads and audits the file (issue 33)."""

from __future__ import annotations

from pathlib import Path

import ezdxf
import pytest

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
            pg.wait_for_function("window.sewmech && window.sewmech.turn", timeout=30000)
            pg.click("#play")  # pause
            pg.errors = errors
            yield pg
        finally:
            browser.close()


def test_the_export_dxf_button_draws_the_angle_shown(page):
    pg = page
    pg.fill("#scrub", "15")  # index 15 of the 2 deg turn: phi = 30 deg
    pg.dispatch_event("#scrub", "input")
    phi = pg.evaluate("window.sewmech.turn.phi_deg[window.sewmech.k]")
    assert phi == 30.0
    with pg.expect_download() as dl:
        pg.click("#export-dxf")
    assert dl.value.suggested_filename == "jb1-3-phi30.dxf"
    doc = ezdxf.readfile(Path(dl.value.path()))
    assert not doc.audit().has_errors and doc.header["$INSUNITS"] == 4
    texts = [t.dxf.text for t in doc.modelspace().query("TEXT")]
    assert "shaft angle phi = 30 deg; scale 1:1, mm" in texts
    assert "cam-feed_cam" in {layer.dxf.name for layer in doc.layers}
    assert pg.errors == []
