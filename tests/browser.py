"""A headless browser for the viewer and report tests (a plugin of tests/conftest.py):
Debian's chromium, driven by Playwright (never a browser Playwright downloads itself).
``scripts/install-test-deps.sh`` (run by the README's test command and ``.ci/run``)
installs it."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest

CHROMIUM = Path("/usr/bin/chromium")
# Flags this closed-network machine needs (no background calls home, no GPU).
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


def chromium_path() -> str:
    path = CHROMIUM if CHROMIUM.exists() else shutil.which("chromium")
    if path is None:
        pytest.fail(
            "Debian's chromium is missing: run `bash scripts/install-test-deps.sh` (the README's"
            " test command and .ci/run do)"
        )
    return str(path)


@pytest.fixture(scope="session")
def browser() -> Iterator[object]:
    """A headless chromium shared by the session's browser tests."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=chromium_path(), headless=True, args=CHROMIUM_ARGS)
        try:
            yield b
        finally:
            b.close()


@pytest.fixture
def page(browser: object) -> Iterator[object]:
    """A fresh page; ``page.console_errors`` collects console errors and page errors."""
    context = browser.new_context(viewport={"width": 1280, "height": 800})  # type: ignore[attr-defined]
    pg = context.new_page()
    errors: list[str] = []
    pg.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    pg.on("pageerror", lambda e: errors.append(str(e)))
    pg.console_errors = errors
    try:
        yield pg
    finally:
        context.close()
