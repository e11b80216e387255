"""Headless Chromium for the browser tests (viewer, study page): Debian's chromium and
chromium-driver driven by Selenium. Nothing downloads a browser or a driver (the driver is given
to Selenium explicitly). A browser test carries :data:`needs_browser`; tests/conftest.py puts it in
the full tier (marks it ``slow``: `bash envs/setup.sh test-all` installs the browser) and skips it
when a piece is missing; with ANIGS_REQUIRE_BROWSER=1 (CI) it runs and fails naming the piece.
"""
from __future__ import annotations

import importlib.util
import os
import shutil
from pathlib import Path

import pytest

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver") or ("/usr/bin/chromedriver" if Path("/usr/bin/chromedriver").exists() else None)
MISSING = [name for name, ok in (("chromium", CHROMIUM), ("chromedriver", CHROMEDRIVER),
                                 ("selenium", importlib.util.find_spec("selenium"))) if not ok]
REQUIRED = os.environ.get("ANIGS_REQUIRE_BROWSER") == "1"
SKIP_REASON = (f"browser test needs {', '.join(MISSING)}: run `bash envs/browser.sh` (apt chromium "
               "chromium-driver as root, pip selenium)")

needs_browser = pytest.mark.browser  # the full tier; skipped without the browser (tests/conftest.py)

FLAGS = ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run")
WEBGL_FLAGS = ("--use-angle=swiftshader", "--enable-unsafe-swiftshader")  # WebGL on the software renderer


def chrome(window: tuple[int, int] = (1280, 860), webgl: bool = False, download_dir: Path | None = None):
    """A headless Chrome session (caller quits it)."""
    if MISSING:  # reached only with ANIGS_REQUIRE_BROWSER=1 (else the test skips): the test fails here
        raise RuntimeError(f"ANIGS_REQUIRE_BROWSER=1 but {', '.join(MISSING)} missing (bash envs/browser.sh)")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for flag in FLAGS + (WEBGL_FLAGS if webgl else ()) + (f"--window-size={window[0]},{window[1]}",):
        opts.add_argument(flag)
    if download_dir is not None:
        opts.add_experimental_option("prefs", {"download.default_directory": str(download_dir),
                                               "download.prompt_for_download": False})
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)
