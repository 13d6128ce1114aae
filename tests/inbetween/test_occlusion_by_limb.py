"""Handles of a limb's region on one layer, by bone (:attr:`physlab.inbetween.occlusion.
Occlusion.limb`, ``suggest_occlusions(by_limb=True)``), instead of the split at the largest
depth gap of Brodt & Bessmeltsev 2024 Secs. 4.2, 5.1, which may cut a limb in two."""
import numpy as np
import pytest

from physlab.inbetween import Skeleton, occlusion_benchmark, suggest_occlusions
from physlab.inbetween.occlusion import (Occlusion, _layered_handle_pockets, _limb_handles,
                                         _limb_split, build_layered_template, limb_contact,
                                         load_occlusions, save_occlusions)

NAMES = ("pelvis", "chest", "neck", "shoulder", "elbow", "hand")
HANDLES = NAMES + tuple(f"{j}_mid" for j in NAMES[1:])     # Skeleton.handles order


def _bar_over_body(depth=(0.0, 0.0, 0.0, -2.0, -2.0, -0.4)):
    """A wide body (x 40–80, y 20–100) and an arm bar (7 px) entering it from the right at
    y = 50, drawn as an RGBA image; the skeleton pelvis → chest → neck | shoulder → elbow →
    hand has the chest bone's midpoint (60, 50) under the arm, next to the hand (55, 50).
    Default depths: the arm in front, its elbow much nearer than its hand, so the region's
    handles — hand −0.4, hand_mid −1.2, chest_mid 0 — have their largest gap inside the arm."""
    H, W = 120, 130
    yy, xx = np.mgrid[0:H, 0:W]
    body = (xx >= 40) & (xx <= 80) & (yy >= 20) & (yy <= 100)
    arm = (xx >= 50) & (xx <= 114) & (abs(yy - 50) <= 3)
    fg = body | arm
    img = np.zeros((H, W, 4))
    img[fg] = (0.8, 0.8, 0.8, 1.0)
    img[arm, :3] = 0.3
    sk = Skeleton(NAMES, np.array([-1, 0, 1, 1, 3, 4]),
                  np.array([[60, 75], [60, 25], [60, 21], [110, 50], [90, 50], [55, 50]], float),
                  np.array(depth, float))
    return img, fg, sk


def _layers(tpl, region=0):
    """Names of the handles on the base layer (A) and in the pocket (B) of a region."""
    reg = tpl.regions[region]
    return ({HANDLES[i] for i in np.flatnonzero(np.isin(tpl.handle_tris, reg.tris_a))},
            {HANDLES[i] for i in np.flatnonzero(np.isin(tpl.handle_tris, reg.tris_b))})


def test_limb_handles_are_the_bones_joints_and_midpoints():
    _, _, sk = _bar_over_body()
    got = _limb_handles(sk, ("elbow", "hand"))
    assert got.shape == (len(HANDLES),)
    assert {HANDLES[i] for i in np.flatnonzero(got)} == {
        "shoulder", "elbow", "hand", "elbow_mid", "hand_mid"}
    assert {HANDLES[i] for i in np.flatnonzero(_limb_handles(sk, ("hand",)))} == {
        "elbow", "hand", "hand_mid"}
    assert not _limb_handles(sk, ()).any()
    for bad, match in (("pelvis", "root"), ("tail", "unknown joint")):
        with pytest.raises(ValueError, match=f"occlusions\\[0\\].limb: .*{match}"):
            _limb_handles(sk, ("hand", bad), "occlusions[0].limb")


def test_limb_split_keeps_the_limb_on_one_layer():
    """Analytic: handles hs = [hand −0.4, hand_mid −1.2, chest_mid 0] (the largest gap, 0.8,
    lies between the arm's two); by bone the arm (mean −0.8) stays on the base layer and the
    body (0) goes into the pocket; the invariants: a depth offset changes nothing, mirrored
    depths swap the layers, ties and one-group regions stay on the base."""
    hdepth = np.array([0.0, 0.0, -1.2, -0.4, 0.0])
    in_limb = np.array([False, False, True, True, False])
    hs = np.array([3, 2, 4])
    assert _limb_split(hs, hdepth, in_limb).tolist() == [False, False, True]
    assert _limb_split(hs, hdepth + 5.0, in_limb).tolist() == [False, False, True]
    assert _limb_split(hs, -hdepth, in_limb).tolist() == [True, True, False]
    flat = np.array([0.0, 0.0, -1.0, 1.0, 0.0])           # limb mean 0 = body 0
    assert not _limb_split(hs, flat, in_limb).any()
    assert not _limb_split(np.array([2, 3]), hdepth, in_limb).any()   # the limb alone
    assert not _limb_split(np.array([4]), hdepth, in_limb).any()      # the body alone


def test_layered_handle_pockets_split_a_single_region_cell_by_bone():
    """The overlap route (:func:`_layered_handle_pockets`): triangle 0 is region 0's only
    cell, triangle 1 outside; handles 0–2 in the region, 3 outside. By depth the gap cuts the
    limb (handles 0, 1), by bone the body's handle 2 goes to the pocket."""
    tri0 = np.array([0, 0, 0, 1])
    hdepth = np.array([-0.4, -1.2, 0.0, 0.0])
    cover = np.array([[True], [False]])
    cell = np.array([0, 1])
    hidden = np.array([np.nan])
    by_depth = _layered_handle_pockets(tri0, hdepth, cover, cell, hidden, "k")
    assert by_depth.tolist() == [0, -1, 0, -1]
    limb = np.array([True, True, False, False])
    assert _layered_handle_pockets(tri0, hdepth, cover, cell, hidden, "k",
                                   [limb]).tolist() == [-1, -1, 0, -1]
    assert _layered_handle_pockets(tri0, hdepth, cover, cell, hidden, "k",
                                   [None]).tolist() == by_depth.tolist()


def test_layered_template_keeps_a_limbs_handles_on_one_layer():
    img, fg, sk = _bar_over_body()
    region, tj = limb_contact(sk, "hand", fg, 5.0)
    kw = dict(mask=fg, target_skeletons=[sk], assignments=[0])
    a, b = _layers(build_layered_template(img, sk, [Occlusion(region, tj)], **kw))
    assert a == {"hand_mid"} and b == {"hand", "chest_mid"}        # the depth gap cuts the arm
    tpl = build_layered_template(img, sk, [Occlusion(region, tj, limb=("elbow", "hand"))], **kw)
    assert _layers(tpl) == ({"hand", "hand_mid"}, {"chest_mid"})
    assert tpl.regions[0].front == "A"                              # the arm in front
    # the arm behind the body: the arm's handles go into the pocket, together
    _, _, behind = _bar_over_body((0.0, 0.0, 0.0, 2.0, 2.0, 0.4))
    tpl = build_layered_template(img, behind, [Occlusion(region, tj, limb=("elbow", "hand"))],
                                 **dict(kw, target_skeletons=[behind]))
    assert _layers(tpl) == ({"chest_mid"}, {"hand", "hand_mid"})
    assert tpl.regions[0].front == "A"                              # the body in front
    with pytest.raises(ValueError, match=r"occlusions\[0\]\.limb: unknown joint 'wrist'"):
        build_layered_template(img, sk, [Occlusion(region, tj, limb=("wrist",))], **kw)


def test_occlusion_limb_validation_and_json_round_trip(tmp_path):
    m = np.zeros((8, 8), bool)
    m[2:5, 2:5] = True
    assert Occlusion(m).limb == ()
    o = Occlusion(m, label="x", limb=["elbow", "hand"])
    assert o.limb == ("elbow", "hand") and "limb=('elbow', 'hand')" in repr(o)
    for bad in ("hand", ("hand", 3), 5):
        with pytest.raises(ValueError, match="Occlusion limb must be a tuple of joint names"):
            Occlusion(m, limb=bad)
    save_occlusions(tmp_path / "o.json", [o, Occlusion(m)])
    back = load_occlusions(tmp_path / "o.json")
    assert [b.limb for b in back] == [("elbow", "hand"), ()]
    (tmp_path / "bad.json").write_text('[{"polygon": [[0, 0], [4, 0], [4, 4]], "limb": "hand"}]')
    with pytest.raises(ValueError, match=r"occlusions\[0\]: Occlusion limb"):
        load_occlusions(tmp_path / "bad.json")


def test_suggested_contact_regions_carry_their_limb():
    pair = next(p for p in occlusion_benchmark(192) if p.name == "fold_arm")
    k1, sk = pair.keyframes()[1], pair.skeleton1
    plain = suggest_occlusions(k1, sk, extent="contact")
    assert plain and all(o.limb == () for o in plain)
    low = suggest_occlusions(k1, sk, extent="contact", by_limb=True)
    up = suggest_occlusions(k1, sk, extent="contact", by_limb=True, up=True)
    assert [o.limb for o in low] == [("left_hand",)]
    assert [o.limb for o in up] == [("left_elbow", "left_hand")]
    assert np.array_equal(low[0].mask, plain[0].mask)
    assert up[0].label == low[0].label
    for kw, match in [({"by_limb": 1}, "by_limb must be True or False"),
                      ({"up": "yes"}, "up must be True or False"),
                      ({"by_limb": True, "extent": "capsule"}, "by_limb=True is for extent"),
                      ({"up": True, "extent": "capsule"}, "up=True is for extent")]:
        with pytest.raises(ValueError, match=match):
            suggest_occlusions(k1, sk, **{"extent": "contact", **kw})


def test_limb_flags_are_for_the_contact_regions():
    from physlab.inbetween import evaluate

    for flag in ("--by-limb", "--limb-up"):
        with pytest.raises(ValueError, match=f"{flag} is for --occluded --source "
                                             "animated_drawings --regions contact"):
            evaluate.main(["--occluded", "--source", "animated_drawings", flag])
    with pytest.raises(ValueError, match="by_limb=True is for regions='contact'"):
        evaluate.OccludedDrawingPair("x", "char1", "zombie", 1.4, 1.9, regions="capsule",
                                     by_limb=True)
    with pytest.raises(ValueError, match="up must be True or False"):
        evaluate.OccludedDrawingPair("x", "char1", "zombie", 1.4, 1.9, regions="contact",
                                     up=None)
