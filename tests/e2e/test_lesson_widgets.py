"""Lessons' ipywidgets really respond in JupyterLab, driven the way a student does it.

Each test copies ``lessons/`` to a temporary directory, starts JupyterLab there (fresh Jupyter
config and runtime dirs, announcements popup disabled, notebook windowing off), opens one lesson in
headless Debian Chromium through Playwright, runs all cells from the Run menu, then works the
controls of the lesson's ``interact`` boxes, checking that the figure in the right box's output is
redrawn (and only there) and that no error shows up anywhere in the notebook:

* lesson 01: move the ``dt`` slider and pick another integrator in the ``method`` dropdown;
* lesson 04: two boxes; move ``stretch y`` in the first (element demo), then ``E`` in the last
  (ball push), whose redraw must leave the first box's figure alone.
* lesson 06: move ``elbow`` then ``shoulder`` in the arm-dragging box; each shown figure must be
  the one ``arm_pose_demo`` draws for the slider readouts (re-rendered here, pixel-compared), whose
  title reports 0 flipped triangles; the limb box must stay untouched.
* lesson 09: lower the guidance scale ``w`` and pick another action; the motion is re-sampled
  with the shipped checkpoint and redrawn.

Screenshots of the widget boxes (and the decoded PNGs they displayed) go to pytest's ``tmp_path``;
their paths are printed (``-s``) and quoted in failure messages.

Needs ``/usr/bin/chromium`` (``make browser``; override with ``PHYSLAB_E2E_CHROMIUM``) and the
``playwright`` Python package; never ``playwright install``. Skipped when either is missing.
"""
from __future__ import annotations

import json
import math
import re
import time

import pytest

from .browser import (HARD_TIMEOUT, LESSON01, LESSON04, LESSONS, LIVE_BOX_SEL, PAGE_TIMEOUT,
                      STALE_ATTR, STALL_TIMEOUT, UPDATE_TIMEOUT, _assert_no_errors,
                      _check_errors_then, _check_single_figure, _draw, _img_src, _in_browser,
                      _initial_figure, _kernel_idle, _kernel_status, _labels, _open_and_run_all,
                      _png_size, _press_slider, _readout, _snapshot, _wait_new_image, _wait_until)

pytestmark = [pytest.mark.e2e]


@pytest.mark.e2e
@pytest.mark.timeout(HARD_TIMEOUT)
def test_lesson01_interact_widget_redraws_figure(lab, tmp_path):
    _in_browser(lab, tmp_path, _drive_lesson01)


def _move_slider(page, cell, box, shots_dir, label, key, presses, old_src, old_shot, name):
    """Press ``key`` ``presses`` times on the slider ``label``, wait for the redrawn figure,
    snapshot it as ``name`` and check it is one new figure. Returns ``(src, before, after,
    shot)`` (readouts before / after)."""
    handle, before = _press_slider(box, label, key, presses, old_shot)
    src = _wait_new_image(page, box, old_src, f"moving the {label!r} slider")
    after = _readout(handle)
    shot = _snapshot(box, shots_dir, name, src)
    assert src != old_src, f"figure unchanged after moving {label!r}; see {old_shot} and {shot}"
    _check_single_figure(cell, box, shot)
    return src, before, after, shot


def _slider_then_dropdown(page, cell, box, shots_dir, t0, slider, key, presses, dropdown,
                          option, names):
    """Press ``key`` ``presses`` times on the slider labelled ``slider`` (its readout must move
    that way), then pick ``option`` in the dropdown labelled ``dropdown``; each change must
    redraw the one figure of ``box``. ``names``: snapshot names (initial, slider, dropdown).
    Returns the three snapshot paths."""
    src0, shot0 = _initial_figure(page, cell, box, shots_dir, names[0], t0)

    src1, before, after, shot1 = _move_slider(page, cell, box, shots_dir, slider, key, presses,
                                              src0, shot0, names[1])
    moved = after > before if key == "ArrowRight" else after < before
    assert moved, f"{slider!r} readout went {before} -> {after} after {key}; see {shot1}"
    print(f"[e2e] {slider} {before} -> {after}: figure redrawn after "
          f"{time.monotonic() - t0:.1f} s")

    select = box.locator(".widget-dropdown").filter(has_text=dropdown).locator("select")
    assert select.count() == 1, f"no dropdown labelled {dropdown!r} in the widget; see {shot1}"
    select.select_option(option)
    src2 = _wait_new_image(page, box, src1, f"selecting {dropdown} {option!r}")
    shot2 = _snapshot(box, shots_dir, names[2], src2)
    assert src2 not in (src0, src1), (
        f"figure unchanged after selecting {option!r}; see {shot1} and {shot2}")
    _check_single_figure(cell, box, shot2)
    print(f"[e2e] {dropdown} {option!r}: figure redrawn after {time.monotonic() - t0:.1f} s")
    return shot0, shot1, shot2


def _drive_lesson01(page, lab, shots_dir):
    t0 = time.monotonic()
    [(cell, box)] = _open_and_run_all(page, lab, LESSON01, 1, t0)
    shots = _slider_then_dropdown(page, cell, box, shots_dir, t0, "dt (s)", "ArrowRight", 3,
                                  "method", "rk4", ("1_initial", "2_dt_moved", "3_rk4"))
    _assert_no_errors(page, f"at the end (widget screenshots: {', '.join(map(str, shots))})")


LESSON04_ELEMENT_CONTROLS = ["stretch x", "stretch y (< 0 inverts)", "shear", "rotation (°)", "ν"]
LESSON04_BALL_CONTROLS = ["E", "ν", "dt (s)"]


@pytest.mark.e2e
@pytest.mark.timeout(HARD_TIMEOUT)
def test_lesson04_two_interact_widgets_redraw_independently(lab, tmp_path):
    _in_browser(lab, tmp_path, _drive_lesson04)


def _drive_lesson04(page, lab, shots_dir):
    t0 = time.monotonic()
    (el_cell, el_box), (ball_cell, ball_box) = _open_and_run_all(page, lab, LESSON04, 2, t0)
    # First box: element_demo (mesh + force arrows); last box: ball_push_demo (filmstrip).
    for box, expected in ((el_box, LESSON04_ELEMENT_CONTROLS), (ball_box, LESSON04_BALL_CONTROLS)):
        assert _labels(box) == expected, f"widget controls {_labels(box)}, expected {expected}"
    el0, el_shot0 = _initial_figure(page, el_cell, el_box, shots_dir, "1_element_initial", t0)
    ball0, ball_shot0 = _initial_figure(page, ball_cell, ball_box, shots_dir, "2_ball_initial", t0,
                                        min_size=(400, 100))

    # 1) First box: squash the patch with "stretch y" (5 steps of 0.05 to the left).
    sy, sy_before = _press_slider(el_box, "stretch y (< 0 inverts)", "ArrowLeft", 5, el_shot0)
    el1 = _wait_new_image(page, el_box, el0, "moving the 'stretch y' slider")
    sy_after = _readout(sy)
    el_shot1 = _snapshot(el_box, shots_dir, "3_element_stretch_y", el1)
    assert sy_after < sy_before, f"stretch y readout went {sy_before} -> {sy_after}; see {el_shot1}"
    assert el1 != el0, f"element figure unchanged after moving stretch y; see {el_shot0}, {el_shot1}"
    _check_single_figure(el_cell, el_box, el_shot1)
    assert _img_src(ball_box) == ball0, (
        f"moving 'stretch y' in the first widget redrew the last one; see {ball_shot0}")
    print(f"[e2e] stretch y {sy_before} -> {sy_after}: element figure redrawn after "
          f"{time.monotonic() - t0:.1f} s")

    # 2) Last box: stiffen the ball with "E" (log slider, 3 steps to the right). Tag the first
    #    box's <img> so that a redraw there shows even if it drew the very same PNG.
    el_img = el_box.locator(".widget-output img")
    el_img.evaluate("img => img.setAttribute('data-e2e-before-E', '1')")
    e_slider, e_before = _press_slider(ball_box, "E", "ArrowRight", 3, ball_shot0)
    ball1 = _wait_new_image(page, ball_box, ball0, "moving the 'E' slider")
    e_after = _readout(e_slider)
    ball_shot1 = _snapshot(ball_box, shots_dir, "4_ball_E", ball1)
    assert e_after > e_before, f"E readout went {e_before} -> {e_after}; see {ball_shot1}"
    assert ball1 != ball0, f"ball figure unchanged after moving E; see {ball_shot0}, {ball_shot1}"
    _check_single_figure(ball_cell, ball_box, ball_shot1)
    el_shot2 = _snapshot(el_box, shots_dir, "5_element_after_E", _img_src(el_box))
    assert _img_src(el_box) == el1, (
        f"moving 'E' in the last widget changed the first widget's figure; see {el_shot1} and "
        f"{el_shot2}")
    assert el_box.locator(".widget-output img[data-e2e-before-E]").count() == 1, (
        f"moving 'E' in the last widget redrew the first widget's figure; see {el_shot2}")
    _check_single_figure(el_cell, el_box, el_shot2)
    print(f"[e2e] E {e_before} -> {e_after}: ball figure redrawn, element figure untouched after "
          f"{time.monotonic() - t0:.1f} s")

    assert page.locator(LIVE_BOX_SEL).count() == 2, "the number of interactive widgets changed"
    _assert_no_errors(page, f"at the end (widget screenshots in {shots_dir})")


LESSON06 = "06_skeleton_driven_deformation.ipynb"
LESSON06_ARM_CONTROLS = ["shoulder (°)", "elbow (°)", "drawing style"]
LESSON06_LIMB_CONTROLS = ["bend (°)", "method"]
MAX_DIFFERING_PIXELS = 20  # a re-rendered figure may differ by antialiasing, not by a title digit


@pytest.mark.e2e
@pytest.mark.timeout(HARD_TIMEOUT)
def test_lesson06_arm_widget_deforms_the_drawing_without_flips(lab, tmp_path):
    _in_browser(lab, tmp_path, _drive_lesson06)


def _callback_png(**params):
    """``arm_pose_demo(**params)`` rendered in this process the way the kernel's inline backend
    renders a Figure for the widget; returns (title, RGBA array)."""
    import io

    from IPython.core.pylabtools import print_figure
    from matplotlib.image import imread

    from physlab.demos.inbetween_deformation import arm_pose_demo

    fig = arm_pose_demo(**params)
    return fig.get_suptitle(), imread(io.BytesIO(print_figure(fig, "png", bbox_inches="tight")))


def _assert_shows_arm_pose(src, shot, **params):
    """The browser's widget image is the figure of ``arm_pose_demo(**params)``, whose title
    reports 0 flipped triangles: the flip count the student sees is the one checked here."""
    import io

    import numpy as np
    from matplotlib.image import imread

    title, expected = _callback_png(**params)
    shown = imread(io.BytesIO(_png_size(src)[0]))
    assert shown.shape == expected.shape, (
        f"widget figure {shown.shape} is not arm_pose_demo({params}) {expected.shape}; see {shot}")
    differ = int(np.count_nonzero(np.abs(shown - expected).max(axis=-1) > 1.5 / 255))
    assert differ <= MAX_DIFFERING_PIXELS, (
        f"widget figure differs from arm_pose_demo({params}) in {differ} pixels; see {shot}")
    m = re.search(r"flipped triangles (\d+)", title)
    assert m and m.group(1) == "0", f"the figure's title reports flips: {title!r}; see {shot}"
    print(f"[e2e] widget shows arm_pose_demo({params}) ({differ} pixels differ): {title!r}")


def _drive_lesson06(page, lab, shots_dir):
    t0 = time.monotonic()
    (arm_cell, arm_box), (limb_cell, limb_box) = _open_and_run_all(page, lab, LESSON06, 2, t0)
    for box, expected in ((arm_box, LESSON06_ARM_CONTROLS), (limb_box, LESSON06_LIMB_CONTROLS)):
        assert _labels(box) == expected, f"widget controls {_labels(box)}, expected {expected}"
    arm0, shot0 = _initial_figure(page, arm_cell, arm_box, shots_dir, "1_arm_initial", t0,
                                  min_size=(500, 250))
    limb0, limb_shot0 = _initial_figure(page, limb_cell, limb_box, shots_dir, "2_limb_initial", t0)
    _assert_shows_arm_pose(arm0, shot0, shoulder_deg=-60.0, elbow_deg=-60.0)

    # 1) Bend the elbow further: 8 steps of 5° to the left (each press is one committed solve).
    arm1, el_before, el_after, shot1 = _move_slider(page, arm_cell, arm_box, shots_dir,
                                                    "elbow (°)", "ArrowLeft", 8, arm0, shot0,
                                                    "3_arm_elbow")
    assert el_after == el_before - 40.0, (
        f"elbow readout went {el_before} -> {el_after}; see {shot1}")
    _assert_shows_arm_pose(arm1, shot1, shoulder_deg=-60.0, elbow_deg=el_after)

    # 2) Raise the shoulder: 12 steps of 5° to the left (arm above the head).
    arm2, sh_before, sh_after, shot2 = _move_slider(page, arm_cell, arm_box, shots_dir,
                                                    "shoulder (°)", "ArrowLeft", 12, arm1, shot1,
                                                    "4_arm_shoulder")
    assert sh_after == sh_before - 60.0, (
        f"shoulder readout went {sh_before} -> {sh_after}; see {shot2}")
    assert arm2 != arm0, f"arm figure back to the first one after moving the shoulder; see {shot2}"
    _assert_shows_arm_pose(arm2, shot2, shoulder_deg=sh_after, elbow_deg=el_after)
    assert _img_src(limb_box) == limb0, (
        f"moving the arm sliders redrew the limb widget; see {limb_shot0}")
    print(f"[e2e] shoulder {sh_before} -> {sh_after}, elbow {el_before} -> {el_after}: redrawn, "
          f"0 flips, after {time.monotonic() - t0:.1f} s")
    _assert_no_errors(page, f"at the end (widget screenshots in {shots_dir})")


LESSON09 = "09_motion_diffusion.ipynb"
LESSON09_CONTROLS = ["guidance scale w", "action"]


@pytest.mark.e2e
@pytest.mark.timeout(HARD_TIMEOUT)
def test_lesson09_guidance_widget_regenerates_the_motion(lab, tmp_path):
    _in_browser(lab, tmp_path, _drive_lesson09)


def _drive_lesson09(page, lab, shots_dir):
    """Lesson 09 (shipped motion checkpoint): lower the classifier-free guidance scale w, then
    ask for another action; each change must sample and draw a new motion."""
    t0 = time.monotonic()
    [(cell, box)] = _open_and_run_all(page, lab, LESSON09, 1, t0)
    assert _labels(box) == LESSON09_CONTROLS, (
        f"widget controls {_labels(box)}, expected {LESSON09_CONTROLS}")
    shots = _slider_then_dropdown(page, cell, box, shots_dir, t0, "guidance scale w",
                                  "ArrowLeft", 5, "action", "a person runs",
                                  ("1_initial", "2_w_lowered", "3_runs"))
    _assert_no_errors(page, f"at the end (widget screenshots: {', '.join(map(str, shots))})")


# --------------------------------------------------------------------------- lesson 10: drawing
LESSON10 = "10_sketch_to_motion.ipynb"
CANVAS_SEL = ".physlab-sketch-canvas"
LIVE_CANVAS_SEL = f"{CANVAS_SEL}:not([{STALE_ATTR}])"
# A stick figure and a pelvis stroke in canvas pixels (480 x 400 canvas), drawn with the mouse
HEAD = [(150 + 16 * math.cos(a), 110 + 16 * math.sin(a))
        for a in [2 * math.pi * k / 24 for k in range(25)]]
FIGURE = [HEAD, [(150, 128), (150, 175), (150, 225)],                  # head, body
          [(110, 205), (130, 170), (150, 145), (170, 170), (190, 205)],  # both arms in one line
          [(150, 225), (138, 280), (132, 335), (122, 340)],              # legs
          [(150, 225), (162, 280), (168, 335), (178, 340)]]
PELVIS_STROKE = [(152 + 12 * k, 227 + (k * k) * 0.12) for k in range(22)]
MAX_PELVIS_PX = 15.0


@pytest.mark.e2e
@pytest.mark.timeout(HARD_TIMEOUT)
def test_lesson10_draw_a_sketch_and_generate(lab, tmp_path):
    _in_browser(lab, tmp_path, _drive_lesson10)


def _canvas_readout(box):
    return box.locator(".widget-html").last.inner_text().strip()


def _drive_lesson10(page, lab, shots_dir):
    """Lesson 10: clear the example sketch, draw a stick figure and a pelvis stroke with the
    mouse, snap the joints, press Generate; the motion's projected pelvis must follow the
    drawn stroke (the readout's pixel distance) and the 3D result must show as an image."""
    t0 = time.monotonic()
    page.goto(f"{lab.url}/lab/tree/{LESSON10}?token={lab.token}", wait_until="domcontentloaded")
    page.locator(".jp-Notebook .jp-Cell").first.wait_for(timeout=PAGE_TIMEOUT * 1000)
    _wait_until(page, lambda: _kernel_idle(page), PAGE_TIMEOUT,
                lambda: f"the kernel to be idle (status {_kernel_status(page)!r})")
    page.evaluate(f"document.querySelectorAll('{CANVAS_SEL}')"
                  f".forEach(e => e.setAttribute('{STALE_ATTR}', '1'))")
    page.locator(".lm-MenuBar-item", has_text=re.compile(r"^\s*Run\s*$")).click()
    page.locator(".lm-Menu-item", has_text=re.compile(r"^\s*Run All Cells")).first.click()
    prompts = page.locator(".jp-InputPrompt")
    boxes = page.locator(LIVE_CANVAS_SEL)

    def all_ran():
        return boxes.count() == 1 and not any("*" in t for t in prompts.all_inner_texts())

    _wait_until(page, lambda: _check_errors_then(page, all_ran, "during Run All"),
                STALL_TIMEOUT, "all cells to run and the sketch canvas to render",
                progress=lambda: sum(bool(re.search(r"\d", t))
                                     for t in prompts.all_inner_texts()))
    box = boxes.first
    box.scroll_into_view_if_needed()
    print(f"[e2e] lesson 10 ran, canvas shown after {time.monotonic() - t0:.1f} s")
    box.screenshot(path=str(shots_dir / "1_example.png"))
    box.get_by_role("button", name="Clear", exact=True).click()
    _wait_until(page, lambda: _canvas_readout(box) == "cleared", UPDATE_TIMEOUT,
                lambda: f"the canvas to clear (readout {_canvas_readout(box)!r})")
    canvas = box.locator("canvas").last                     # the top layer gets the mouse
    for k, stroke in enumerate(FIGURE, start=1):
        _draw(page, canvas, stroke)
        _wait_until(page, lambda: _canvas_readout(box).startswith(f"{k} pose and 0 trajectory"),
                    UPDATE_TIMEOUT, lambda: f"pose stroke {k} to arrive (readout "
                                            f"{_canvas_readout(box)!r})")
    box.get_by_role("button", name="trajectory", exact=True).click()
    _draw(page, canvas, PELVIS_STROKE)
    _wait_until(page, lambda: _canvas_readout(box).endswith("1 trajectory strokes"),
                UPDATE_TIMEOUT, lambda: f"the trajectory stroke to arrive (readout "
                                        f"{_canvas_readout(box)!r})")
    box.get_by_role("button", name="Snap joints", exact=True).click()
    _wait_until(page, lambda: "snapped" in _canvas_readout(box), UPDATE_TIMEOUT,
                lambda: f"the joints to snap (readout {_canvas_readout(box)!r})")
    box.screenshot(path=str(shots_dir / "2_drawn.png"))
    box.get_by_role("button", name="Generate", exact=True).click()
    _wait_until(page, lambda: _check_errors_then(
        page, lambda: _canvas_readout(box).startswith("generated"), "while generating"),
        STALL_TIMEOUT, lambda: f"the motion (readout {_canvas_readout(box)!r})",
        progress=lambda: not _kernel_idle(page))
    text = _canvas_readout(box)
    shot = shots_dir / "3_generated.png"
    box.screenshot(path=str(shot))
    m = re.search(r"pelvis ([0-9.]+) px", text)
    assert m, f"the readout names no pelvis error: {text!r}; see {shot}"
    assert float(m.group(1)) < MAX_PELVIS_PX, (
        f"the projected pelvis is {m.group(1)} px from the drawn stroke on average (limit "
        f"{MAX_PELVIS_PX}); see {shot}")
    img = box.locator("img").last
    assert img.evaluate("i => i.naturalWidth") > 200, f"no 3D result image; see {shot}"
    print(f"[e2e] lesson 10: drew {len(FIGURE)} pose strokes and a pelvis stroke, generated "
          f"after {time.monotonic() - t0:.1f} s: {text}")
    _assert_no_errors(page, f"at the end (screenshots in {shots_dir})")


# --------------------------------------------------------------------------- every other lesson
SPECIFIC_TESTS = {LESSON01, LESSON04, LESSON06, LESSON09, LESSON10}


def _widget_cells(path):
    """Number of code cells of a lesson that build an ``interact`` widget."""
    nb = json.loads(path.read_text(encoding="utf-8"))
    return sum(1 for c in nb["cells"] if c["cell_type"] == "code"
               and re.search(r"(?m)^\s*(\w+\s*=\s*)?interact\(", "".join(c["source"])))


WIDGET_LESSONS = {p.name: n for p in sorted(LESSONS.glob("*.ipynb")) if (n := _widget_cells(p))}


def test_every_widget_lesson_is_driven_in_the_browser():
    """No lesson with widgets escapes the browser tests (collected without a browser)."""
    canvases = {p.name for p in LESSONS.glob("*.ipynb") if "SketchCanvas(" in p.read_text()}
    assert SPECIFIC_TESTS <= set(WIDGET_LESSONS) | canvases, sorted(WIDGET_LESSONS)
    assert canvases <= SPECIFIC_TESTS, sorted(canvases)
    assert len(WIDGET_LESSONS) >= 8, sorted(WIDGET_LESSONS)


@pytest.mark.e2e
@pytest.mark.timeout(2 * HARD_TIMEOUT)
@pytest.mark.parametrize("lesson", sorted(set(WIDGET_LESSONS) - SPECIFIC_TESTS))
def test_lesson_widgets_render_and_redraw(lab, tmp_path, lesson):
    """Any other lesson: every widget draws one figure with usable sliders; moving the first
    slider of each box (or picking the next option of its first dropdown) redraws it."""
    _in_browser(lab, tmp_path, lambda page, lab, shots: _drive_any(page, lab, shots, lesson))


def _drive_any(page, lab, shots_dir, lesson):
    t0 = time.monotonic()
    pairs = _open_and_run_all(page, lab, lesson, WIDGET_LESSONS[lesson], t0)
    srcs = [_initial_figure(page, cell, box, shots_dir, f"{k}_initial", t0, min_size=(200, 100))
            for k, (cell, box) in enumerate(pairs)]
    for k, ((cell, box), (src, shot)) in enumerate(zip(pairs, srcs)):
        if box.locator(".widget-slider").count():
            label = box.locator(".widget-slider .widget-label").first.inner_text().strip()
            handle, before = _press_slider(box, label, "ArrowRight", 1, shot)
            if _readout(handle) == before:                     # already at its maximum
                handle.locator(".noUi-handle").press("ArrowLeft")
            what = f"moving the {label!r} slider"
        else:
            select = box.locator(".widget-dropdown select").first
            options = select.locator("option").all_inner_texts()
            current = select.evaluate("s => s.selectedIndex")
            select.select_option(index=(current + 1) % len(options))
            what = f"picking {options[(current + 1) % len(options)]!r}"
        new = _wait_new_image(page, box, src, what)
        shot2 = _snapshot(box, shots_dir, f"{k}_moved", new)
        _check_single_figure(cell, box, shot2)
        print(f"[e2e] {lesson} box {k}: {what} redrew the figure after "
              f"{time.monotonic() - t0:.1f} s")
    _assert_no_errors(page, f"at the end (widget screenshots in {shots_dir})")
