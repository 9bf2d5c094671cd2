"""Headless Chromium (Debian's `chromium`), as the tests that render pages run it."""

import os
import shutil
import subprocess
from pathlib import Path

import pytest


def chromium() -> str:
    """The browser's path; without one the test is skipped, or fails under REQUIRE_BROWSER=1."""
    found = shutil.which("chromium")
    if found is None:
        if os.environ.get("REQUIRE_BROWSER") == "1":
            pytest.fail(
                "REQUIRE_BROWSER=1 but chromium is not installed (apt-get install chromium)"
            )
        pytest.skip("chromium is not installed (apt-get install chromium); REQUIRE_BROWSER=1 fails")
    return found


def command(url: str, profile: Path, *options: str) -> list[str]:
    """The command that opens ``url`` headless with its own profile folder, offline, in a
    1024 × 768 window, with ``options`` (a --screenshot, --dump-dom, a virtual time budget)."""
    return [
        chromium(),
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--enable-unsafe-swiftshader",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={profile}",
        "--window-size=1024,768",
        *options,
        url,
    ]


def dom(url: str, profile: Path, *options: str) -> str:
    """The page's DOM as the browser holds it once loaded (and after ``options``' virtual
    time), serialised as HTML."""
    run = subprocess.run(
        command(url, profile, "--dump-dom", *options), capture_output=True, text=True, timeout=120
    )
    assert run.returncode == 0, run.stderr[-2000:]
    return run.stdout
