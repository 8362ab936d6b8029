"""The live page in a headless browser: Playwright driving the system's Chromium.

Used by the browser test, ``forcelearn bench live`` and the screenshot program
``python -m forcelearn.tools.live.screenshot``. Playwright (``pip install
'forcelearn[browser]'``; the test extra has it too) talks to the browser; the
browser is the one the system has, found as ``$FORCELEARN_CHROMIUM``,
``chromium``, ``chromium-browser`` or ``google-chrome`` on PATH (``.ci/run``
installs Debian's ``chromium``). Playwright's own browser downloads are never used.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from forcelearn.errors import ForcelearnError

if TYPE_CHECKING:
    from playwright.sync_api import Page

NAMES = ("chromium", "chromium-browser", "google-chrome")

_RENDERED = """([canvases, after]) => {
  const body = document.body;
  const drawn = document.querySelectorAll('canvas[data-drawn]').length;
  if (!body.dataset.trial || drawn < canvases || Number(body.dataset.trial) <= after) {
    return false;
  }
  return {
    trial: Number(body.dataset.trial),
    trials_done: Number(body.dataset.trialsDone),
    version: Number(body.dataset.version),
    status: document.getElementById('s-trial').textContent,
    state: document.getElementById('s-state').textContent,
    drawn: drawn,
  };
}"""
"""True-ish once the page has drawn its plots for a trial above ``after``: what it shows."""


class BrowserUnavailable(ForcelearnError):
    """No Chromium on this machine, or Playwright is not installed."""


def find_chromium() -> str | None:
    """The path of the system's Chromium, or None."""
    named = os.environ.get("FORCELEARN_CHROMIUM")
    if named:
        return shutil.which(named) or (named if Path(named).exists() else None)
    return next((path for name in NAMES if (path := shutil.which(name))), None)


def require_browser() -> str:
    """The system Chromium's path, once Playwright and Chromium are both found.

    Raises:
        BrowserUnavailable: either is missing (the message says what to install).
    """
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError as exc:
        raise BrowserUnavailable(
            "the live page's browser tools need Playwright: pip install 'forcelearn[browser]'"
        ) from exc
    executable = find_chromium()
    if executable is None:
        raise BrowserUnavailable(
            "no chromium on PATH: apt-get install chromium, or set FORCELEARN_CHROMIUM "
            "to a Chromium executable (Playwright's own browser downloads are not used)"
        )
    return executable


@contextmanager
def headless_page(width: int = 1400, height: int = 900, timeout_s: float = 120.0) -> Iterator[Page]:
    """A page in a headless system Chromium, closed (with the browser) on exit.

    Args:
        width: the viewport's width, px.
        height: the viewport's height, px.
        timeout_s: the longest any one page action may wait, s (a guard, not a measurement).

    Raises:
        BrowserUnavailable: Playwright or Chromium is missing (:func:`require_browser`).
    """
    executable = require_browser()
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(
            executable_path=executable,
            args=["--disable-dev-shm-usage", "--disable-gpu", "--hide-scrollbars"],
        )
        try:
            page = browser.new_page(viewport={"width": width, "height": height})
            page.set_default_timeout(timeout_s * 1000.0)
            yield page
        finally:
            browser.close()


def wait_rendered(page: Page, canvases: int, after_trial: int = -1) -> dict[str, Any]:
    """Wait until the live page has drawn ``canvases`` plots for a trial above ``after_trial``.

    Synchronised on what the page itself sets when it renders (``data-drawn`` on
    each plot, the status trial on ``<body>``); waits at most the page's default
    timeout. Returns the page's trial index, trials done, data version, and the
    status panel's trial and state texts.
    """
    seen = page.wait_for_function(_RENDERED, arg=[canvases, after_trial]).json_value()
    return dict(seen)
