"""The ``lab`` fixture of the browser tests: JupyterLab on a copy of ``lessons/`` (skips
without Chromium or playwright)."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from .browser import CHROMIUM, LESSONS, LabServer


@pytest.fixture
def lab(tmp_path):
    if not Path(CHROMIUM).exists():
        pytest.skip(f"{CHROMIUM} not found: install Debian chromium (`make browser`, or "
                    "`apt-get install chromium`) to run the browser tests")
    pytest.importorskip("playwright.sync_api",
                        reason="the playwright Python package is not installed")
    root = tmp_path / "lessons"
    # Work on a copy: running and autosaving in the browser must not touch the committed lessons.
    shutil.copytree(LESSONS, root, ignore=shutil.ignore_patterns(".ipynb_checkpoints"))
    server = LabServer(root, tmp_path / "jupyter")
    server.home.mkdir()
    try:
        yield server.start()
    finally:
        server.stop()
    assert server.proc.poll() is not None, f"JupyterLab (pid {server.proc.pid}) is still running"
