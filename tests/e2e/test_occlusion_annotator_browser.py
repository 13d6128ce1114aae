"""The occlusion annotator really responds in JupyterLab, driven with the mouse.

A scratch notebook (written into the server's temporary root next to the copied lessons) builds
``OcclusionAnnotator`` on key 1 of the ``fold_arm`` pair at 160 px (forearm across the belly,
one region with two T-junctions), saves the annotation and shows the widget. In headless
Chromium the test then picks the ``t-junction`` mode, clicks the region's outline far from the
existing T-junctions, presses Save and checks that the JSON on disk gained that T-junction;
clicks the new dot again (removed), presses Solve and waits for the coloured contours. Widget
screenshots go to pytest's ``tmp_path`` (paths printed with ``-s``).

Same requirements and skips as the other browser tests (harness: :mod:`tests.e2e.browser`):
``/usr/bin/chromium`` and the ``playwright`` package.
"""
from __future__ import annotations

import json
import re
import time

import numpy as np
import pytest

from .browser import (HARD_TIMEOUT, STALL_TIMEOUT, UPDATE_TIMEOUT, _assert_no_errors,
                      _check_errors_then, _draw, _in_browser, _kernel_idle, _wait_until,
                      run_scratch_notebook, widget_readout, write_scratch_notebook)

pytestmark = [pytest.mark.e2e]

SIZE = 160
NOTEBOOK = "occlusion_annotator_scratch.ipynb"
ANNOTATION = "fold_arm_key1.json"
BOX_SEL = ".physlab-occlusion-annotator"
CELL = f"""\
from physlab.inbetween import occlusion_benchmark
from physlab.viz.occlusion_annotator import OcclusionAnnotator

pair = next(p for p in occlusion_benchmark({SIZE}) if p.name == "fold_arm")
k0, k1 = pair.keyframes()
o0, o1 = pair.occlusions()
a = OcclusionAnnotator(k1, pair.skeleton1, occlusions=o1, target_skeleton=pair.skeleton0,
                       file="{ANNOTATION}")
a.save()
a"""


def _write_notebook(path):
    write_scratch_notebook(path, CELL)


def _t_junctions(path):
    return [p for o in json.loads(path.read_text())["occlusions"] for p in o["t_junctions"]]


def _click_target():
    """The point on the region's outline farthest from its two T-junctions: ``(keyframe px,
    the same annotator built here)``, whose ``to_canvas`` gives the canvas pixels to click."""
    from physlab.inbetween import occlusion_benchmark
    from physlab.mesh import boundary_polygon
    from physlab.viz.occlusion_annotator import OcclusionAnnotator

    pair = next(p for p in occlusion_benchmark(SIZE) if p.name == "fold_arm")
    k1, (occ,) = pair.keyframes()[1], pair.occlusions()[1]
    P = boundary_polygon(occ.mask, epsilon=0.5)
    d = np.linalg.norm(P[:, None] - occ.t_junctions[None], axis=2).min(axis=1)
    return P[np.argmax(d)], OcclusionAnnotator(k1, pair.skeleton1, occlusions=[occ])


_readout = widget_readout


def _wait_readout(page, box, pattern, what, timeout=UPDATE_TIMEOUT):
    """Wait until the widget's readout matches ``pattern`` (the kernel may stay busy: Solve)."""
    _wait_until(page, lambda: _check_errors_then(
        page, lambda: re.search(pattern, _readout(box)), f"while waiting for {what}"),
        timeout, lambda: f"{what} (readout {_readout(box)!r})",
        progress=lambda: not _kernel_idle(page))
    return _readout(box)


@pytest.mark.e2e
@pytest.mark.timeout(HARD_TIMEOUT)
def test_occlusion_annotator_click_t_junction_and_save(lab, tmp_path):
    _write_notebook(lab.root / NOTEBOOK)
    _in_browser(lab, tmp_path, _drive_annotator)


def _drive_annotator(page, lab, shots_dir):
    t0 = time.monotonic()
    saved = lab.root / ANNOTATION
    run_scratch_notebook(page, lab, NOTEBOOK)
    boxes = page.locator(BOX_SEL)
    _wait_until(page, lambda: _check_errors_then(page, lambda: boxes.count() == 1,
                                                 "running the scratch notebook"),
                STALL_TIMEOUT, "the occlusion annotator to render",
                progress=lambda: not _kernel_idle(page))
    box = boxes.first
    box.scroll_into_view_if_needed()
    _wait_until(page, lambda: saved.is_file(), UPDATE_TIMEOUT, f"the first save to {saved}")
    before = _t_junctions(saved)
    assert len(before) == 2, f"the true annotation has 2 T-junctions, {saved} holds {before}"
    print(f"[e2e] annotator shown after {time.monotonic() - t0:.1f} s: {_readout(box)!r}")
    box.screenshot(path=str(shots_dir / "1_shown.png"))

    box.get_by_role("button", name="t-junction", exact=True).click()
    canvas = box.locator("canvas").last                     # the top layer gets the mouse
    target, same = _click_target()
    assert int(canvas.get_attribute("width")) == same.canvas.width, (
        f"the browser's canvas is {canvas.get_attribute('width')} px wide, the annotator built "
        f"here {same.canvas.width}: the click would miss")
    _draw(page, canvas, [tuple(same.to_canvas(target))])
    text = _wait_readout(page, box, r"^added a T-junction", "the T-junction click")
    m = re.search(r"at \(([\d.]+), ([\d.]+)\)", text)
    added = np.array([float(m.group(1)), float(m.group(2))])
    box.get_by_role("button", name="Save", exact=True).click()
    _wait_readout(page, box, r"^saved 1 region", "Save")
    after = _t_junctions(saved)
    shot = shots_dir / "2_t_junction_saved.png"
    box.screenshot(path=str(shot))
    assert len(after) == len(before) + 1, (
        f"{saved} holds {len(after)} T-junctions after the click and Save, expected "
        f"{len(before) + 1}; see {shot}")
    new = np.array([p for p in after if p not in before])
    assert len(new) == 1 and np.linalg.norm(new[0] - added) < 0.1, (
        f"the saved new T-junction {new} is not the one the readout reported ({added}); "
        f"see {shot}")
    assert np.linalg.norm(new[0] - target) < 2.0, (
        f"the new T-junction {new[0]} is not where the test clicked ({target}); see {shot}")
    print(f"[e2e] clicked T-junction at {new[0]} saved after {time.monotonic() - t0:.1f} s")

    _draw(page, canvas, [tuple(same.to_canvas(added))])     # click the new dot: removed
    _wait_readout(page, box, r"^removed the T-junction", "removing the T-junction")
    box.get_by_role("button", name="Solve", exact=True).click()
    text = _wait_readout(page, box, r"^solved in", "Solve", timeout=STALL_TIMEOUT)
    shot = shots_dir / "3_solved.png"
    box.scroll_into_view_if_needed()
    box.screenshot(path=str(shot))
    vis, hid = map(int, re.search(r"(\d+) visible .* (\d+) hidden", text).groups())
    assert vis > 0 and hid > 0, f"Solve coloured no visible or no hidden edge: {text!r}; {shot}"
    assert "chosen" in box.inner_text(), f"no energies listed after Solve; see {shot}"
    print(f"[e2e] {text} after {time.monotonic() - t0:.1f} s; screenshot {shot}")
    _assert_no_errors(page, f"at the end (screenshots in {shots_dir})")
