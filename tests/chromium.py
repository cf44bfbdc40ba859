"""Headless Chromium for the browser tests: Debian's chromium driven by Selenium through Debian's chromedriver (given
by path, so Selenium Manager is not asked to download anything). WebGL runs on SwiftShader; offline, quiet, a fresh
profile, and a viewport of exactly the size asked for.

Screenshots are taken through the driver once the page stands still, not with `chromium --screenshot` and a virtual
time budget: that way hung in 3 of 4 runs of the same page on a quiet machine (and in all three tries of a test run),
never finishing the page's virtual time."""

import contextlib
import hashlib
import shutil
import time
from pathlib import Path

import pytest

CHROMIUM, CHROMEDRIVER = shutil.which("chromium"), shutil.which("chromedriver")
# Why a browser test is skipped; `make test` installs nothing outside .venv, so on a machine without them these tests
# skip, and tests/conftest.py sums them up in one line of the test summary.
MISSING = (
    "Chromium or chromedriver is not installed: `make browser-test` installs them (Debian's chromium, "
    "chromium-driver) and runs these tests"
)
needs_chromium = pytest.mark.skipif(CHROMIUM is None or CHROMEDRIVER is None, reason=MISSING)


@contextlib.contextmanager
def chromium(profile: Path, window: tuple[int, int]):
    """A Selenium driver of a headless Chromium whose pages are `window` (width, height) pixels."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in (
        "--headless=new",
        "--no-sandbox",
        "--disable-gpu",
        # WebGL without a GPU: SwiftShader, asked for explicitly (Chromium is retiring the silent fallback).
        "--enable-unsafe-swiftshader",
        "--use-angle=swiftshader",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--disable-extensions",
        "--hide-scrollbars",
        f"--user-data-dir={profile}",
        f"--window-size={window[0]},{window[1]}",
    ):
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(executable_path=CHROMEDRIVER), options=options)
    try:
        # The window's size includes what a headless window still reserves for its frame: set the page's own.
        width, height = window
        metrics = {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False}
        driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride", metrics)
        yield driver
    finally:
        driver.quit()


def screenshot_when_still(driver, shot: Path, timeout: float = 30.0, interval: float = 0.5) -> None:
    """Save the page's screenshot once two taken `interval` seconds apart are the same (WebGL has drawn and the page
    stands still); after `timeout` seconds, the last one."""
    end, last = time.monotonic() + timeout, None
    while True:
        png = driver.get_screenshot_as_png()
        digest = hashlib.sha256(png).digest()
        if digest == last or time.monotonic() > end:
            shot.write_bytes(png)
            return
        last = digest
        time.sleep(interval)
