"""The 3D motion editor really responds in JupyterLab, driven with the mouse.

A scratch notebook (written into the server's temporary root next to the copied lessons) builds
``MotionEditor`` on "a person walks" with the shipped generator at 20 steps, writes where the
pelvis path's sample 20 lies on the canvas (pixels, from the editor's own top view) and shows
the widget. In headless Chromium the test drags that handle with the mouse in the top view,
waits for the readout to report the move, presses Regenerate and waits for the new clip (the
readout's pelvis distance must be a few cm, the canvas must look different), then presses Save
and checks that the JSON on disk — ``editor.conditions`` in the kernel — holds the point moved
by the dragged pixels in metres. Widget screenshots go to pytest's ``tmp_path`` (paths printed
with ``-s``).

Same requirements and skips as the other browser tests (harness: :mod:`tests.e2e.browser`):
``/usr/bin/chromium`` and the ``playwright`` package.
"""
from __future__ import annotations

import io
import json
import re
import time

import numpy as np
import pytest

from .browser import (HARD_TIMEOUT, STALL_TIMEOUT, UPDATE_TIMEOUT, _assert_no_errors,
                      _check_errors_then, _draw, _in_browser, _kernel_idle, _wait_until,
                      run_scratch_notebook, widget_readout, write_scratch_notebook)

pytestmark = [pytest.mark.e2e]

NOTEBOOK = "motion_editor_scratch.ipynb"
HANDLE = "pelvis_handle.json"
SAVED = "edited_conditions.json"
BOX_SEL = ".physlab-motion-editor"
INDEX = 20                       # the pelvis sample dragged (a handle: every 4th sample)
DRAG_PX = (45.0, -20.0)          # right (+x) and up the canvas (+z) in the top view
MAX_PELVIS_CM = 5.0
CELL = f"""\
import json
from physlab.viz.motion_editor import MotionEditor

editor = MotionEditor(action="a person walks", generate_options={{"steps": 20}}, file="{SAVED}")
top = editor.views["top"]
p = editor.conditions["trajectories_3d"]["pelvis"][{INDEX}]
with open("{HANDLE}", "w") as f:
    json.dump({{"px": top.to_canvas(p).tolist(), "point": p.tolist(), "scale": top.scale,
               "width": editor.canvas.width}}, f)
editor"""


def _write_notebook(path):
    write_scratch_notebook(path, CELL)


_readout = widget_readout


def _wait_readout(page, box, pattern, what, timeout=UPDATE_TIMEOUT):
    """Wait until the widget's readout matches ``pattern`` (the kernel may stay busy)."""
    _wait_until(page, lambda: _check_errors_then(
        page, lambda: re.search(pattern, _readout(box)), f"while waiting for {what}"),
        timeout, lambda: f"{what} (readout {_readout(box)!r})",
        progress=lambda: not _kernel_idle(page))
    return _readout(box)


def _pixels(png):
    import imageio.v3 as iio

    return iio.imread(io.BytesIO(png))[..., :3].astype(int)


@pytest.mark.e2e
@pytest.mark.timeout(HARD_TIMEOUT)
def test_motion_editor_drag_pelvis_regenerate_and_save(lab, tmp_path):
    _write_notebook(lab.root / NOTEBOOK)
    _in_browser(lab, tmp_path, _drive_editor)


def _drive_editor(page, lab, shots_dir):
    t0 = time.monotonic()
    run_scratch_notebook(page, lab, NOTEBOOK)
    boxes = page.locator(BOX_SEL)
    _wait_until(page, lambda: _check_errors_then(page, lambda: boxes.count() == 1,
                                                 "running the scratch notebook"),
                STALL_TIMEOUT, "the motion editor to render",
                progress=lambda: not _kernel_idle(page))
    box = boxes.first
    box.scroll_into_view_if_needed()
    handle_file = lab.root / HANDLE
    _wait_until(page, lambda: handle_file.is_file(), UPDATE_TIMEOUT, f"{handle_file}")
    handle = json.loads(handle_file.read_text())
    canvas = box.locator("canvas").last                     # the top layer gets the mouse
    assert int(canvas.get_attribute("width")) == handle["width"], (
        f"the browser's canvas is {canvas.get_attribute('width')} px wide, the kernel's "
        f"{handle['width']}: the drag would miss")
    time.sleep(1.0)                                         # let the first drawing land
    shot = shots_dir / "1_shown.png"
    box.screenshot(path=str(shot))
    before = _pixels(canvas.screenshot())
    print(f"[e2e] editor shown after {time.monotonic() - t0:.1f} s: {_readout(box)!r}; {shot}")

    x0, y0 = handle["px"]
    dx, dy = DRAG_PX
    _draw(page, canvas, [(x0, y0)] + [(x0 + dx * k / 6, y0 + dy * k / 6) for k in range(1, 7)])
    text = _wait_readout(page, box, rf"^moved pelvis sample {INDEX}", "the drag to arrive")
    shot = shots_dir / "2_dragged.png"
    box.screenshot(path=str(shot))
    print(f"[e2e] {text}; {shot}")

    box.get_by_role("button", name="Regenerate", exact=True).click()
    text = _wait_readout(page, box, r"^regenerated", "Regenerate", timeout=STALL_TIMEOUT)
    time.sleep(1.0)
    shot = shots_dir / "3_regenerated.png"
    box.screenshot(path=str(shot))
    after = _pixels(canvas.screenshot())
    m = re.search(r"pelvis ([0-9.]+) cm", text)
    assert m, f"the readout names no pelvis distance: {text!r}; see {shot}"
    assert float(m.group(1)) < MAX_PELVIS_CM, (
        f"the regenerated pelvis is {m.group(1)} cm from the edited points on average (limit "
        f"{MAX_PELVIS_CM} cm); see {shot}")
    changed = int(np.count_nonzero(np.abs(after - before).max(axis=-1) > 30)) \
        if after.shape == before.shape else after.size
    assert changed > 200, f"the canvas barely changed ({changed} px) after the drag and "\
                          f"Regenerate; see {shot}"
    print(f"[e2e] {text}; {changed} canvas px changed; {shot}")

    box.get_by_role("button", name="Save", exact=True).click()
    _wait_readout(page, box, r"^saved the conditions", "Save")
    saved = json.loads((lab.root / SAVED).read_text())
    got = np.array(saved["trajectories_3d"]["pelvis"][INDEX])
    s = handle["scale"]
    want = np.array(handle["point"]) + [dx / s, 0.0, -dy / s]   # canvas up = +z
    assert np.linalg.norm(got - want) < 2.0 / s, (
        f"the saved pelvis sample {INDEX} is {got}, expected {want} (the handle at "
        f"{handle['point']} dragged by {DRAG_PX} px at {s:.1f} px/m); see {shot}")
    assert saved["action"] == "a person walks" and len(saved["keypose_3d"]) == 22
    print(f"[e2e] saved pelvis sample {INDEX} at {got} (expected {want}) after "
          f"{time.monotonic() - t0:.1f} s")
    box.get_by_role("button", name="keypose", exact=True).click()   # the keypose handles
    time.sleep(0.5)
    box.screenshot(path=str(shots_dir / "4_keypose_mode.png"))
    _assert_no_errors(page, f"at the end (screenshots in {shots_dir})")
