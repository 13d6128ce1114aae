"""physlab.inbetween.characters: procedural cartoon characters with ground-truth poses."""
import subprocess
import sys

import numpy as np
import pytest
from scipy import ndimage as ndi

from physlab.inbetween import characters as ch
from physlab import datasets
from physlab.inbetween.skeleton import Skeleton, interpolate

STYLES = ch.CHARACTER_STYLES
S = 192  # small image size for the fast tests


@pytest.fixture(scope="module")
def benchmark():
    return ch.inbetween_benchmark()  # the default, 512 px


def luminance(rgb):
    return rgb[..., :3].astype(float) @ [0.2125, 0.7154, 0.0721] / 255


def premultiplied(img):
    out = img.astype(float)
    out[..., :3] *= out[..., 3:4] / 255
    return out


def rotate_image(img, deg, center):
    """Premultiplied float image rotated by ``deg`` (clockwise on screen) about (x, y) center."""
    th = np.deg2rad(deg)
    # output pixel (row, col) samples the input at R^-1 (p - c) + c, written in (row, col)
    M = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    c = np.asarray(center, float)[::-1]
    pre = premultiplied(img)
    return np.stack([ndi.affine_transform(pre[..., k], M, c - M @ c, order=1)
                     for k in range(4)], axis=-1)


def rotate_skeleton(sk, deg, center):
    th = np.deg2rad(deg)
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    return sk.with_xy((sk.xy - center) @ R.T + center)


# ---------------------------------------------------------------------------- skeleton
def test_rest_skeleton_reference_and_layout():
    sk = ch.character_skeleton(512)
    assert isinstance(sk, Skeleton) and sk.names == ch.CHARACTER_JOINTS and len(sk) == 16
    assert sk.names[sk.root] == "pelvis"
    assert sk.names[sk.parents[sk.index("left_hand")]] == "left_elbow"
    u = 512 / 512 * 0.7 * 512 / 404.0  # image px per design px
    np.testing.assert_allclose(sk.xy[sk.index("pelvis")], [255.5, 255.5 + 26 * u])
    np.testing.assert_allclose(sk.xy[sk.index("head_top")], [255.5, 255.5 + (26 - 216) * u])
    # symmetric; the character's left is on the image's right; arms out, legs apart
    xy = sk.xy - sk.xy[sk.root]
    for n in ("shoulder", "elbow", "hand", "hip", "knee", "foot"):
        left, right = xy[sk.index(f"left_{n}")], xy[sk.index(f"right_{n}")]
        np.testing.assert_allclose(left, right * [-1, 1], atol=1e-9)
        assert left[0] > 0
    hand, shoulder = xy[sk.index("left_hand")], xy[sk.index("left_shoulder")]
    assert hand[0] - shoulder[0] > 0.15 * 512 and 0 < hand[1] - shoulder[1] < 0.12 * 512
    assert xy[sk.index("left_foot"), 0] > 1.5 * xy[sk.index("left_hip"), 0]


@pytest.mark.parametrize("size", [96, 512])
def test_rest_figure_fills_70_percent_centred(size):
    img = ch.render_character(ch.character_skeleton(size), "flat", size)
    ys, xs = np.nonzero(img[..., 3])
    assert (ys.max() - ys.min() + 1) / size == pytest.approx(0.70, abs=0.015)
    assert (ys.max() + ys.min()) / 2 == pytest.approx((size - 1) / 2, abs=1.5)
    assert (xs.max() + xs.min()) / 2 == pytest.approx((size - 1) / 2, abs=1.0)


def test_skeleton_scales_with_size():
    a, b = ch.character_skeleton(256), ch.character_skeleton(512)
    np.testing.assert_allclose(2 * (a.xy - 127.5), b.xy - 255.5, atol=1e-9)


def test_pose_character_rotates_bones_relative_to_rest():
    rest = ch.character_skeleton(S)
    p = ch.pose_character(rest, left_upper_arm=-30, head=10)
    d = np.rad2deg(p.local_angles() - rest.local_angles())
    expect = np.zeros(16)
    expect[rest.index("left_elbow")], expect[rest.index("head_top")] = -30, 10
    np.testing.assert_allclose(d, expect, atol=1e-9)
    np.testing.assert_allclose(p.bone_lengths(), rest.bone_lengths())
    # negative = counter-clockwise on screen: the left (screen-right) arm goes up
    assert p.xy[p.index("left_hand"), 1] < rest.xy[rest.index("left_hand"), 1]
    # whole-body rotation and offset are rigid motions; stretch scales one bone
    r = ch.pose_character(rest, rotation=90, offset=(3, -2))
    c = rest.xy[rest.root]
    np.testing.assert_allclose(r.xy, (rest.xy - c) @ np.array([[0, 1], [-1, 0]]) + c + [3, -2],
                               atol=1e-9)
    s = ch.pose_character(rest, stretch={"torso": 1.2})
    j = rest.index("chest")
    assert s.bone_lengths()[j] == pytest.approx(1.2 * rest.bone_lengths()[j])
    with pytest.raises(ValueError, match="forearm"):
        ch.pose_character(rest, left_hand=10)
    with pytest.raises(ValueError, match="stretch"):
        ch.pose_character(rest, stretch={"head": 0})


# ---------------------------------------------------------------------------- rendering
@pytest.mark.parametrize("style", STYLES)
def test_render_format_ink_and_texture(style):
    img = ch.render_character(ch.character_skeleton(S), style, S, seed=1)
    assert img.shape == (S, S, 4) and img.dtype == np.uint8
    a = img[..., 3]
    assert np.all(np.concatenate([a[0], a[-1], a[:, 0], a[:, -1]]) == 0)
    assert 0.08 < (a == 255).mean() < 0.4
    partial = (a > 0) & (a < 255)
    assert partial.any()  # antialiased edges, only at edges
    assert not np.any(partial & ~ndi.binary_dilation(a == 255, iterations=2))
    fg = a == 255
    rim = fg & ~ndi.binary_erosion(fg, iterations=1)
    L = luminance(img)
    assert np.median(L[rim]) < 0.3  # dark ink outline
    inner = ndi.binary_erosion(fg, iterations=4)
    assert L[inner].std() > 0.1  # textures, not flat fills
    assert len(np.unique(img[inner][:, :3] // 32, axis=0)) >= 8


def test_render_is_deterministic_and_depends_on_style_and_seed():
    sk = ch.pose_character(ch.character_skeleton(S), left_forearm=-40)
    a = ch.render_character(sk, "shaded", S, seed=3)
    np.testing.assert_array_equal(a, ch.render_character(sk, "shaded", S, seed=3))
    assert not np.array_equal(a, ch.render_character(sk, "shaded", S, seed=4))
    assert not np.array_equal(a, ch.render_character(sk, "flat", S, seed=3))
    # silhouettes do not depend on style or seed, only on the pose
    alphas = [ch.render_character(sk, st, S, seed=s)[..., 3] for st in STYLES for s in (0, 9)]
    for al in alphas[1:]:
        np.testing.assert_array_equal(al, alphas[0])


@pytest.mark.parametrize("style", STYLES)
def test_rigid_rotation_by_90_degrees_rotates_the_image(style):
    sk = ch.pose_character(ch.character_skeleton(S), left_upper_arm=-50, head=12, right_shin=-15)
    img = ch.render_character(sk, style, S, seed=2)
    # np.rot90 (counter-clockwise on screen): pixel (x, y) moves to (y, S - 1 - x)
    rot = sk.with_xy(np.stack([sk.xy[:, 1], S - 1 - sk.xy[:, 0]], axis=1))
    diff = np.abs(np.rot90(img).astype(int) - ch.render_character(rot, style, S, seed=2))
    assert diff.mean() < 0.05


@pytest.mark.parametrize("style", STYLES)
def test_rigid_rotation_by_30_degrees_moves_texture_with_the_body(style):
    sk = ch.pose_character(ch.character_skeleton(S), left_upper_arm=-40, right_forearm=20)
    c = np.array([(S - 1) / 2, (S - 1) / 2])
    img = ch.render_character(sk, style, S, seed=1)
    img2 = premultiplied(ch.render_character(rotate_skeleton(sk, 30, c), style, S, seed=1))
    fg = img2[..., 3] > 0
    err = np.abs(rotate_image(img, 30, c) - img2)[fg]
    unrotated = np.abs(premultiplied(img) - img2)[fg].mean()
    # bilinear resampling blurs the ink edges a little; the rest matches
    assert err.mean() < 10 and np.median(err) < 5 and err.mean() < unrotated / 8


@pytest.mark.parametrize("style", STYLES)
def test_moving_one_forearm_moves_only_its_texture_rigidly(style):
    size = 256
    sk0 = ch.pose_character(ch.character_skeleton(size), left_upper_arm=-20)
    sk1 = ch.pose_character(sk0, left_forearm=35)
    img0 = ch.render_character(sk0, style, size, seed=4)
    img1 = ch.render_character(sk1, style, size, seed=4)
    # only the forearm and hand change (plus the elbow cap of the upper arm lying on them)
    changed = np.any(img0 != img1, axis=-1)
    arm = [ch.CHARACTER_PARTS.index(p) for p in ("left_forearm", "left_hand")]
    near = ndi.binary_dilation(np.isin(ch.character_part_labels(sk0, size), arm)
                               | np.isin(ch.character_part_labels(sk1, size), arm),
                               iterations=2)
    assert changed.any() and not np.any(changed & ~near)
    # inside the forearm, img1 = img0 rotated by 35° about the elbow
    elbow = sk0.xy[sk0.index("left_elbow")]
    inside = ndi.binary_erosion(ch.character_part_labels(sk1, size) == arm[0], iterations=2)
    assert inside.sum() > 80
    err = np.abs(rotate_image(img0, 35, elbow) - premultiplied(img1))[inside].mean()
    still = np.abs(premultiplied(img0) - premultiplied(img1))[inside].mean()
    assert err < 10 and still > 5 * err


def test_stretched_bone_stretches_its_part():
    rest = ch.character_skeleton(256)
    long = ch.pose_character(rest, stretch={"left_thigh": 1.3})
    i = ch.CHARACTER_PARTS.index("left_thigh")
    hip = rest.xy[rest.index("left_hip")]

    def reach(sk):  # farthest thigh pixel from the hip: bone length + end radius
        ys, xs = np.nonzero(ch.character_part_labels(sk, 256) == i)
        return np.hypot(xs - hip[0], ys - hip[1]).max()

    L = rest.bone_lengths()[rest.index("left_knee")]
    r = 15 * L / 80  # thigh: 80 design px long, end radius 15
    assert reach(rest) == pytest.approx(L + r, abs=1.0)
    assert reach(long) == pytest.approx(1.3 * (L + r), abs=1.0)  # the whole part scales


def test_part_labels_match_the_render_and_layering():
    sk = ch.character_skeleton(256)
    lab = ch.character_part_labels(sk, 256)
    assert lab.dtype == np.int8 and lab.min() == -1 and lab.max() == len(ch.CHARACTER_PARTS) - 1
    alpha = ch.render_character(sk, "flat", 256)[..., 3]
    inside, opaque = lab >= 0, alpha >= 128  # pixel centre inside ⇔ coverage ≥ 1/2
    assert (inside & opaque).sum() / (inside | opaque).sum() > 0.995
    counts = np.bincount(lab[lab >= 0], minlength=len(ch.CHARACTER_PARTS))
    assert np.all(counts > 30)  # every part visible at rest
    # the torso covers the top of the upper arm at the shoulder (parents over children)
    x, y = np.round(sk.xy[sk.index("left_shoulder")] - [4, 0]).astype(int)
    assert ch.CHARACTER_PARTS[lab[y, x]] == "torso"
    assert sorted(ch.PAINT_ORDER) == sorted(ch.CHARACTER_PARTS)


def test_part_overlaps_reports_occlusions_only():
    rest = ch.character_skeleton(256)
    assert ch.part_overlaps(rest, 256) == []
    hug = ch.pose_character(rest, left_upper_arm=60, left_forearm=100)  # hand on the belly
    pairs = {(a, b) for a, b, _ in ch.part_overlaps(hug, 256)}
    assert ("torso", "left_hand") in pairs or ("torso", "left_forearm") in pairs
    crossed = ch.pose_character(rest, left_thigh=35, right_thigh=-35)
    assert any({a, b} == {"right_thigh", "left_thigh"} for a, b, _ in
               ch.part_overlaps(crossed, 256))
    # adjacent parts overlap at their joint but are never reported
    for a, b, n in ch.part_overlaps(hug, 256) + ch.part_overlaps(crossed, 256):
        assert frozenset((a, b)) not in ch.ADJACENT_PARTS and n > 0


# ---------------------------------------------------------------------------- errors
def test_bad_inputs_raise_clear_errors():
    sk = ch.character_skeleton(S)
    with pytest.raises(ValueError, match="unknown style"):
        ch.render_character(sk, "watercolour", S)
    with pytest.raises(ValueError, match="size must be >= 64"):
        ch.render_character(ch.character_skeleton(64), "flat", 32)
    with pytest.raises(ValueError, match="size must be >= 64"):
        ch.character_skeleton(40)
    with pytest.raises(ValueError, match="outside the 96×96 image"):
        ch.render_character(sk, "flat", 96)  # a skeleton made for a larger image
    with pytest.raises(ValueError, match="topology of character_skeleton"):
        names = list(sk.names)
        names[-1] = "left_toe"
        ch.render_character(Skeleton(names, sk.parents, sk.xy), "flat", S)
    with pytest.raises(ValueError, match="topology of character_skeleton"):
        ch.render_character(Skeleton(sk.names[:3], sk.parents[:3], sk.xy[:3]), "flat", S)
    with pytest.raises(TypeError, match="Skeleton"):
        ch.render_character(sk.xy, "flat", S)
    with pytest.raises(ValueError, match="topology of character_skeleton"):
        ch.part_overlaps(Skeleton(["a", "b"], [-1, 0], [[1, 1], [5, 5]]), S)
    with pytest.raises(ValueError, match="kind"):
        ch.InbetweenPair("x", "medium", "flat", 0, sk, sk, S)
    with pytest.raises(ValueError, match="skeleton1"):
        ch.InbetweenPair("x", "tight", "flat", 0, sk, ch.character_skeleton(2 * S), S)
    pair = ch.InbetweenPair("x", "tight", "flat", 0, sk, sk, S)
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        pair.ground_truth(1.5)
    with pytest.raises(ValueError, match="n_frames"):
        pair.animation(1)


# ---------------------------------------------------------------------------- benchmark
def test_benchmark_counts_and_angle_criteria(benchmark):
    assert len(benchmark) >= 12
    assert len({p.name for p in benchmark}) == len(benchmark)
    kinds = [p.kind for p in benchmark]
    assert kinds.count("tight") >= 5 and kinds.count("far") >= 6
    assert {p.style for p in benchmark} == set(STYLES)
    assert len({p.seed for p in benchmark}) == len(benchmark)
    for p in benchmark:
        assert p.size == 512 and p.skeleton0.same_topology(p.skeleton1)
        change = p.angle_changes()
        if p.kind == "tight":
            assert change.max() <= 25.0 + 1e-9, p.name
        else:
            # some limb swings > 90°, and < 180° so the shortest arc is unambiguous
            assert 90.0 < change.max() < 170.0, p.name


def test_benchmark_is_occlusion_free_and_inside_the_image(benchmark):
    for p in benchmark:
        for t, sk in zip(np.linspace(0, 1, 21), p.animation(21)):
            assert ch.part_overlaps(sk, p.size) == [], (p.name, t)
            lab = ch.character_part_labels(sk, p.size) >= 0
            border = np.concatenate([lab[:4].ravel(), lab[-4:].ravel(), lab[:, :4].ravel(),
                                     lab[:, -4:].ravel()])
            assert not border.any(), (p.name, t)


def test_inbetween_pair_renders_ground_truth_along_the_animation():
    pairs = ch.inbetween_benchmark(size=96)
    assert [p.name for p in pairs] == [p.name for p in ch.inbetween_benchmark()]
    p = next(q for q in pairs if q.kind == "far")
    k0, k1 = p.keyframes()
    np.testing.assert_array_equal(p.ground_truth(0.0), k0)
    np.testing.assert_array_equal(p.ground_truth(1.0), k1)
    mid = p.ground_truth(0.5)
    assert not np.array_equal(mid, k0) and not np.array_equal(mid, k1)
    stack = p.ground_truth(np.array([0.0, 0.5, 1.0]))
    assert stack.shape == (3, 96, 96, 4) and stack.dtype == np.uint8
    np.testing.assert_array_equal(stack[1], mid)
    anim = p.animation(5)
    assert len(anim) == 5 and all(isinstance(s, Skeleton) for s in anim)
    np.testing.assert_allclose(anim[0].xy, p.skeleton0.xy)
    np.testing.assert_allclose(anim[-1].xy, p.skeleton1.xy)
    np.testing.assert_allclose(anim[2].xy, interpolate(p.skeleton0, p.skeleton1, 0.5).xy)
    np.testing.assert_array_equal(
        mid, ch.render_character(anim[2], p.style, p.size, p.seed))


# ---------------------------------------------------------------------------- packaging
def test_old_import_paths_work_for_one_release_and_warn():
    import importlib

    import physlab.inbetween as ib

    for name in ch.__all__:
        assert getattr(ib, name) is getattr(ch, name)
    for name in datasets._MOVED:  # names that lived in physlab.datasets before the move
        with pytest.warns(DeprecationWarning, match=f"physlab.datasets.{name} moved"):
            assert getattr(datasets, name) is getattr(ch, name)
    sys.modules.pop("physlab.characters", None)
    with pytest.warns(DeprecationWarning, match="physlab.characters moved"):
        old = importlib.import_module("physlab.characters")
    assert old.inbetween_benchmark is ch.inbetween_benchmark


def test_importing_datasets_stays_light():
    code = ("import sys, physlab.datasets, physlab.paint; "
            "print(sorted(m for m in ('torch', 'matplotlib', 'scipy', 'physlab.inbetween') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]"
