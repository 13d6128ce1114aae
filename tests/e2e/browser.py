"""The JupyterLab + headless Chromium harness of the browser tests (``tests/e2e``).

A JupyterLab server on a copy of ``lessons/`` (:class:`LabServer`, the ``lab`` fixture of
``conftest.py``), Chromium driven through Playwright (:func:`_in_browser`), waits that fail
with what they waited for, and the page checks every test shares (no error output, kernel
idle, new image shown). Needs ``/usr/bin/chromium`` (``make browser``; override with
``PHYSLAB_E2E_CHROMIUM``) and the ``playwright`` Python package; never ``playwright install``.
"""
from __future__ import annotations

import base64
import json
import os
import re
import signal
import struct
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
LESSONS = REPO / "lessons"
LESSON01 = "01_odes_and_explicit_euler.ipynb"
LESSON04 = "04_fixed_corotated_fem.ipynb"
CHROMIUM = os.environ.get("PHYSLAB_E2E_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--disable-quic",
                 "--no-first-run", "--disable-background-networking", "--disable-component-update",
                 "--disable-sync"]

# Timeouts (seconds). A whole test takes ~15-60 s on a quiet machine of this kind. Waits on the
# kernel are proportional to its work: Run All may take up to STALL_TIMEOUT per cell (the
# deadline moves on whenever another cell finishes), a widget update as long as the kernel stays
# busy; MAX_WAIT caps both, so a hung kernel still fails.
SERVER_START_TIMEOUT = 60
PAGE_TIMEOUT = 60
STALL_TIMEOUT = 120
UPDATE_TIMEOUT = 30
MAX_WAIT = 900
# pytest-timeout's backstop for a whole test: above MAX_WAIT (a run-all wait plus widget waits),
# so a busy machine fails on a named wait above, never on an anonymous kill.
HARD_TIMEOUT = MAX_WAIT + 600
SETTLE_SECONDS = 1.0  # the widget's image must stay unchanged this long (with the kernel idle)
# A slider whose description eats the row leaves no room for its track (lesson 08 once).
MIN_TRACK_PX = 100

# What a student would see as an error in an output area (tracebacks are rendered as stderr).
STDERR_SEL = '.jp-OutputArea-output[data-mime-type="application/vnd.jupyter.stderr"]'
WIDGET_ERROR_TEXT = "Error displaying widget"
KERNEL_IDLE = re.compile(r"\| Idle\s*$")
# Boxes drawn by this kernel. Before Run All every box already on the page is marked stale, so
# a redraw of the widget state saved in the notebook is never mistaken for a live widget.
STALE_ATTR = "data-e2e-stale"
LIVE_BOX_SEL = f".widget-interact:not([{STALE_ATTR}])"


# --------------------------------------------------------------------------- JupyterLab server
class LabServer:
    """``jupyter lab`` on 127.0.0.1 serving ``root``, with private config/runtime dirs under
    ``home``. Only the process this object started (and its process group) is ever signalled."""

    def __init__(self, root: Path, home: Path):
        self.root, self.home = root, home
        self.token = os.urandom(16).hex()
        self.log_path = home / "jupyterlab.log"
        self.proc: subprocess.Popen | None = None
        self.url = ""

    def _write_config(self):
        cfg, rt = self.home / "jupyter_config", self.home / "jupyter_runtime"
        (cfg / "labconfig").mkdir(parents=True)
        rt.mkdir(parents=True)
        # The "Jupyter news?" popup can cover the menu bar: disable the announcements plugin.
        (cfg / "labconfig" / "page_config.json").write_text(json.dumps(
            {"disabledExtensions": {"@jupyterlab/apputils-extension:announcements": True}}))
        # Keep every cell in the DOM (the default windowing drops off-screen cells).
        settings = cfg / "lab" / "user-settings" / "@jupyterlab" / "notebook-extension"
        settings.mkdir(parents=True)
        (settings / "tracker.jupyterlab-settings").write_text(json.dumps({"windowingMode": "none"}))
        # JUPYTER_DATA_DIR stays as is: the ipywidgets labextension and the python3 kernelspec
        # come from sys.prefix/share/jupyter, which is searched regardless.
        return dict(os.environ, JUPYTER_CONFIG_DIR=str(cfg), JUPYTER_RUNTIME_DIR=str(rt),
                    IPYTHONDIR=str(self.home / "ipython"), PYTHONUNBUFFERED="1")

    def start(self):
        env = self._write_config()
        cmd = [sys.executable, "-m", "jupyterlab", "--no-browser", "--ip=127.0.0.1", "--port=0",
               f"--IdentityProvider.token={self.token}", f"--ServerApp.root_dir={self.root}",
               "--LabApp.news_url=None",
               "--LabApp.check_for_updates_class=jupyterlab.NeverCheckForUpdate"]
        if hasattr(os, "geteuid") and os.geteuid() == 0:
            cmd.append("--allow-root")
        with open(self.log_path, "wb") as log:
            self.proc = subprocess.Popen(cmd, env=env, cwd=self.root, stdout=log,
                                         stderr=subprocess.STDOUT, start_new_session=True)
        info = Path(env["JUPYTER_RUNTIME_DIR"]) / f"jpserver-{self.proc.pid}.json"
        deadline = time.monotonic() + SERVER_START_TIMEOUT
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"JupyterLab exited with code {self.proc.returncode}\n"
                                   + self.log_tail())
            if info.exists():
                try:
                    self.url = json.loads(info.read_text())["url"].rstrip("/")
                    self._request("GET", "/api/status", timeout=2)
                    return self
                except (ValueError, KeyError, OSError):
                    pass  # file half-written or server not answering yet
            time.sleep(0.2)
        raise RuntimeError(f"JupyterLab did not come up within {SERVER_START_TIMEOUT} s\n"
                           + self.log_tail())

    def _request(self, method, path, timeout=5):
        req = urllib.request.Request(self.url + path, method=method,
                                     data=b"" if method == "POST" else None,
                                     headers={"Authorization": f"token {self.token}"})
        with urllib.request.urlopen(req, timeout=timeout) as resp:
            return resp.read()

    def stop(self):
        proc = self.proc
        if proc is None or proc.poll() is not None:
            return
        try:  # clean shutdown: the server also shuts its kernels down
            self._request("POST", "/api/shutdown", timeout=5)
            proc.wait(timeout=15)
        except Exception:
            pass
        for sig, wait in ((signal.SIGTERM, 10), (signal.SIGKILL, 5)):
            if proc.poll() is not None:  # not yet reaped otherwise, so its pid is still ours
                break
            try:
                os.killpg(proc.pid, sig)  # the group start_new_session gave the server
            except ProcessLookupError:
                break
            try:
                proc.wait(timeout=wait)
            except subprocess.TimeoutExpired:
                pass

    def log_tail(self, n=40):
        try:
            lines = self.log_path.read_text(errors="replace").splitlines()[-n:]
        except OSError:
            return f"(no server log at {self.log_path})"
        return f"JupyterLab log {self.log_path} (last {len(lines)} lines):\n" + "\n".join(lines)


# --------------------------------------------------------------------------- page helpers

def write_scratch_notebook(path, source):
    """A one-cell notebook (Python 3 kernel) at ``path`` running ``source``: the scratch
    notebooks of the widget browser tests."""
    import nbformat

    nb = nbformat.v4.new_notebook()
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3 (ipykernel)",
                                 "language": "python"}
    nb.cells = [nbformat.v4.new_code_cell(source)]
    nbformat.write(nb, str(path))


def run_scratch_notebook(page, lab, notebook):
    """Open ``notebook`` (in the server's root) in JupyterLab, wait for an idle kernel and
    run its first cell (Shift+Enter)."""
    page.goto(f"{lab.url}/lab/tree/{notebook}?token={lab.token}", wait_until="domcontentloaded")
    page.locator(".jp-Notebook .jp-Cell").first.wait_for(timeout=PAGE_TIMEOUT * 1000)
    _wait_until(page, lambda: _kernel_idle(page), PAGE_TIMEOUT,
                lambda: f"the kernel to be idle (status {_kernel_status(page)!r})")
    page.locator(".jp-Notebook .jp-Cell").first.click()
    page.keyboard.press("Shift+Enter")


def widget_readout(box):
    """The text of a physlab canvas widget's readout line (``.physlab-readout``)."""
    return box.locator(".physlab-readout").inner_text().strip()

def _wait_until(page, check, timeout, what, poll_ms=200, progress=None):
    """Poll ``check()`` (truthy result = done) until ``timeout`` seconds; fail saying ``what``
    (a string, or a callable giving one at failure time). ``check`` may raise AssertionError to
    fail early (e.g. when an error output shows up).

    ``progress``: optional callable returning a token of ongoing work (the number of executed
    cells, whether the kernel is busy...); whenever the token changes, or while it is ``True``,
    the deadline moves to ``timeout`` seconds later, never beyond :data:`MAX_WAIT` in all. So a
    slow machine gets the time its work needs, and a stalled kernel still fails."""
    start = last = time.monotonic()
    token = progress() if progress else None
    while True:
        result = check()
        if result:
            return result
        now = time.monotonic()
        if progress:
            new = progress()
            if new is True or new != token:
                token, last = new, now
        if now - last > timeout or now - start > MAX_WAIT:
            what = what() if callable(what) else what
            raise AssertionError(f"timed out after {now - start:.0f} s ({now - last:.0f} s "
                                 f"without progress) waiting for {what}")
        page.wait_for_timeout(poll_ms)


def _kernel_status(page):
    texts = page.locator(".jp-StatusBar-Widget").all_inner_texts()
    for line in "\n".join(texts).splitlines():
        if "|" in line and "(" in line:  # "Python 3 (ipykernel) | Idle"
            return line.strip()
    return ""


def _kernel_idle(page):
    return bool(KERNEL_IDLE.search(_kernel_status(page)))


def _error_outputs(page):
    """Texts of error-looking outputs anywhere in the notebook (incl. inside widget outputs)."""
    errors = [t for t in page.locator(STDERR_SEL).all_inner_texts() if t.strip()]
    errors += [t for t in page.locator(".jp-OutputArea-output").all_inner_texts()
               if WIDGET_ERROR_TEXT in t]
    return errors


def _assert_no_errors(page, where):
    errors = _error_outputs(page)
    assert not errors, f"error output in the notebook {where}:\n" + "\n-----\n".join(
        e[-3000:] for e in errors)


def _img_src(box):
    imgs = box.locator(".widget-output img")
    return imgs.first.get_attribute("src") if imgs.count() else None


def _png_size(src):
    assert src and src.startswith("data:image/png;base64,"), f"not a PNG data URL: {str(src)[:80]}"
    data = base64.b64decode(src.split(",", 1)[1])
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "widget image is not a PNG"
    return data, struct.unpack(">II", data[16:24])  # IHDR width, height


def _wait_new_image(page, box, old_src, what):
    """Wait until the widget shows an image other than ``old_src`` and has settled: the kernel is
    idle and the image stayed the same for SETTLE_SECONDS (each key press makes its own update)."""
    _wait_until(page, lambda: _check_errors_then(page, lambda: _img_src(box) not in (None, old_src),
                                                 f"after {what}"),
                UPDATE_TIMEOUT, f"the widget figure to change after {what}",
                progress=lambda: not _kernel_idle(page))
    state = {"src": None, "since": 0.0}

    def settled():
        src, now = _img_src(box), time.monotonic()
        if src != state["src"] or src is None or not _kernel_idle(page):
            state.update(src=src, since=now)
            return False
        return now - state["since"] >= SETTLE_SECONDS

    _wait_until(page, lambda: _check_errors_then(page, settled, f"after {what}"), UPDATE_TIMEOUT,
                f"the widget figure to settle after {what}", progress=lambda: not _kernel_idle(page))
    return state["src"]


def _check_errors_then(page, check, where="while waiting"):
    _assert_no_errors(page, where)
    return check()


def _snapshot(box, out_dir: Path, name, src):
    """Screenshot the widget box and write the PNG it displays; returns the screenshot path."""
    box.scroll_into_view_if_needed()
    shot = out_dir / f"{name}.png"
    box.screenshot(path=str(shot))
    data, _ = _png_size(src)
    (out_dir / f"{name}_figure.png").write_bytes(data)
    print(f"[e2e] screenshot {shot}  (figure {out_dir / f'{name}_figure.png'})")
    return shot


def _check_single_figure(cell, box, shot):
    """Exactly one figure: inside the widget's output, none elsewhere in the cell's output."""
    n_widget = box.locator(".widget-output img").count()
    n_cell = cell.locator(".jp-Cell-outputArea img").count()
    assert n_widget == 1 and n_cell == 1, (
        f"expected exactly one figure in the interactive widget's output, found {n_widget} in the "
        f"widget and {n_cell} in the whole cell output; see {shot}")


def _labels(box):
    return [t.strip() for t in box.locator(".widget-label").all_inner_texts()]


def _slider(box, label):
    """The slider of ``box`` whose description is exactly ``label`` (two boxes may both have a
    "ν" slider, and "E" is a substring of other labels: match the whole label, inside one box)."""
    exact = re.compile(rf"^\s*{re.escape(label)}\s*$")
    return box.locator(".widget-slider").filter(
        has=box.page.locator(".widget-label", has_text=exact))


def _readout(slider):
    # d3-format writes negative numbers with U+2212 MINUS SIGN ("−0.500").
    return float(slider.locator(".widget-readout").inner_text().strip().replace("\u2212", "-"))


def _press_slider(box, label, key, presses, shot):
    """Focus the handle of the slider labelled ``label`` and press ``key`` ``presses`` times
    (continuous_update=False, so each key press is one committed change). Returns the slider and
    its readout before the presses."""
    slider = _slider(box, label)
    assert slider.count() == 1, (
        f"no single slider labelled {label!r} in the widget (its controls: {_labels(box)}); "
        f"see {shot}")
    before = _readout(slider)
    handle = slider.locator(".noUi-handle")
    handle.focus()
    for _ in range(presses):
        handle.press(key)
    return slider, before


# --------------------------------------------------------------------------- driving a lesson
def _open_and_run_all(page, lab, lesson, n_boxes, t0):
    """Open ``lesson``, wait for its kernel, run all cells from the Run menu and wait until every
    cell has run and ``n_boxes`` live interactive widgets are on the page, one per code cell.
    Returns ``[(cell, box), ...]`` in notebook order (each box located inside its cell)."""
    page.goto(f"{lab.url}/lab/tree/{lesson}?token={lab.token}", wait_until="domcontentloaded")
    page.locator(".jp-Notebook .jp-Cell").first.wait_for(timeout=PAGE_TIMEOUT * 1000)
    # The toolbar can say idle while the kernel is still starting: wait for the status bar.
    _wait_until(page, lambda: _kernel_idle(page), PAGE_TIMEOUT,
                lambda: f"the status bar to show the kernel idle (it shows "
                        f"{_kernel_status(page)!r})")
    print(f"[e2e] {lesson} open, kernel idle after {time.monotonic() - t0:.1f} s")

    # Should JupyterLab ever redraw the saved widget state, don't mistake it for the live widget.
    page.evaluate(f"document.querySelectorAll('.widget-interact')"
                  f".forEach(e => e.setAttribute('{STALE_ATTR}', '1'))")
    page.locator(".lm-MenuBar-item", has_text=re.compile(r"^\s*Run\s*$")).click()
    page.locator(".lm-Menu-item", has_text=re.compile(r"^\s*Run All Cells")).first.click()

    boxes = page.locator(LIVE_BOX_SEL)
    prompts = page.locator(".jp-InputPrompt")

    def all_ran():
        # Run All marks every code cell "[*]" at once, so once a live box exists (it can only
        # come from this run) no "[*]" left means the whole notebook has been executed.
        return (boxes.count() == n_boxes
                and not any("*" in t for t in prompts.all_inner_texts()))

    def executed():  # "[3]:" prompts: the number of cells that finished
        return sum(bool(re.search(r"\d", t)) for t in prompts.all_inner_texts())

    _wait_until(page, lambda: _check_errors_then(page, all_ran, "during Run All"),
                STALL_TIMEOUT,
                lambda: f"all cells to run and {n_boxes} interactive widget(s) (.widget-interact) "
                        f"to render after Run All Cells (found {boxes.count()}; prompts "
                        f"{[t for t in prompts.all_inner_texts() if t.strip()]})",
                progress=executed)
    cells = page.locator(".jp-CodeCell").filter(has=page.locator(LIVE_BOX_SEL))
    assert cells.count() == n_boxes, (
        f"expected {n_boxes} code cells holding one interactive widget each, found "
        f"{cells.count()} cells holding {boxes.count()} widgets")
    print(f"[e2e] all cells ran, {n_boxes} widget(s) rendered after {time.monotonic() - t0:.1f} s")
    pairs = [(cells.nth(i), cells.nth(i).locator(LIVE_BOX_SEL)) for i in range(n_boxes)]
    for _, box in pairs:
        _assert_slider_tracks(box)
    return pairs


def _assert_slider_tracks(box):
    """Every slider of ``box`` shows its whole description and a track a student can drag
    (at least :data:`MIN_TRACK_PX` wide): a long description must not squeeze it away."""
    sliders = box.locator(".widget-slider")
    for i in range(sliders.count()):
        sl = sliders.nth(i)
        label = sl.locator(".widget-label").first
        track = sl.locator(".slider-container").first.bounding_box()
        width = track["width"] if track else 0.0
        text = label.inner_text().strip()
        clipped = label.evaluate("e => e.scrollWidth > e.clientWidth + 1")
        assert width >= MIN_TRACK_PX and not clipped, (
            f"slider {text!r}: track {width:.0f} px wide (need >= {MIN_TRACK_PX}), description "
            f"{'clipped' if clipped else 'fits'}; give the widget a wider description or put the "
            f"label above it (physlab.viz.widgets)")


def _initial_figure(page, cell, box, shots_dir, name, t0, min_size=(200, 150)):
    """Wait for the first figure of a freshly rendered box; check it is one loaded PNG of at least
    ``min_size`` px. Returns ``(src, screenshot path)``."""
    try:
        src = _wait_new_image(page, box, None, f"Run All Cells ({name})")
    except AssertionError as exc:
        if _img_src(box) is not None:
            raise
        shot = shots_dir / f"{name}_no_figure.png"
        box.scroll_into_view_if_needed()
        box.screenshot(path=str(shot))
        out = box.locator(".widget-output")
        raise AssertionError(
            f"the interactive widget rendered (its controls: {_labels(box)}) but its output area "
            f"shows no figure (kernel status {_kernel_status(page)!r}; output area holds "
            f"{out.locator('.jp-OutputArea-child').count()} outputs, text "
            f"{out.inner_text()[:500]!r}); see {shot}") from exc
    shot = _snapshot(box, shots_dir, name, src)
    _check_single_figure(cell, box, shot)
    _, (w, h) = _png_size(src)
    assert w >= min_size[0] and h >= min_size[1], (
        f"widget figure is only {w}x{h} px (expected at least {min_size}); see {shot}")
    assert box.locator(".widget-output img").evaluate("img => img.naturalWidth") > 0, (
        f"the widget figure did not load in the browser; see {shot}")
    print(f"[e2e] {name}: {w}x{h} px figure drawn after {time.monotonic() - t0:.1f} s")
    return src, shot


def _draw(page, canvas, points):
    """One mouse stroke through ``points`` (canvas pixels) on the canvas element."""
    bb = canvas.bounding_box()
    assert bb, "the sketch canvas has no bounding box (not rendered?)"
    sx = bb["width"] / float(canvas.get_attribute("width") or bb["width"])
    sy = bb["height"] / float(canvas.get_attribute("height") or bb["height"])
    x0, y0 = points[0]
    page.mouse.move(bb["x"] + x0 * sx, bb["y"] + y0 * sy)
    page.mouse.down()
    for x, y in points[1:]:
        page.mouse.move(bb["x"] + x * sx, bb["y"] + y * sy, steps=3)
    page.mouse.up()


def _in_browser(lab, tmp_path, drive):
    """Launch headless Chromium, run ``drive(page, lab, shots_dir)``; on failure, fail with a
    whole-page screenshot, the browser's JS errors and the server log."""
    from playwright.sync_api import sync_playwright

    shots_dir = tmp_path / "screenshots"
    shots_dir.mkdir()
    browser_errors: list[str] = []
    t0 = time.monotonic()
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            page.set_default_timeout(PAGE_TIMEOUT * 1000)
            page.on("pageerror", lambda e: browser_errors.append(f"pageerror: {e}"))
            page.on("console", lambda m: browser_errors.append(f"console.{m.type}: {m.text}")
                    if m.type == "error" else None)
            try:
                drive(page, lab, shots_dir)
            except Exception as exc:
                failure_shot = shots_dir / "failure_page.png"
                try:
                    page.screenshot(path=str(failure_shot))
                except Exception as shot_exc:
                    failure_shot = f"(page screenshot failed: {shot_exc})"
                js = "\n".join(browser_errors[-20:]) or "(none)"
                pytest.fail(f"{type(exc).__name__}: {exc}\n\nwhole page: {failure_shot}\n"
                            f"widget screenshots: {shots_dir}\nbrowser errors:\n{js}\n\n"
                            f"{lab.log_tail()}", pytrace=True)
        finally:
            browser.close()
    print(f"[e2e] browser part took {time.monotonic() - t0:.1f} s; "
          f"JS errors: {browser_errors or 'none'}")
