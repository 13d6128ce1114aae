"""The storyboard editor really generates and exports in JupyterLab.

A scratch notebook (written into the server's temporary root next to the copied lessons) loads
``data/motion/example_storyboard.json`` (walk with a drawn sketch, bow, wave) into
``StoryboardEditor`` with fast options (20 DDIM steps, no guidance) and shows it. In headless
Chromium the test presses Generate, watches the progress bar over the frames and junctions
appear, waits for the preview animation (a GIF in an ``<img>``) and the status line, presses
Export and reads the exported BVH back with
:func:`~physlab.viz.storyboard_view.check_bvh`: 3 clips of 40 frames joined by 2 transitions
of 20 = 160 frames. Widget screenshots go to pytest's ``tmp_path`` (paths printed with ``-s``).

Same requirements and skips as the other browser tests (harness: :mod:`tests.e2e.browser`):
``/usr/bin/chromium`` and the ``playwright`` package.
"""
from __future__ import annotations

import re
import time

import pytest

from .browser import (HARD_TIMEOUT, REPO, STALL_TIMEOUT, _assert_no_errors, _check_errors_then,
                      _in_browser, _kernel_idle, _wait_until, run_scratch_notebook,
                      widget_readout, write_scratch_notebook)

pytestmark = [pytest.mark.e2e]

NOTEBOOK = "storyboard_editor_scratch.ipynb"
EXPORT = "storyboard_export"
EXAMPLE = REPO / "data" / "motion" / "example_storyboard.json"
BOX_SEL = ".physlab-storyboard-editor"
VIEWPORT_HEIGHT = 2000
N_FRAMES = 3 * 40 + 2 * 20            # three 40-frame clips, two 20-frame transitions (default)
CELL = f"""\
from physlab.viz.storyboard_editor import StoryboardEditor

editor = StoryboardEditor({str(EXAMPLE)!r},
                          generate_options={{"steps": 20, "guidance_final": 0}},
                          export_dir={EXPORT!r})
editor"""


def _write_notebook(path):
    write_scratch_notebook(path, CELL)


_readout = widget_readout


def _preview_width(box):
    """Natural width of the preview animation (0 while there is none)."""
    img = box.locator(".physlab-storyboard-preview")
    if not img.count() or not img.first.is_visible():
        return 0
    return img.first.evaluate("i => i.complete ? i.naturalWidth : 0")


@pytest.mark.e2e
@pytest.mark.timeout(HARD_TIMEOUT)
def test_storyboard_editor_generates_and_exports(lab, tmp_path):
    _write_notebook(lab.root / NOTEBOOK)
    _in_browser(lab, tmp_path, _drive_editor)


def _drive_editor(page, lab, shots_dir):
    from physlab.viz.storyboard_view import check_bvh

    t0 = time.monotonic()
    # A tall window: JupyterLab scrolls inside its own panel, so a widget taller than the
    # window would be cut in the screenshots.
    page.set_viewport_size({"width": 1280, "height": VIEWPORT_HEIGHT})
    run_scratch_notebook(page, lab, NOTEBOOK)
    boxes = page.locator(BOX_SEL)
    _wait_until(page, lambda: _check_errors_then(page, lambda: boxes.count() == 1
                                                 and _kernel_idle(page),
                                                 "running the scratch notebook"),
                STALL_TIMEOUT, "the storyboard editor to render",
                progress=lambda: not _kernel_idle(page))
    box = boxes.first
    thumbs = box.locator("img").count()
    print(f"[e2e] editor shown after {time.monotonic() - t0:.1f} s: {_readout(box)!r}")
    box.screenshot(path=str(shots_dir / "1_shown.png"))
    assert box.get_by_role("button", name=re.compile(r"^3: ")).count() == 1, (
        f"the strip does not show the example's 3 frames; see {shots_dir / '1_shown.png'}")
    assert thumbs >= 3, f"no thumbnails in the strip; see {shots_dir / '1_shown.png'}"

    box.get_by_role("button", name="Generate", exact=True).click()
    bars = set()

    def generated():
        out = box.locator(".widget-output").first     # tqdm's bar inside the widget
        if out.locator(".progress").count():
            bars.add(re.sub(r"\s+", " ", out.inner_text()).strip()[:40])
        return _readout(box).startswith("generated") and _preview_width(box) > 0

    _wait_until(page, lambda: _check_errors_then(page, generated, "while generating"),
                STALL_TIMEOUT, lambda: f"the preview animation (status {_readout(box)!r})",
                progress=lambda: not _kernel_idle(page))
    text = _readout(box)
    preview = box.locator(".physlab-storyboard-preview").first
    preview.scroll_into_view_if_needed()
    shot = shots_dir / "2_generated.png"
    box.screenshot(path=str(shot))
    print(f"[e2e] generated after {time.monotonic() - t0:.1f} s: {text!r}; progress bar "
          f"states seen: {sorted(bars)}; screenshot {shot}")
    assert bars, f"no progress bar appeared in the widget while generating; see {shot}"
    assert f"generated {N_FRAMES} frames" in text, f"status {text!r}; see {shot}"
    src = preview.get_attribute("src") or ""
    width = _preview_width(box)
    assert width == 640, (f"the preview is {width} px wide, expected the capsule human and the "
                          f"sketch overlay side by side (2 x 320); src {src[:40]!r}; see {shot}")
    assert "a person waves the right hand" in box.inner_text(), f"no timeline; see {shot}"

    box.get_by_role("button", name="Export", exact=True).click()
    _wait_until(page, lambda: _check_errors_then(
        page, lambda: _readout(box).startswith("exported"), "while exporting"),
        STALL_TIMEOUT, lambda: f"the export (status {_readout(box)!r})",
        progress=lambda: not _kernel_idle(page))
    text = _readout(box)
    shot = shots_dir / "3_exported.png"
    box.screenshot(path=str(shot))
    m = re.search(r"exported (\d+) files \((\d+) frames\)", text)
    assert m and int(m.group(2)) == N_FRAMES, f"status {text!r}; see {shot}"
    bvh = lab.root / EXPORT / "storyboard.bvh"
    assert bvh.is_file(), f"{bvh} was not written; status {text!r}; see {shot}"
    info = check_bvh(bvh, n_frames=N_FRAMES)
    assert "storyboard.bvh" in box.inner_text(), f"the written files are not listed; see {shot}"
    print(f"[e2e] exported after {time.monotonic() - t0:.1f} s: {text!r}; {bvh} has "
          f"{info['n_frames']} frames at {info['fps']:g} fps; screenshot {shot}")
    _assert_no_errors(page, f"at the end (screenshots in {shots_dir})")
