"""The occlusion annotator in a kernel (the browser test clicks it in JupyterLab): mouse events
paint and erase masks, draw polygons, add and remove T-junctions; the depth control writes the
skeleton's depth; Save / Load round-trip; Solve colours the contours of the fold_arm pair;
bad input shows a readable message."""
from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("ipycanvas")

from physlab.inbetween import (Occlusion, Skeleton, load_occlusions,  # noqa: E402
                               occlusion_benchmark)
from physlab.mesh import boundary_polygon  # noqa: E402
from physlab.viz.occlusion_annotator import OcclusionAnnotator  # noqa: E402

SIZE = 160


@pytest.fixture(scope="module")
def fold():
    """The fold_arm pair: key 1 has the left forearm across the belly (one true region with
    two T-junctions)."""
    pair = next(p for p in occlusion_benchmark(SIZE) if p.name == "fold_arm")
    k0, k1 = pair.keyframes()
    o0, o1 = pair.occlusions()
    return pair, k1, o1


def _plain(sk):
    """The skeleton without depths."""
    return Skeleton(sk.names, sk.parents, sk.xy)


def _drag(a, points):
    """Mouse events at keyframe pixels ``points`` as the canvas delivers them (canvas pixels,
    through the error guard)."""
    P = a.to_canvas(np.asarray(points, float).reshape(-1, 2))
    a._guard(a._on_down, *P[0])
    for p in P[1:]:
        a._guard(a._on_move, *p)
    a._guard(a._on_up, *P[-1])


def _far_outline_point(o):
    """The outline vertex of an occlusion farthest from its T-junctions."""
    P = boundary_polygon(o.mask, epsilon=0.5)
    d = np.linalg.norm(P[:, None] - o.t_junctions[None], axis=2).min(axis=1)
    return P[np.argmax(d)]


def test_canvas_shows_the_drawing_enlarged(fold):
    pair, k1, o1 = fold
    whole = OcclusionAnnotator(k1, pair.skeleton1, occlusions=[], crop=False)
    assert whole.scale == 3 and (whole.canvas.width, whole.canvas.height) == (480, 480)
    np.testing.assert_allclose(whole.to_canvas([0.0, 0.0]), [1.5, 1.5])  # pixel [0, 0]'s centre
    a = OcclusionAnnotator(k1, pair.skeleton1, occlusions=[])           # cropped to the drawing
    x0, y0, x1, y1 = a.view
    ys, xs = np.nonzero(a.foreground)
    assert x0 < xs.min() and xs.max() < x1 and y0 < ys.min() and ys.max() < y1
    assert (x1 - x0) * (y1 - y0) < 0.6 * SIZE ** 2 and a.scale == 4
    assert (a.canvas.width, a.canvas.height) == ((x1 - x0) * 4, (y1 - y0) * 4)
    np.testing.assert_allclose(a.to_image(*a.to_canvas([52.0, 34.0])), [52.0, 34.0])
    np.testing.assert_allclose(a.to_canvas([x0, y0]), [2.0, 2.0])


def test_painting_and_erasing_edit_the_current_mask(fold):
    pair, k1, o1 = fold
    a = OcclusionAnnotator(k1, pair.skeleton1, occlusions=[], suggest=False)
    assert a.regions == [] and a.occlusions == [] and a.current is None
    chest = pair.skeleton1.xy[pair.skeleton1.index("chest")]
    a.brush.value = 3
    _drag(a, [chest, chest + [8, 0], chest + [8, 6]])         # the first stroke starts a region
    assert a.current == 0 and len(a.occlusions) == 1
    m = a.regions[0].mask
    painted = int(m.sum())
    assert m[int(chest[1]), int(chest[0])] and m[int(chest[1]) + 6, int(chest[0]) + 8]
    assert 60 < painted < 200 and f"painted {painted} px" in a.status
    assert "chest" in a.joints_near()                        # the depth control follows
    a.mode.value = "erase"
    _drag(a, [chest, chest + [2, 0]])
    assert not m[int(chest[1]), int(chest[0])] and 0 < m.sum() < painted
    assert "erased" in a.status
    a.delete.click()
    assert a.regions == [] and a.current is None
    _drag(a, [chest])                                         # nothing to erase: said, not raised
    assert "no region to erase from" in a.status


def test_polygon_mode_makes_a_region(fold):
    pair, k1, o1 = fold
    a = OcclusionAnnotator(k1, pair.skeleton1, occlusions=o1)
    a.mode.value = "polygon"
    square = [(60, 80), (76, 80), (76, 92), (60, 92)]
    for p in square[:2]:
        _drag(a, [p])
    a.close.click()                                           # two corners: an error, shown
    assert "at least 3 corners" in a.status and len(a.regions) == 1
    for p in square[2:]:
        _drag(a, [p])
    a.close.click()
    assert len(a.regions) == 2 and a.current == 1 and a.region.value == 1
    m = a.regions[1].mask
    assert m.sum() == Occlusion(np.array(square, float)).mask_array((SIZE, SIZE)).sum()
    assert m[86, 68] and not m[70, 68] and "px from the polygon" in a.status
    a.mode.value = "polygon"                                  # an unfinished polygon ...
    _drag(a, [(20, 20)])
    a.mode.value = "paint"                                    # ... is dropped on leaving
    assert a._polygon == [] and "dropped" in a.status


def test_t_junction_click_adds_to_the_nearest_region_and_a_second_removes_it(fold):
    pair, k1, o1 = fold
    a = OcclusionAnnotator(k1, pair.skeleton1, occlusions=o1)
    a.new_region()                                            # an empty second region
    a.mode.value = "t-junction"
    target = _far_outline_point(o1[0])
    _drag(a, [target + [1.0, 0.5]])                           # a little off the outline
    tj = a.regions[0].t_junctions
    assert len(tj) == 3 and a.current == 0 and "added a T-junction" in a.status
    A = boundary_polygon(o1[0].mask, epsilon=0.5)
    e, r = np.roll(A, -1, axis=0) - A, tj[-1] - A                # outline edges, to the point
    t = np.clip(np.einsum("ij,ij->i", r, e) / np.einsum("ij,ij->i", e, e), 0, 1)
    assert np.linalg.norm(r - t[:, None] * e, axis=1).min() < 1e-6   # snapped onto the outline
    assert len(a.occlusions[0].t_junctions) == 3
    _drag(a, [tj[-1] + [0.8, -0.8]])                          # click on it again: removed
    assert len(a.regions[0].t_junctions) == 2 and "removed the T-junction" in a.status
    np.testing.assert_allclose(a.regions[0].t_junctions, o1[0].t_junctions)
    _drag(a, [(5.0, 5.0)])                                    # far from every outline: warned
    assert len(a.regions[0].t_junctions) == 3 and "Solve needs" in a.status
    b = OcclusionAnnotator(k1, pair.skeleton1, occlusions=[], suggest=False)
    b.mode.value = "t-junction"
    _drag(b, [(80.0, 80.0)])
    assert "no occlusion region yet" in b.status


def test_depth_control_writes_the_skeleton_depth(fold):
    pair, k1, o1 = fold
    sk = _plain(pair.skeleton1)
    a = OcclusionAnnotator(k1, sk, occlusions=o1)
    assert a.skeleton is sk and a.skeleton.depth is None
    assert set(a.joint.options) >= {"left_hand", "left_elbow", "chest"}
    assert "left_foot" not in a.joint.options                # only joints near the region
    a.joint.value = "left_hand"
    a.depth.value = -1.5                                      # the slider commits a depth
    d = a.skeleton.depth
    assert d[sk.index("left_hand")] == -1.5 and np.count_nonzero(d) == 1
    assert "depth of left_hand = -1.5" in a.status
    a.set_depth("left_elbow", -1.0)
    assert a.skeleton.depth[sk.index("left_elbow")] == -1.0
    a.joint.value = "left_elbow"
    assert a.depth.value == -1.0                              # the slider shows the joint's
    a.set_depth("chest", 4.0)                                 # beyond the slider's range
    a.joint.value = "chest"
    assert a.depth.max >= 4.0 and a.skeleton.depth[sk.index("chest")] == 4.0
    a._guard(a.set_depth, "tail", 1.0)
    assert "no joint 'tail'" in a.status
    assert pair.skeleton1.depth is not None and sk.depth is None  # inputs untouched


def test_save_and_load_round_trip(fold, tmp_path):
    pair, k1, o1 = fold
    a = OcclusionAnnotator(k1, _plain(pair.skeleton1), occlusions=o1)
    a.set_depth("left_hand", -1.0)
    a.mode.value = "t-junction"
    _drag(a, [_far_outline_point(o1[0])])
    a.new_region()                                            # empty: left out of the file
    path = tmp_path / "key1.json"
    a.file.value = str(path)
    a.save_button.click()
    assert f"saved 1 region(s) to {path}" in a.status and "1 empty" in a.status
    data = json.loads(path.read_text())
    assert data["image_size"] == [SIZE, SIZE] and data["joint_depth"]["left_hand"] == -1.0
    assert len(load_occlusions(path)[0].t_junctions) == 3     # the library reads it too
    b = OcclusionAnnotator(k1, _plain(pair.skeleton1), occlusions=[], suggest=False)
    b.load(path)
    assert len(b.regions) == 1 and "loaded 1 region(s)" in b.status
    ma, mb = a.regions[0].mask, b.regions[0].mask
    assert (ma & mb).sum() / (ma | mb).sum() > 0.97
    np.testing.assert_allclose(b.regions[0].t_junctions, a.regions[0].t_junctions)
    np.testing.assert_array_equal(b.skeleton.depth, a.skeleton.depth)
    assert b.to_json() == json.dumps(json.loads(b.to_json()), indent=1)


def test_solve_colours_visible_and_hidden_contours(fold):
    pair, k1, o1 = fold
    a = OcclusionAnnotator(k1, pair.skeleton1, occlusions=o1)
    assert a.solve_button.layout.display == "none"            # no target pose: no Solve
    a._guard(a.solve)
    assert "pass target_skeleton=" in a.status
    a = OcclusionAnnotator(k1, pair.skeleton1, occlusions=o1, target_skeleton=pair.skeleton0)
    assert a.solve_button.layout.display != "none"
    a.solve_button.click()
    (reg,) = a.template.regions
    vis = reg.visible_edges()
    assert 0 < vis.sum() < reg.n_edges                        # blue and red edges both drawn
    assert f"{int(vis.sum())} visible contour edges (blue), {reg.n_edges - int(vis.sum())} " \
           f"hidden (red)" in a.status
    energies = sorted(e for _, _, e in reg.energies)
    assert len(energies) == 2 and energies[0] < energies[1]   # two assignments (k = 2, Eq. 2)
    text = a.energies.value
    assert text.count("E = ") == 2 and "← chosen" in text and f"{energies[0]:10.4f}" in text
    a.set_depth("left_hand", -1.0)                            # any edit: solve again
    assert a.template is None and "press Solve" in a.energies.value


def test_bad_input_gives_clear_messages(fold, tmp_path):
    pair, k1, o1 = fold
    with pytest.raises(ValueError, match=r"image: joint .* lies outside the 60x60 image"):
        OcclusionAnnotator(k1[:60, :60], pair.skeleton1)      # the skeleton of another image
    with pytest.raises(TypeError, match="skeleton must be a physlab.inbetween.Skeleton"):
        OcclusionAnnotator(k1, pair.skeleton1.xy)
    small = np.zeros((20, 20), bool)
    small[5:9, 5:9] = True
    with pytest.raises(ValueError, match=r"occlusions\[1\]: .*differs from the image"):
        OcclusionAnnotator(k1, pair.skeleton1, occlusions=[o1[0], Occlusion(small)])
    with pytest.raises(TypeError, match=r"occlusions\[0\] is a ndarray"):
        OcclusionAnnotator(k1, pair.skeleton1, occlusions=[o1[0].mask])
    other = Skeleton(["a", "b"], [-1, 0], [[10, 10], [20, 20]])
    with pytest.raises(ValueError, match="skeleton and target_skeleton have different joints"):
        OcclusionAnnotator(k1, pair.skeleton1, target_skeleton=other)
    with pytest.raises(ValueError, match="scale must be >= 1"):
        OcclusionAnnotator(k1, pair.skeleton1, scale=0)

    a = OcclusionAnnotator(k1, pair.skeleton1, occlusions=o1, target_skeleton=pair.skeleton0)
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    a.file.value = str(bad)
    a.load_button.click()
    assert "not valid JSON" in a.status and str(bad) in a.status and len(a.regions) == 1
    bad.write_text(json.dumps({"occlusions": [], "image_size": [512, 512]}))
    a.load_button.click()
    assert "annotation of a 512x512 image; this keyframe is 160x160" in a.status
    bad.write_text(json.dumps({"occlusions": [{"polygon": [[0, 0], [1, 0]]}]}))
    a.load_button.click()
    assert "occlusions[0]" in a.status and ">= 3" in a.status
    bad.write_text(json.dumps({"occlusions": [], "joint_depth": {"tail": 1.0}}))
    a.load_button.click()
    assert "unknown joint(s) ['tail']" in a.status and len(a.regions) == 1
    a.file.value = str(tmp_path / "missing.json")
    a.load_button.click()
    assert "no annotation file at" in a.status

    a.mode.value = "t-junction"                               # a T-junction off the outline
    _drag(a, [(20.0, 20.0)])
    a.solve_button.click()
    assert a.template is None and "t_junctions[2]" in a.status
    assert "from the occlusion mask's outline" in a.status and "Traceback" not in a.status
    a.new_region()
    a.solve_button.click()
    assert "region(s) [1] are empty" in a.status
