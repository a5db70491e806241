"""Headless Chromium for the tests that open a page in a real browser
(tests/test_batch.py's contact sheet, tests/test_export_gltf_browser.py's glTF viewer).
CI installs Debian's ``chromium`` (.ci/run); without it those tests skip."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest


def chromium() -> str:
    """The Chromium executable; skips the calling test where there is none."""
    browser = shutil.which("chromium") or shutil.which("chromium-browser") \
        or shutil.which("google-chrome")
    if browser is None:
        pytest.skip("no Chromium here (CI installs the Debian package 'chromium')")
    return browser


def headless_flags(profile: Path, budget_ms: int = 5000) -> list[str]:
    """Headless, offline, a throwaway profile; scripts run for ``budget_ms`` of virtual
    time (timers fast-forwarded, pending requests waited for) before a dump or screenshot."""
    return ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
            "--disable-background-networking", "--disable-component-update",
            "--disable-sync", f"--user-data-dir={profile}",
            f"--virtual-time-budget={budget_ms}"]
