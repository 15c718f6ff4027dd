"""Chromium for the page's browser tests: Debian's package (Playwright's own browser download
is not used). Without it the tests skip on a user's machine and fail in CI."""

from __future__ import annotations

import os
import shutil

import pytest

#: Chromium's switches for a headless run in a container without network
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                 "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync"]
HOW = ("the page's browser tests need Chromium and Playwright's Python package: `apt-get"
       " install chromium` (Debian/Ubuntu; or set SEWMECH_CHROMIUM to a Chromium binary) and"
       " `pip install -e .[test]`")


def required() -> bool:
    """In CI (CI set, or .ci/run's SEWMECH_REQUIRE_BROWSER=1) a missing browser is a failure."""
    return bool(os.environ.get("CI") or os.environ.get("SEWMECH_REQUIRE_BROWSER"))


def chromium_path() -> str:
    path = os.environ.get("SEWMECH_CHROMIUM") or shutil.which("chromium") or shutil.which(
        "chromium-browser")
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        path = None
    if not path:
        if required():
            pytest.fail(f"no Chromium or Playwright in CI: {HOW}", pytrace=False)
        pytest.skip(f"no Chromium or Playwright here: {HOW}")
    return path
