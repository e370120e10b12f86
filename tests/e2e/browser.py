"""A real headless browser for the view's page: Debian's Chromium driven by Playwright, offline, WebGL in software."""

from __future__ import annotations

import contextlib
import io
import shutil
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest

#: The flags of a Chromium that reaches nothing but the page (the machine's network is closed) and draws WebGL on
#: the CPU (SwiftShader).
CHROMIUM_FLAGS = ("--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--use-angle=swiftshader",
                  "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist")
VIEWPORT = {"width": 1000, "height": 700}
PAGE_TIMEOUT_S = 120.0


def chromium_path() -> str:
    """Debian's chromium, or a skip that says how to install it."""
    path = shutil.which("chromium")
    if path is None:
        pytest.skip("the view's browser tests need Debian's chromium (apt-get install chromium; .ci/run installs it)")
    return path


@contextlib.contextmanager
def page_of(url: str) -> Iterator[Any]:
    """A page of a fresh headless Chromium showing `url`, loaded and connected to the view."""
    from playwright.sync_api import sync_playwright

    executable = chromium_path()
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=executable, headless=True, args=list(CHROMIUM_FLAGS))
        try:
            page = browser.new_page(viewport=VIEWPORT)
            page.set_default_timeout(PAGE_TIMEOUT_S * 1000)
            page.goto(url, wait_until="load")
            page.wait_for_selector("canvas")
            yield page
        finally:
            browser.close()


def page_text(page: Any) -> str:
    """Everything the page shows as text."""
    return str(page.inner_text("body"))


def wait_for_text(page: Any, condition: Callable[[str], bool], timeout: float = PAGE_TIMEOUT_S) -> str:
    """The page's text once `condition` holds for it; fails with the text seen last."""
    deadline = time.monotonic() + timeout
    text = ""
    while time.monotonic() < deadline:
        text = page_text(page)
        if condition(text):
            return text
        page.wait_for_timeout(100)
    raise AssertionError(f"the page never showed what was expected; it showed:\n{text}")


def screenshot(page: Any) -> np.ndarray:
    """The 3D canvas as an RGB array."""
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(page.locator("canvas").first.screenshot())).convert("RGB")).astype(int)


def coloured(image: np.ndarray, colour: tuple[int, int, int], tolerance: int = 40) -> np.ndarray:
    """Pixels near `colour` (each channel within `tolerance`)."""
    return np.all(np.abs(image - np.array(colour)) <= tolerance, axis=-1)


def arm_pixels(image: np.ndarray) -> np.ndarray:
    """Pixels of the drawn arm: bluish shades, unlike the white background and the grey grid."""
    red, green, blue = image[..., 0], image[..., 1], image[..., 2]
    return (blue - red > 25) & (blue > 60) & (green < 235)


def wait_for_image(page: Any, condition: Callable[[np.ndarray], bool], timeout: float = PAGE_TIMEOUT_S) -> np.ndarray:
    """A screenshot of the canvas once `condition` holds for it (the scene fades in and streams in)."""
    deadline = time.monotonic() + timeout
    image = screenshot(page)
    while not condition(image):
        if time.monotonic() > deadline:
            raise AssertionError("the canvas never showed what was expected")
        page.wait_for_timeout(200)
        image = screenshot(page)
    return image
