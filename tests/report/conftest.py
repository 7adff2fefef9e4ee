"""Fixtures of the report tests: an analysed tiny dataset and a headless Chromium page."""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from energy_margin.analysis.frame import AnalyzerConfig
from energy_margin.analysis.run import analyze

CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]


@pytest.fixture(scope="session")
def analysed_source(tiny_dataset_source: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The tiny pushing dataset analysed with 10 expansions per frame (never modified)."""
    target = tmp_path_factory.mktemp("analysed") / "tiny"
    shutil.copytree(tiny_dataset_source, target)
    analyze(target, AnalyzerConfig(expansions=10), seed=0, workers=1, progress=False)
    return target


@pytest.fixture
def analysed(analysed_source: Path, tmp_path: Path) -> Path:
    """A private copy of the analysed tiny dataset."""
    target = tmp_path / "analysed"
    shutil.copytree(analysed_source, target)
    return target


def chromium_path() -> str | None:
    """Debian's Chromium, or ``None``."""
    return shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.fixture
def chromium_page() -> Iterator[tuple[Any, list[str]]]:
    """A page of a fresh headless Chromium (Debian's) and the console errors it reports."""
    executable = chromium_path()
    if executable is None:
        pytest.skip("Chromium is not installed (apt-get install chromium; .ci/run installs it)")
    playwright_api = pytest.importorskip("playwright.sync_api", reason="playwright is not installed")
    errors: list[str] = []
    with tempfile.TemporaryDirectory() as profile, playwright_api.sync_playwright() as playwright:
        browser = playwright.chromium.launch_persistent_context(
            profile, executable_path=executable, args=CHROMIUM_ARGS, viewport={"width": 1200, "height": 800}
        )
        page = browser.new_page()
        page.on("console", lambda message: errors.append(message.text) if message.type == "error" else None)
        page.on("pageerror", lambda error: errors.append(str(error)))
        try:
            yield page, errors
        finally:
            browser.close()
