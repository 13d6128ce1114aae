"""Browser (end-to-end) tests: lessons driven in JupyterLab inside headless Chromium.

Run with ``pytest tests -m e2e`` (``make test-e2e`` installs Debian ``chromium`` first)."""
