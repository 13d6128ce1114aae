"""Occlusion layers (Brodt & Bessmeltsev 2024, Secs. 4.1–4.4, 5.1, Eq. 2, Algorithm 1)."""
import warnings

import numpy as np
import pytest

from physlab.inbetween import (CHARACTER_JOINTS, PAINT_ORDER, Occlusion, Skeleton,
                               character_skeleton, inbetween,
                               inbetween_benchmark, interpolate, load_occlusions,
                               occlusion_benchmark, paint_order, save_occlusions, suggest_occlusions)
from physlab.inbetween.occlusion import (OcclusionRegion, build_layered_template,
                                         count_valid_assignments, incise, limb_overlaps,
                                         refine_through_t_junctions, switch_points,
                                         valid_assignments)
from physlab.inbetween.template import build_template
from physlab.mesh import TriMesh

SIZE = 192


# ------------------------------------------------------------------ switching rule (Eq. 2)
def _switches(b):
    return {i for i in range(len(b)) if b[i] != b[i - 1]}


@pytest.mark.parametrize("n,tj", [(10, []), (10, [2, 6]), (12, [0, 3, 5, 9]), (9, [4]),
                                  (11, [1, 5, 8]), (7, [0, 2, 4, 5, 6])])
def test_valid_assignments_follow_the_switching_rule(n, tj):
    out = valid_assignments(n, tj)
    k = len(tj)
    assert len(out) == count_valid_assignments(n, k) == (2 if k % 2 == 0 else 2 * (n - k))
    seen = set()
    for b, cusp in out:
        assert b.shape == (n,) and set(np.unique(b)) <= {0, 1}
        sw = _switches(b)
        if k % 2 == 0:
            assert cusp is None and sw == set(tj)      # no cusp for even k
        else:
            assert cusp not in tj and sw == set(tj) | {cusp}   # exactly one cusp
        seen.add(b.tobytes())
    assert len(seen) == len(out)                      # all distinct
    # and nothing is missing: brute force over all 2^n assignments
    allowed = 0
    for code in range(2 ** n):
        b = np.array([(code >> i) & 1 for i in range(n)])
        sw = _switches(b)
        if set(tj) <= sw and len(sw - set(tj)) <= 1:
            allowed += 1
    assert allowed == len(out)


def test_valid_assignments_reject_bad_input():
    with pytest.raises(ValueError, match="n >= 3"):
        valid_assignments(2, [])
    with pytest.raises(ValueError, match="0..9"):
        valid_assignments(10, [10])
    with pytest.raises(ValueError, match="repeat"):
        valid_assignments(10, [3, 3])


def test_switch_points_ignore_short_runs():
    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    P = np.c_[np.cos(t), np.sin(t)]
    lab = np.zeros(40, bool)
    lab[10:25] = True
    lab[3] = True   # one-point noise
    sp = switch_points(P, lab, min_run=3)
    assert len(sp) == 2
    assert np.allclose(sp[0], 0.5 * (P[9] + P[10])) and np.allclose(sp[1], 0.5 * (P[24] + P[25]))


# ------------------------------------------------------------------ incision (Algorithm 1)
def _square_with_pocket():
    """A 4×4 grid square whose middle 2×2 cells form an occlusion region, with its pocket."""
    g = np.array([[x, y] for y in range(5) for x in range(5)], float)
    tris = []
    for y in range(4):
        for x in range(4):
            a, b, c, d = y * 5 + x, y * 5 + x + 1, (y + 1) * 5 + x + 1, (y + 1) * 5 + x
            tris += [[a, b, c], [a, c, d]]
    tris = np.array(tris)
    cent = g[tris].mean(1)
    inside = np.flatnonzero((cent[:, 0] > 1) & (cent[:, 0] < 3) & (cent[:, 1] > 1) & (cent[:, 1] < 3))
    loop = np.array([6, 7, 8, 13, 18, 17, 16, 11])   # the region's outline, in order
    interior = [12]
    pocket_of = {12: 25}
    pt = tris[inside].copy()
    pt[pt == 12] = 25
    X = np.r_[g, g[interior]]
    T = np.r_[tris, pt]
    reg = OcclusionRegion(loop=loop, t_junctions=np.array([0, 4]),
                          non_manifold=np.zeros(8, bool), tris_a=inside,
                          tris_b=np.arange(len(tris), len(tris) + len(inside)),
                          pocket_of=pocket_of)
    return X, T, reg


def _edge_sharers(tris, sel, e):
    """Triangles (indices into tris[sel]) containing edge e."""
    return [i for i, t in enumerate(tris[sel]) if e[0] in t and e[1] in t]


def test_incision_connects_layers_exactly_along_the_non_cut_edges():
    X, T, reg = _square_with_pocket()
    b = valid_assignments(8, [0, 4])[0][0]           # b switches at loop vertices 0 and 4
    assert list(b) == [0, 0, 0, 0, 1, 1, 1, 1]
    T2, n_new, copies = incise(T, [reg], [b], len(X))
    mesh = TriMesh(np.r_[X, X[[v for v, _ in copies]]], T2)  # valid mesh, no degenerate tris
    outside = np.setdiff1d(np.arange(len(T) - len(reg.tris_a)), reg.tris_a)
    for i in range(8):
        e = (reg.loop[i], reg.loop[(i + 1) % 8])
        out_t = _edge_sharers(T2, outside, e)
        assert len(out_t) == 1                        # the outside keeps its own vertices
        a_t = _edge_sharers(T2, reg.tris_a, e)
        b_t = _edge_sharers(T2, reg.tris_b, e)
        # the attached layer shares the edge with the outside, the other is cut from it
        assert (len(a_t) == 1) == (b[i] == 0)
        assert (len(b_t) == 1) == (b[i] == 1)
    # the cut ends at the switching vertices: every layer still touches them
    for v in (reg.loop[0], reg.loop[4]):
        assert (T2[reg.tris_a] == v).any() and (T2[reg.tris_b] == v).any()
    assert n_new == 2 * 3 and mesh.n == len(X) + 6    # 3 inner cut vertices per layer


def test_non_manifold_edges_stay_attached_to_both_layers():
    X, T, reg = _square_with_pocket()
    reg.non_manifold[1] = True
    b = np.array([0, 0, 0, 0, 1, 1, 1, 1])
    T2, _, _ = incise(T, [reg], [b], len(X))
    e = (reg.loop[1], reg.loop[2])
    assert len(_edge_sharers(T2, reg.tris_a, e)) == 1 and len(_edge_sharers(T2, reg.tris_b, e)) == 1


# ------------------------------------------------------------------ mask refinement (Sec. 4.1)
def test_refinement_passes_the_outline_through_the_t_junctions():
    t = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    P = np.c_[50 + 30 * np.cos(t), 50 + 20 * np.sin(t)]
    tjs = np.array([[81.5, 50.0], [50.0, 27.0]])   # 1.5 and 3 px off the ellipse
    R, idx = refine_through_t_junctions(P, tjs, radius=15.0)
    assert np.allclose(R[idx], tjs)
    far = np.linalg.norm(R[:, None] - tjs[None], axis=2).min(1) > 15.0
    orig = np.linalg.norm(R[far][:, None] - P[None], axis=2).min(1)
    assert far.sum() > 10 and orig.max() < 0.5        # the far outline stays put
    from physlab.mesh import polygon_is_simple
    assert polygon_is_simple(R)


def test_refinement_rejects_a_t_junction_off_the_outline():
    t = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    P = np.c_[50 + 30 * np.cos(t), 50 + 20 * np.sin(t)]
    with pytest.raises(ValueError, match=r"t_junctions\[1\].*px from the occlusion"):
        refine_through_t_junctions(P, [[80, 50], [50, 50]])


# ------------------------------------------------------------------ depth, occlusions, data
def test_skeleton_depth_validation_round_trip_and_interpolation():
    sk = character_skeleton(SIZE)
    assert sk.depth is None and "depth" not in sk.to_dict()
    d = sk.with_depth({"left_hand": -1.0, "left_elbow": -1.0})
    assert d.depth[d.index("left_hand")] == -1.0 and d.depth[d.index("pelvis")] == -1.0
    assert Skeleton(**d.to_dict()).depth.tolist() == d.depth.tolist()
    e = sk.with_depth(np.arange(len(sk), dtype=float))
    mid = interpolate(e, e.with_depth(np.zeros(len(sk))), 0.25)
    assert np.allclose(mid.depth, 0.75 * np.arange(len(sk)))
    with pytest.raises(ValueError, match="depth must have shape"):
        sk.with_depth([0.0, 1.0])
    with pytest.raises(ValueError, match="NaN"):
        sk.with_depth(np.full(len(sk), np.nan))
    with pytest.raises(ValueError, match="unknown joint"):
        sk.with_depth({"tail": 1.0})


def test_paint_order_follows_depth():
    sk = character_skeleton(SIZE)
    assert paint_order(sk) == PAINT_ORDER
    flat = {j: 0.0 for j in CHARACTER_JOINTS}
    assert paint_order(sk.with_depth(flat)) == PAINT_ORDER
    front = paint_order(sk.with_depth({**flat, "left_elbow": -1.0, "left_hand": -1.0}))
    assert front[-2:] == ("left_forearm", "left_hand") or front[-1] == "left_forearm"
    assert front.index("left_forearm") > front.index("torso")


@pytest.fixture(scope="module")
def fold():
    pair = next(p for p in occlusion_benchmark(SIZE) if p.name == "fold_arm")
    k0, k1 = pair.keyframes()
    o0, o1 = pair.occlusions()
    return pair, k0, k1, o0, o1


def test_true_occlusions_of_the_benchmark(fold):
    pair, k0, k1, o0, o1 = fold
    assert o0 == [] and len(o1) == 1
    assert "left_forearm" in o1[0].label and "torso" in o1[0].label
    assert len(o1[0].t_junctions) % 2 == 0 and len(o1[0].t_junctions) >= 2
    # every benchmark pair of part 1 is occlusion-free, every pair here occludes at a key
    assert all(not limb_overlaps(s) for p in inbetween_benchmark(SIZE) for s in p.animation(5))
    for p in occlusion_benchmark(SIZE):
        assert any(p.occlusions()), p.name


def test_occlusion_json_round_trip_and_errors(tmp_path, fold):
    *_, o1 = fold
    path = tmp_path / "occ.json"
    save_occlusions(path, o1)
    back = load_occlusions(path)
    m0, m1 = o1[0].mask, back[0].mask_array(o1[0].mask.shape)
    assert (m0 & m1).sum() / (m0 | m1).sum() > 0.85
    assert np.allclose(back[0].t_junctions, o1[0].t_junctions)
    path.write_text('{"occlusions": [{"t_junctions": []}]}')
    with pytest.raises(ValueError, match=r"occ.json: occlusions\[0\].*polygon"):
        load_occlusions(path)
    path.write_text("{nope")
    with pytest.raises(ValueError, match="occ.json: not valid JSON"):
        load_occlusions(path)
    with pytest.raises(ValueError, match="empty"):
        Occlusion(np.zeros((4, 4), bool))


def test_suggested_occlusions_cover_the_true_region(fold):
    pair, k0, k1, o0, o1 = fold
    sug = suggest_occlusions(k1, pair.skeleton1)
    assert sug, "the forearm across the belly must be suggested"
    union = np.any([s.mask for s in sug], axis=0)
    true = o1[0].mask
    assert (union & true).sum() > 0.3 * true.sum()



# Suggested T-junctions (suggest_t_junctions, a CPU heuristic) against the true ones of the
# benchmark's key 1, on the suggested region that overlaps the true region most. Measured at
# 192 px (radius default): nearest suggested-to-true distance fold_arm 5.0, arm_behind 5.7,
# cross_legs 3.0 px; farthest 11.9, 10.1, 8.1 px (the capsules are not the limbs'
# silhouettes, and the suggested region is not the true one). Tolerances: nearest <= 6 px
# (= T_JUNCTION_TOLERANCE), every suggested one <= 12.5 px from a true one. cross_step (legs
# crossed at the knees) is not held to it: nearest 2.0 px, farthest 15.6 px.
@pytest.mark.parametrize("name", ["fold_arm", "arm_behind", "cross_legs"])
def test_suggested_t_junctions_near_the_true_ones(name):
    from physlab.inbetween.occlusion import T_JUNCTION_TOLERANCE, suggest_t_junctions

    pair = next(p for p in occlusion_benchmark(SIZE) if p.name == name)
    k1 = pair.keyframes()[1]
    true = pair.occlusions()[1][0]
    sug = suggest_occlusions(k1, pair.skeleton1, t_junctions=True)
    assert [len(o.t_junctions) for o in suggest_occlusions(k1, pair.skeleton1)] == [0] * len(sug)
    best = max(sug, key=lambda o: (o.mask & true.mask).sum())
    tj, T = best.t_junctions, true.t_junctions
    assert len(tj) >= 2 and len(tj) % 2 == len(T) % 2 == 0      # parity of the switching rule
    d = np.linalg.norm(tj[:, None] - T[None], axis=2).min(axis=1)
    assert d.min() <= T_JUNCTION_TOLERANCE and d.max() <= 12.5, d
    # on the region's outline: the template's refinement accepts them (and they stay apart)
    from skimage.measure import find_contours
    poly = max(find_contours(np.pad(best.mask, 1).astype(float), 0.5), key=len)[:-1, ::-1] - 1
    P, idx = refine_through_t_junctions(poly, tj)
    assert len(set(idx.tolist())) == len(tj)
    # every region's T-junctions come from the same function on its own bones
    a, b = best.label.split("/")
    radius = 0.06 * max(np.ptp(pair.skeleton1.xy[:, 1]), np.ptp(pair.skeleton1.xy[:, 0]))
    from physlab.inbetween.template import as_rgba_float, classical_foreground_mask
    fg = classical_foreground_mask(as_rgba_float(k1))
    again = suggest_t_junctions(best.mask, pair.skeleton1, (a, b), radius, fg)
    assert np.allclose(again, tj)


def test_suggested_t_junctions_front_and_depthless(fold):
    from physlab.inbetween.occlusion import suggest_t_junctions

    pair, k1 = fold[0], fold[2]
    sk = pair.skeleton1
    best = max(suggest_occlusions(k1, sk), key=lambda o: o.mask.sum())  # chest/left_hand
    fg = k1[..., 3] > 127
    args = (best.mask, sk, ("chest", "left_hand"), 10.0, fg)
    by_depth = suggest_t_junctions(*args)                       # the hand is nearer
    assert np.allclose(by_depth, suggest_t_junctions(*args, front=["left_hand"]))
    # without depths the bone deepest in the hierarchy (the forearm) is the occluder
    flat = suggest_t_junctions(best.mask, sk.with_depth(None), ("chest", "left_hand"), 10.0, fg)
    assert np.allclose(flat, by_depth)
    assert len(suggest_t_junctions(*args, front=["chest"])) % 2 == 0


def test_layered_template_takes_suggested_t_junctions(fold):
    pair, k0, k1, o0, o1 = fold
    sug = suggest_occlusions(k1, pair.skeleton1, t_junctions=True)
    best = max(sug, key=lambda o: o.mask.sum())
    tpl = build_layered_template(k1, pair.skeleton1, [best],
                                 target_skeletons=pair.animation(3)[::-1][1:])
    (reg,) = tpl.regions
    assert len(reg.t_junctions) == len(best.t_junctions) >= 2
    assert len(reg.energies) == count_valid_assignments(reg.n_edges, len(reg.t_junctions))
    sw = {i for i in range(reg.n_edges) if reg.b[i] != reg.b[i - 1]}
    assert set(reg.t_junctions.tolist()) <= sw      # b switches at every T-junction


def test_suggested_t_junctions_bad_input(fold):
    from physlab.inbetween.occlusion import suggest_t_junctions

    pair, k1 = fold[0], fold[2]
    sk = pair.skeleton1
    fg = k1[..., 3] > 127
    reg = np.zeros_like(fg)
    reg[80:90, 90:100] = True
    ok = (reg, sk, ("chest", "left_hand"), 10.0, fg)
    for args, kw, match in [
        ((np.zeros_like(fg),) + ok[1:], {}, "region must be a non-empty"),
        (ok[:4] + (fg[:-1],), {}, "mask must have the region's shape"),
        (ok[:3] + (0.0, fg), {}, "radius must be a positive"),
        (ok[:3] + (True, fg), {}, "radius must be a positive"),
        (ok[:2] + (("chest",),) + ok[3:], {}, "at least two distinct bones"),
        (ok[:2] + ("chest",) + ok[3:], {}, "sequence of joint names"),
        (ok[:2] + (("chest", "elbow_of_nobody"),) + ok[3:], {}, "unknown joint"),
        (ok[:2] + (("pelvis", "left_hand"),) + ok[3:], {}, "is the root"),
        (ok, {"front": ["chest", "left_hand"]}, "proper subset"),
        (ok, {"front": ["head"]}, "proper subset"),
        (ok, {"min_run": 0}, "min_run must be"),
    ]:
        with pytest.raises(ValueError, match=match):
            suggest_t_junctions(*args, **kw)
    with pytest.raises(ValueError, match="t_junctions must be True or False"):
        suggest_occlusions(k1, sk, t_junctions="yes")
    with pytest.raises(ValueError, match="mask must have the image's shape"):
        suggest_occlusions(k1, sk, mask=fg[:-1])

# ------------------------------------------------------------------ layered template
@pytest.fixture(scope="module")
def layered(fold):
    pair, k0, k1, o0, o1 = fold
    anim = pair.animation(5)[::-1]
    return build_layered_template(k1, pair.skeleton1, o1, target_skeletons=anim[1:],
                                  other_image=k0, other_occlusions=o0)


def test_layered_template_rest_pose_renders_the_keyframe(layered, fold):
    pair, k0, k1, o0, o1 = fold
    img = layered.image
    out = layered.render(layered.X)
    inside = layered.mask
    diff = np.abs(out[..., :3] * out[..., 3:] - img[..., :3] * img[..., 3:]).max(-1)
    assert np.percentile(diff[inside], 99) < 0.02 and diff[inside].mean() < 0.003


def test_layered_template_picks_the_cheaper_topology_and_the_arm_in_front(layered):
    (reg,) = layered.regions
    energies = [e for _, _, e in reg.energies]
    assert len(energies) == count_valid_assignments(reg.n_edges, len(reg.t_junctions)) == 2
    chosen = [e for b, _, e in reg.energies if np.array_equal(b, reg.b)][0]
    assert chosen == min(energies) and max(energies) > 1.2 * chosen
    # the arm's handles are nearer (depth -1): the layer holding them is in front
    assert reg.front == "A" and reg.depth[0] < reg.depth[1]
    vis = reg.visible_edges()
    assert 0 < vis.sum() < reg.n_edges                # some outline visible, some hidden
    assert 0.0 < layered.inpainted_fraction < 0.6     # most of the hidden torso from key 0


def test_inpainted_mask_is_a_texture_channel(layered, fold):
    """The atlas' inpainted texels (Sec. 5.1) drawn like the texture: hidden at the rest pose
    (q = 1 at the own keyframe, Sec. 5.2), the hole itself when the back layer is drawn alone."""
    from scipy import ndimage

    from physlab.render import warp_texture

    pair, k0, k1, o0, o1 = fold
    H, W = layered.shape
    atlas = layered.inpainted
    assert atlas.shape == (2 * H, W) and atlas.dtype == bool
    assert not atlas[:H].any()                           # the keyframe's own texels
    hole = atlas[H:]
    assert hole.any() and not (hole & ~o1[0].mask).any()   # inside the occlusion region
    assert hole.sum() / o1[0].mask.sum() == pytest.approx(layered.inpainted_fraction)
    # rest pose, depth order: the front layer covers the back layer, nothing inpainted shows
    assert not layered.render_inpainted(layered.X, skeleton=pair.skeleton1).any()
    # the back layer alone at rest: the hole in image space, within a pixel of the hole's or
    # the layer's outline (antialiased edges); without the other key it is all inpainted
    blind = build_layered_template(k1, pair.skeleton1, o1, target_skeletons=[pair.skeleton0],
                                   assignments=[0])
    assert blind.inpainted_fraction == 1.0

    def band(m):
        return ndimage.binary_dilation(m, np.ones((3, 3))) & \
            ~ndimage.binary_erosion(m, np.ones((3, 3)))

    for tpl, least in ((layered, 30), (blind, 150)):
        back = tpl.back_triangles
        assert back.sum() == len(tpl.regions[0].tris_a)
        hole = tpl.inpainted[H:]
        got = tpl.render_inpainted(tpl.X, triangles=back)
        cover = warp_texture(np.ones((H, W, 4), np.float32), tpl.X, tpl.X, tpl.tris[back],
                             (H, W))[..., 3] > 0.5
        want = hole & cover
        assert want.sum() > least
        assert not ((got ^ want) & ~(band(hole) | band(cover))).any()
        # the rest are half-covered outline pixels (alpha ≤ 0.5 in ``cover``, not in ``want``)
        assert (got & want).sum() / (got | want).sum() > (0.6 if tpl is layered else 0.9)
        np.testing.assert_array_equal(tpl.render_inpainted(tpl.X, triangles=np.flatnonzero(
            back)), got)                                 # indices or a bool mask
    assert not (want & ~got).any()                       # blind: all of the layer inpainted
    # deformed to key 0's pose the torso under the forearm shows: inpainted pixels appear,
    # all on the drawn silhouette
    from physlab.inbetween.pipeline import deform_sequence

    x = deform_sequence(layered, [pair.skeleton0])[0][0]
    seen = layered.render_inpainted(x, skeleton=pair.skeleton0)
    alpha = layered.render(x, skeleton=pair.skeleton0)[..., 3]
    assert seen.sum() > 10 and not (seen & (alpha == 0)).any()
    # a single sheet has no inpainted texel
    sheet = build_template(k0, pair.skeleton0)
    assert not sheet.render_inpainted(sheet.X).any()


def test_render_inpainted_bad_input(layered):
    with pytest.raises(ValueError, match=r"x must have shape"):
        layered.render_inpainted(layered.X[:5])
    with pytest.raises(ValueError, match="triangles must be indices"):
        layered.render_inpainted(layered.X, triangles=[-1])
    with pytest.raises(ValueError, match="triangles as a bool mask"):
        layered.render_inpainted(layered.X, triangles=np.ones(3, bool))


def test_layered_template_bad_input(fold):
    pair, k0, k1, o0, o1 = fold
    far = Occlusion(o1[0].mask, np.array([[5.0, 5.0]]))
    with pytest.raises(ValueError, match=r"key1: occlusions\[0\]: t_junctions\[0\]"):
        build_layered_template(k1, pair.skeleton1, [far], target_skeletons=[pair.skeleton0],
                               name="key1")
    outside = np.zeros((SIZE, SIZE), bool)
    outside[:20, :20] = True
    with pytest.raises(ValueError, match="outside the foreground"):
        build_layered_template(k1, pair.skeleton1, [Occlusion(outside)],
                               target_skeletons=[pair.skeleton0])
    with pytest.raises(ValueError, match="target_skeletons"):
        build_layered_template(k1, pair.skeleton1, o1)
    with pytest.raises(ValueError, match="no joint depths"):
        build_layered_template(k1, pair.skeleton1.with_depth(None), o1,
                               target_skeletons=[pair.skeleton0])
    with pytest.raises(ValueError, match="overlaps an earlier occlusion region"):
        build_layered_template(k1, pair.skeleton1, [o1[0], o1[0]],
                               target_skeletons=[pair.skeleton0])
    with pytest.raises(ValueError, match=r"assignments\[0\] = 5 but region 0 has 2"):
        build_layered_template(k1, pair.skeleton1, o1, assignments=[5])
    with pytest.raises(TypeError, match=r"occlusions\[0\]"):
        build_layered_template(k1, pair.skeleton1, [o1[0].mask], target_skeletons=[pair.skeleton0])


# Limb widths from a drawing (bone_widths) and per-bone capsules (suggest_occlusions(widths=)).
def test_bone_widths_are_the_renderers_limb_radii():
    """The procedural renderer draws limbs as capsules of known radii (characters._CAPSULES,
    design px): bone_widths of the rest drawing finds them (plus about half the ink line)."""
    from physlab.inbetween.characters import _CAPSULES, _unit, render_character
    from physlab.inbetween.occlusion import bone_widths
    from physlab.inbetween.template import as_rgba_float, classical_foreground_mask

    size = 256
    rest = character_skeleton(size)
    fg = classical_foreground_mask(as_rgba_float(render_character(rest, "flat", size, 0)))
    w = bone_widths(rest, fg)
    u = _unit(size)
    for joint, part in (("left_elbow", "upper_arm"), ("left_hand", "forearm"),
                        ("left_knee", "thigh"), ("left_foot", "shin"),
                        ("right_hand", "forearm"), ("right_knee", "thigh")):
        true = u * np.mean(_CAPSULES[part])
        assert abs(w[joint] - true) <= 0.12 * true + 0.6, (joint, w[joint], true)
    with pytest.raises(ValueError, match="mask"):
        bone_widths(rest, fg.astype(float))
    for bad in (120, "50", True):
        with pytest.raises(ValueError, match="percentile"):
            bone_widths(rest, fg, percentile=bad)


# measured at 192 px, widths from the rest drawing: IoU of the suggestion with the true region
# fold_arm 0.47 -> 0.59, arm_behind 0.46 -> 0.58 (cross_legs 0.47 -> 0.69, cross_step 0.44 ->
# 0.76); the T-junctions' distances to the true ones 11.9 / 5.0 -> 2.7 / 0.8 px and
# 5.7 / 10.1 -> 1.6 / 0.0 px
@pytest.mark.parametrize("name", ["fold_arm", "arm_behind"])
def test_drawn_widths_suggest_the_region_and_t_junctions_nearer_the_truth(name):
    from physlab.inbetween.characters import render_character
    from physlab.inbetween.occlusion import bone_widths
    from physlab.inbetween.template import as_rgba_float, classical_foreground_mask

    pair = next(p for p in occlusion_benchmark(SIZE) if p.name == name)
    rest = character_skeleton(SIZE)
    free = render_character(rest, pair.style, SIZE, pair.seed)
    w = bone_widths(rest, classical_foreground_mask(as_rgba_float(free)))
    k1, sk = pair.keyframes()[1], pair.skeleton1
    true = pair.occlusions()[1][0]

    def iou(sug):
        u = np.any([o.mask for o in sug], axis=0)
        return (u & true.mask).sum() / (u | true.mask).sum()

    thin = suggest_occlusions(k1, sk, t_junctions=True)
    drawn = suggest_occlusions(k1, sk, t_junctions=True, widths=w)
    assert iou(drawn) > iou(thin) + 0.08
    best = max(drawn, key=lambda o: (o.mask & true.mask).sum())
    assert len(best.t_junctions) == len(true.t_junctions) == 2
    d = np.linalg.norm(best.t_junctions[:, None] - true.t_junctions[None], axis=2).min(axis=1)
    assert d.max() <= 4.0, d
    # same radius everywhere = the capsule suggestion, bit for bit
    r = 0.06 * max(np.ptp(sk.xy[:, 1]), np.ptp(sk.xy[:, 0]))
    same = suggest_occlusions(k1, sk, t_junctions=True, widths={j: r for j in w})
    assert all(np.array_equal(a.mask, b.mask) and np.allclose(a.t_junctions, b.t_junctions)
               for a, b in zip(same, thin)) and len(same) == len(thin)
    for bad, msg in (([1.0], "dict"), ({"nose": 3.0}, "nose"), ({"left_hand": -1.0}, "left_hand"),
                     ({"left_hand": "4"}, "left_hand")):
        with pytest.raises(ValueError, match=msg):
            suggest_occlusions(k1, sk, widths=bad)


# ------------------------------------------------------------------ the pipeline
def test_overlapping_limbs_without_occlusions_warn_or_raise(fold):
    pair, k0, k1, o0, o1 = fold
    with pytest.raises(ValueError, match="left_hand"):
        inbetween(k0, k1, pair.skeleton0, pair.skeleton1, 3, pair.animation(3), strict=True)


# measured at 192 px, PSNR gain at t = 0.5 / over all in-betweens: fold_arm +1.6 / +2.2 dB,
# arm_behind +0.9 / +2.0, cross_step +1.7 / +1.3 (cross_legs: a tie by construction, key 0's
# legs are apart, see occlusion_benchmark)
@pytest.mark.parametrize("name, gain_all", [("fold_arm", 1.5), ("arm_behind", 1.5),
                                            ("cross_step", 0.8)])
def test_layered_inbetween_beats_the_single_sheet(name, gain_all):
    from physlab.inbetween.evaluate import score_frames

    pair = next(p for p in occlusion_benchmark(SIZE) if p.name == name)
    k0, k1 = pair.keyframes()
    o0, o1 = pair.occlusions()
    n = 7
    truth = pair.ground_truth(np.linspace(0, 1, n))
    lay = inbetween(k0, k1, pair.skeleton0, pair.skeleton1, n, pair.animation(n),
                    occlusions0=o0, occlusions1=o1)
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        one = inbetween(k0, k1, pair.skeleton0, pair.skeleton1, n, pair.animation(n))
    assert any("overlap" in str(x.message) for x in w)
    assert any(f for f in one.flags) and not any(f for f in lay.flags)
    s_l, s_s = score_frames(lay.frames, truth), score_frames(one.frames, truth)
    assert s_l["psnr_mid"] > s_s["psnr_mid"] + 0.5
    assert s_l["psnr_all"] > s_s["psnr_all"] + gain_all
    assert s_l["cd_mid"] < s_s["cd_mid"] and s_l["cd_all"] < s_s["cd_all"]


@pytest.fixture(scope="module")
def fold_q(fold):
    """fold_arm through the pipeline with q from the inpainted masks and with q ≡ 1."""
    pair, k0, k1, o0, o1 = fold
    n = 7
    run = {tq: inbetween(k0, k1, pair.skeleton0, pair.skeleton1, n, pair.animation(n),
                         occlusions0=o0, occlusions1=o1, texture_quality=tq)
           for tq in ("inpainted", "none")}
    return run["inpainted"], run["none"]


def test_texture_quality_feeds_the_blend(fold_q):
    """Sec. 5.2: q(I←(t)) < 1 where key 1's inpainted torso shows; the blend leans on key 0."""
    r, r1 = fold_q
    n = len(r.t)
    assert r.inpainted_fwd.shape == r.inpainted_bwd.shape == (n,) + r.fwd.shape[1:3]
    np.testing.assert_array_equal(r.q_fwd, np.ones(n))           # key 0 has no occlusion
    assert r.q_bwd[-1] == 1.0 and not r.inpainted_bwd[-1].any()  # own keyframe: all hidden
    assert np.all(r.q_bwd[:-1] < 1) and np.all(np.diff(r.q_bwd) >= 0)
    assert not (r.inpainted_bwd & (r.bwd[..., 3] == 0)).any()    # on the silhouette only
    A, F = r.inpainted_bwd, r.bwd[..., 3] > 0.5
    np.testing.assert_allclose(r.q_bwd, 1 - (A & F).sum((1, 2)) / F.sum((1, 2)))
    assert r.q_bwd[0] == pytest.approx(0.989, abs=3e-3)          # measured at 192 px
    # q is measured in both modes; it changes the costs and moves the path towards key 0
    np.testing.assert_array_equal(r.q_bwd, r1.q_bwd)
    assert np.all(r.path.alphas <= r1.path.alphas + 1e-12)
    assert np.any(r.path.alphas < r1.path.alphas - 1e-12)
    assert np.all(r.costs.vertex[-1] == r1.costs.vertex[-1])     # q = 1 at key 1: same row
    assert not np.array_equal(r.costs.vertex, r1.costs.vertex)
    np.testing.assert_array_equal(r.frames[[0, -1]], r1.frames[[0, -1]])


def test_texture_quality_option_errors(fold):
    pair, k0, k1, o0, o1 = fold
    with pytest.raises(ValueError, match="texture_quality must be one of"):
        inbetween(k0, k1, pair.skeleton0, pair.skeleton1, 3, pair.animation(3),
                  occlusions0=o0, occlusions1=o1, texture_quality="iou")


# ------------------------------------------------------------------ three layers (nested pockets)
def _grid(nx, ny):
    g = np.array([[x, y] for y in range(ny + 1) for x in range(nx + 1)], float)
    tris = []
    for y in range(ny):
        for x in range(nx):
            a, b = y * (nx + 1) + x, y * (nx + 1) + x + 1
            c, d = (y + 1) * (nx + 1) + x + 1, (y + 1) * (nx + 1) + x
            tris += [[a, b, c], [a, c, d]]
    return g, np.array(tris)


def _cells_in(X, tris, x0, x1, y0, y1):
    c = X[tris].mean(1)
    return np.flatnonzero((c[:, 0] > x0) & (c[:, 0] < x1) & (c[:, 1] > y0) & (c[:, 1] < y1))


@pytest.mark.parametrize("boxes", [((1, 5, 1, 4), (3, 7, 2, 5)),     # outlines cross
                                   ((1, 7, 1, 5), (3, 6, 2, 4))])    # nested
def test_overlapping_pockets_incise_each_layer_exactly_along_its_own_cuts(boxes):
    """Two overlapping regions of an 8×6 grid (Sec. 4.2 pockets, one per region): three layers
    in the overlap; each region's incision (Algorithm 1) cuts its own base triangles or its
    own pocket from the outside exactly where ``b`` says, and leaves the other region's pocket
    running across its outline."""
    from physlab.inbetween.occlusion import sew_pockets

    X, tris = _grid(8, 6)
    sels = [_cells_in(X, tris, *b) for b in boxes]
    X_all, T_all, regs = sew_pockets(X, tris, sels)
    both = np.intersect1d(*sels)
    assert len(both) > 0 and len(X_all) == len(X) + sum(len(r.pocket_of) for r in regs)
    # three layers over the overlap: every overlap cell is covered three times
    cent = X_all[T_all].mean(1).round(6)
    in_both = np.isin(np.arange(len(T_all)), both)
    for c in np.unique(cent[in_both], axis=0):
        assert (cent == c).all(1).sum() == 3
    bs = []
    for reg in regs:
        n = reg.n_edges
        tj = [0, n // 2]
        reg.t_junctions = np.array(tj)
        bs.append(valid_assignments(n, tj)[0][0])
    T2, n_new, copies = incise(T_all, regs, bs, len(X_all))
    X2 = np.r_[X_all, X_all[[v for v, _ in copies]]]
    TriMesh(X2, T2)                                          # a valid mesh
    def shared(i, j):  # triangles i and j of the incised template still share an edge
        return len(set(T2[i].tolist()) & set(T2[j].tolist())) == 2

    for r, (reg, b) in enumerate(zip(regs, bs)):
        other = regs[1 - r]
        outside = np.setdiff1d(np.arange(len(tris)), reg.tris_a)
        for i in range(reg.n_edges):
            e = (reg.loop[i], reg.loop[(i + 1) % reg.n_edges])
            (o,) = outside[_edge_sharers(T_all, outside, e)]      # by triangle, before the cut
            (a,) = reg.tris_a[_edge_sharers(T_all, reg.tris_a, e)]
            (p,) = reg.tris_b[_edge_sharers(T_all, reg.tris_b, e)]
            assert shared(o, a) == (b[i] == 0) and shared(o, p) == (b[i] == 1)
            # where this outline runs inside the other region, the other's pocket runs across
            u, v = (other.pocket_of.get(int(w)) for w in e)
            if u is not None and v is not None and u in T2[other.tris_b] and v in T2[other.tris_b]:
                assert len(_edge_sharers(T2, other.tris_b, (u, v))) == 2
    # the template stays one connected piece (non-manifold but connected, Sec. 3)
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    E = np.r_[T2[:, [0, 1]], T2[:, [1, 2]]]
    assert connected_components(coo_matrix((np.ones(len(E)), E.T), shape=(len(X2),) * 2),
                                directed=False)[0] == 1


def test_overlap_incision_is_the_pocket_rule_for_one_region():
    """The union–find incision of overlapping regions, on a single pocket, cuts exactly as the
    per-layer rule of :func:`incise` (same copies, same edges shared)."""
    from physlab.inbetween.occlusion import _incise_overlapping

    X, T, reg = _square_with_pocket()
    for b in (valid_assignments(8, [0, 4])[0][0], valid_assignments(8, [0, 4])[1][0],
              np.array([0, 0, 1, 1, 1, 1, 1, 0])):
        T1, n1, c1 = incise(T, [reg], [b], len(X))
        T2, n2, c2 = _incise_overlapping(T, [reg], [b], len(X))
        assert n1 == n2 and sorted(c1) == sorted(c2)

        def pairs(tt):  # which triangles share an edge
            E = {}
            for i, t in enumerate(tt):
                for e in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
                    E.setdefault(tuple(sorted(e)), []).append(i)
            return sorted(tuple(v) for v in E.values() if len(v) > 1)

        assert pairs(T1) == pairs(T2)


@pytest.fixture(scope="module")
def three():
    from physlab.inbetween import occlusion_benchmark_three_layers

    (pair,) = occlusion_benchmark_three_layers(SIZE)
    k0, k1 = pair.keyframes()
    o0, o1 = pair.occlusions()
    tpl = build_layered_template(k1, pair.skeleton1, o1, target_skeletons=pair.animation(5)[::-1][1:],
                                 other_image=k0, other_occlusions=o0)
    return pair, k0, k1, o0, o1, tpl


def test_layered_masks_of_the_three_layer_pair(three):
    """One mask per hidden layer, sorted by depth (Sec. 4): the torso under the left forearm,
    then the right forearm under torso and left forearm; they overlap where the forearms
    cross. On the two-layer pairs the masks cover the same pixels as character_occlusions."""
    from physlab.inbetween import character_layered_occlusions, character_occlusions

    pair, k0, k1, o0, o1, tpl = three
    assert o0 == [] and len(o1) == 2
    assert o1[0].label.endswith("/torso") and "left_forearm" in o1[0].label
    assert o1[1].label.endswith("/right_forearm+right_hand")
    assert (o1[0].mask & o1[1].mask).sum() > 50                 # 94 px at 192 px
    assert all(len(o.t_junctions) % 2 == 0 and len(o.t_junctions) >= 2 for o in o1)
    for p in occlusion_benchmark(SIZE):
        lay, flat = character_layered_occlusions(p.skeleton1, SIZE), character_occlusions(
            p.skeleton1, SIZE)
        u = np.any([o.mask for o in lay], axis=0)
        np.testing.assert_array_equal(u, np.any([o.mask for o in flat], axis=0))
        assert sum(o.mask.sum() for o in lay) == u.sum()        # no overlap: two layers


def test_three_layer_template_rest_pose_renders_the_keyframe(three):
    pair, k0, k1, o0, o1, tpl = three
    assert tpl.n_layers == 3 and np.bincount(tpl.layer_rank).tolist()[2] > 20
    assert tpl.regions[0].overlaps == (1,) and tpl.regions[1].overlaps == (0,)
    H, W = tpl.shape
    assert tpl.texture.shape == (3 * H, W, 4) and tpl.inpainted.shape == (3 * H, W)
    img = tpl.image
    out = tpl.render(tpl.X)
    diff = np.abs(out[..., :3] * out[..., 3:] - img[..., :3] * img[..., 3:]).max(-1)
    assert np.percentile(diff[tpl.mask], 99) < 0.02 and diff[tpl.mask].mean() < 0.003
    # nothing hidden shows at rest, the atlas bands are inpainted only inside their regions
    assert not tpl.render_inpainted(tpl.X).any()
    both = o1[0].mask & o1[1].mask
    assert not (tpl.inpainted[2 * H:] & ~both).any()
    assert not (tpl.inpainted[H:2 * H] & ~(o1[0].mask | o1[1].mask)).any()
    # the other key textures part of the hidden layers
    assert 0.0 < tpl.inpainted_fraction < 0.9


def test_three_layer_order_follows_the_joint_depths(three):
    """In the overlap the three layers hold left forearm (depth −1), torso (0) and right
    forearm (+1), front to back (Sec. 5.1); measured mean layer depths −0.63, 0.00, 0.53."""
    pair, k0, k1, o0, o1, tpl = three
    a, b = tpl.regions
    O = np.intersect1d(a.tris_a, b.tris_a)
    pos = [{int(t): k for k, t in enumerate(r.tris_a)} for r in (a, b)]
    stack = [O] + [r.tris_b[[p[int(t)] for t in O]] for r, p in zip((a, b), pos)]
    d = tpl.triangle_depth()
    for k, tt in enumerate(stack):
        assert set(tpl.layer_rank[tt].tolist()) == {k}
    means = [d[tt].mean() for tt in stack]
    assert means[0] < -0.4 and abs(means[1]) < 0.2 and means[2] > 0.4
    # the handles on those layers: the right hand in the back pocket
    sk = pair.skeleton1
    h = sk.index("right_hand")
    assert tpl.layer_rank[tpl.handle_tris[h]] == 2
    # each region picked its topology by energy, switching at its T-junctions (Eq. 2)
    for reg in tpl.regions:
        assert len(reg.energies) == count_valid_assignments(reg.n_edges, len(reg.t_junctions))
        sw = {i for i in range(reg.n_edges) if reg.b[i] != reg.b[i - 1]}
        assert set(reg.t_junctions.tolist()) <= sw


def test_three_layer_template_bad_input(three):
    pair, k0, k1, o0, o1, tpl = three
    kw = dict(target_skeletons=[pair.skeleton0], name="key1")
    with pytest.raises(ValueError, match=r"key1: occlusions are listed in an order the joint "
                                         r"depths contradict: occlusions\[0\] comes before "
                                         r"occlusions\[1\]"):
        build_layered_template(k1, pair.skeleton1, o1[::-1], **kw)
    flat = pair.skeleton1.with_depth(np.zeros(len(pair.skeleton1)))
    with pytest.raises(ValueError, match=r"occlusions\[0\] and occlusions\[1\] overlap, so 3 "
                                         r"layers.*only 1 distinct depth.*skeleton.depth"):
        build_layered_template(k1, flat, o1, **kw)
    m = o1[1].mask.copy()
    m[tuple(np.argwhere(m)[0])] = False                      # the same mask but one pixel
    inner = Occlusion(m)
    with pytest.raises(ValueError, match=r"occlusions\[1\] overlaps an earlier occlusion region, "
                                         r"occlusions\[0\], almost entirely"):
        build_layered_template(k1, pair.skeleton1, [o1[1], inner], **kw)


# measured at 192 px, 7 frames: PSNR t = 0.5 / all in-betweens, CD ×1e5 t = 0.5 / all:
# three layers 26.91 / 30.82 dB, 1.44 / 0.89; one sheet 24.83 / 29.07 dB, 1.88 / 1.26; the
# merged two-layer region (character_occlusions) 26.41 / 29.79 dB, 1.50 / 1.12
def test_three_layer_inbetween_beats_the_single_sheet_and_two_layers():
    from physlab.inbetween import character_occlusions, occlusion_benchmark_three_layers
    from physlab.inbetween.evaluate import score_frames

    (pair,) = occlusion_benchmark_three_layers(SIZE)
    k0, k1 = pair.keyframes()
    o0, o1 = pair.occlusions()
    n = 7
    truth = pair.ground_truth(np.linspace(0, 1, n))
    anim = pair.animation(n)
    lay = inbetween(k0, k1, pair.skeleton0, pair.skeleton1, n, anim, occlusions0=o0,
                    occlusions1=o1)
    assert lay.templates[1].n_layers == 3
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        one = inbetween(k0, k1, pair.skeleton0, pair.skeleton1, n, anim)
    assert any("overlap" in str(x.message) for x in w)
    two = inbetween(k0, k1, pair.skeleton0, pair.skeleton1, n, anim, occlusions0=o0,
                    occlusions1=character_occlusions(pair.skeleton1, SIZE))
    assert two.templates[1].n_layers == 2
    s_l, s_s, s_2 = (score_frames(r.frames, truth) for r in (lay, one, two))
    assert s_l["psnr_mid"] > s_s["psnr_mid"] + 1.0 and s_l["psnr_all"] > s_s["psnr_all"] + 1.0
    assert s_l["cd_mid"] < 0.9 * s_s["cd_mid"] and s_l["cd_all"] < 0.85 * s_s["cd_all"]
    assert s_l["psnr_all"] > s_2["psnr_all"] + 0.5 and s_l["cd_all"] < 0.9 * s_2["cd_all"]
