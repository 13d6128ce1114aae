"""Tests of physlab.inbetween.retarget: posing drawn skeletons with BVH motions.

A tiny hand-made BVH actor gives analytic cases; the real cases use the AnimatedDrawings
example characters and BVH clips from the external data folder (``real_data`` fixture).
Attribution: AnimatedDrawings, MIT, © Meta Platforms, Inc. and affiliates; jumping_jacks.bvh
derives from the CMU Graphics Lab Motion Capture Database (mocap.cs.cmu.edu, NSF EIA-0196217).
"""
import numpy as np
import pytest

from physlab.inbetween import Skeleton
from physlab.inbetween.retarget import (
    ANIMATED_DRAWINGS_MOTIONS,
    ANIMATED_DRAWINGS_START_FRAMES,
    CMU1_MAPPING,
    FAIR1_MAPPING,
    ROKOKO_MAPPING,
    KeyframePoses,
    bvh_joint_depths,
    bvh_to_skeletons,
    default_mapping,
    keyframe_poses,
    load_character,
    load_motion,
)
from physlab.motion import BVHMotion

# ----------------------------------------------------------------------------- tiny actor
# y up, facing +z (so its left is +x), T-pose; every joint rotates Z X Y, the root also moves.
_TINY = [  # name, parent, offset
    ("Hips", -1, (0, 0, 0)), ("Neck", 0, (0, 2, 0)),
    ("LeftArm", 0, (1, 1.8, 0)), ("LeftHand", 2, (1, 0, 0)),
    ("RightArm", 0, (-1, 1.8, 0)), ("RightHand", 4, (-1, 0, 0)),
    ("LeftUpLeg", 0, (0.5, 0, 0)), ("LeftFoot", 6, (0, -2, 0)),
    ("RightUpLeg", 0, (-0.5, 0, 0)), ("RightFoot", 8, (0, -2, 0)),
]
TINY_MAPPING = {"neck": ("Hips", "Neck"), "left_hand": ("LeftArm", "LeftHand"),
                "right_hand": ("RightArm", "RightHand"), "left_foot": ("LeftUpLeg", "LeftFoot"),
                "right_foot": ("RightUpLeg", "RightFoot")}


def tiny_motion(frames):
    """BVHMotion of the tiny actor; ``frames`` is a list of dicts joint -> {channel: value}."""
    names = [n for n, _, _ in _TINY]
    chans = [["Xposition", "Yposition", "Zposition"] * (p < 0) + ["Zrotation", "Xrotation",
                                                                   "Yrotation"]
             for _, p, _ in _TINY]
    rows = []
    for fr in frames:
        row = []
        for n, c in zip(names, chans):
            row += [fr.get(n, {}).get(ch, 0.0) for ch in c]
        rows.append(row)
    return BVHMotion(names=names, parents=[p for _, p, _ in _TINY],
                     offsets=[o for _, _, o in _TINY], channels=chans, frame_time=0.1,
                     motion=np.array(rows, dtype=float))


def tiny_drawing():
    """A drawing with arms hanging down-out and splayed legs (pixels, y down)."""
    names = ["root", "neck", "left_shoulder", "left_hand", "right_shoulder", "right_hand",
             "left_hip", "left_foot", "right_hip", "right_foot"]
    parents = [-1, 0, 0, 2, 0, 4, 0, 6, 0, 8]
    xy = [[100, 100], [100, 40], [120, 50], [150, 80], [80, 50], [50, 80],
          [110, 100], [130, 150], [90, 100], [70, 150]]
    return Skeleton(names, np.array(parents), np.array(xy, dtype=float))


def _angle(sk, name):
    return float(np.degrees(sk.bone_angles()[sk.index(name)]))


def test_tiny_tpose_absolute_directions():
    """T-pose seen from the front: left arm to screen right, neck up, legs down, and the
    drawing's bone lengths kept; lifting the left arm (Zrotation 90) points it up."""
    m = tiny_motion([{}, {"LeftArm": {"Zrotation": 90.0}}])
    sk = tiny_drawing()
    s0, s1 = bvh_to_skeletons(m, sk, TINY_MAPPING)
    assert _angle(s0, "left_hand") == pytest.approx(0.0, abs=1e-9)
    assert abs(_angle(s0, "right_hand")) == pytest.approx(180.0, abs=1e-9)
    assert _angle(s0, "neck") == pytest.approx(-90.0, abs=1e-9)
    assert _angle(s0, "left_foot") == pytest.approx(90.0, abs=1e-9)
    assert _angle(s1, "left_hand") == pytest.approx(-90.0, abs=1e-9)     # up on screen
    assert _angle(s1, "right_hand") == pytest.approx(_angle(s0, "right_hand"), abs=1e-9)
    for s in (s0, s1):
        assert s.same_topology(sk)
        np.testing.assert_allclose(s.bone_lengths(), sk.bone_lengths(), atol=1e-9)
        # unmapped bones whose parent is the root keep their drawn direction and place
        np.testing.assert_allclose(s.xy[s.index("left_shoulder")], sk.xy[sk.index("left_shoulder")],
                                   atol=1e-12)


def test_tiny_root_displacement_scaled_by_leg_ratio():
    """Stepping 1 unit to the actor's left (+x) and 0.5 up moves the root by s·(1, -0.5) px,
    s = drawing leg length / BVH leg length; root_motion=False keeps it fixed."""
    m = tiny_motion([{}, {"Hips": {"Xposition": 1.0, "Yposition": 0.5}}])
    sk = tiny_drawing()
    s = sk.bone_lengths()[[sk.index("left_foot"), sk.index("right_foot")]].sum() / 4.0
    moved = bvh_to_skeletons(m, sk, TINY_MAPPING)[1]
    np.testing.assert_allclose(moved.xy[0], sk.xy[0] + s * np.array([1.0, -0.5]), atol=1e-9)
    fixed = bvh_to_skeletons(m, sk, TINY_MAPPING, root_motion=False)[1]
    np.testing.assert_array_equal(fixed.xy[0], sk.xy[0])


def test_tiny_invariant_to_turning_and_to_the_up_axis():
    """Invariants: the actor turned about the vertical (camera follows the facing), or the
    whole clip recorded z-up (root Xrotation 90) give the same drawing poses."""
    pose = {"LeftArm": {"Zrotation": 60.0, "Yrotation": 20.0}, "RightArm": {"Zrotation": -30.0},
            "LeftUpLeg": {"Zrotation": 15.0}}
    sk = tiny_drawing()
    base = bvh_to_skeletons(tiny_motion([{}, pose]), sk, TINY_MAPPING)[1]
    turned = tiny_motion([{}, {**pose, "Hips": {"Yrotation": 70.0}}])
    got = bvh_to_skeletons(turned, sk, TINY_MAPPING)[1]
    np.testing.assert_allclose(got.xy, base.xy, atol=1e-9)
    zup = tiny_motion([{"Hips": {"Xrotation": 90.0}}, {**pose, "Hips": {"Xrotation": 90.0}}])
    got = bvh_to_skeletons(zup, sk, TINY_MAPPING)[1]
    np.testing.assert_allclose(got.xy, base.xy, atol=1e-9)
    # with a camera fixed at frame 0 the turn shows: the left arm is foreshortened
    fixed = bvh_to_skeletons(turned, sk, TINY_MAPPING, follow_turns=False)[1]
    assert not np.allclose(fixed.xy, base.xy, atol=1e-3)


def test_tiny_side_view_and_degenerate_projection():
    """Side view: an arm pointing forward (+z) points to screen right; arms along the
    left-right axis project to a point, so they keep their drawn direction."""
    m = tiny_motion([{}, {"LeftArm": {"Yrotation": -90.0}}])   # (1,0,0) -> (0,0,1)
    sk = tiny_drawing()
    s0, s1 = bvh_to_skeletons(m, sk, TINY_MAPPING, view="side")
    assert _angle(s1, "left_hand") == pytest.approx(0.0, abs=1e-9)
    for name in ("right_hand",):
        assert _angle(s0, name) == pytest.approx(_angle(sk, name), abs=1e-9)
    assert _angle(s0, "neck") == pytest.approx(-90.0, abs=1e-9)
    # per-joint views: only the left arm from the side
    s1b = bvh_to_skeletons(m, sk, TINY_MAPPING, view={"left_hand": "side"})[1]
    assert _angle(s1b, "left_hand") == pytest.approx(0.0, abs=1e-9)
    assert abs(_angle(s1b, "right_hand")) == pytest.approx(180.0, abs=1e-9)


def test_tiny_relative_method_reference_is_rest():
    m = tiny_motion([{"LeftArm": {"Zrotation": 10.0}}, {"LeftArm": {"Zrotation": 100.0}}])
    sk = tiny_drawing()
    s0, s1 = bvh_to_skeletons(m, sk, TINY_MAPPING, method="relative")
    np.testing.assert_allclose(s0.xy, sk.xy, atol=1e-9)
    # the arm rotated 90° up (counter-clockwise on screen = -90° in y-down angles)
    assert _angle(s1, "left_hand") == pytest.approx(_angle(sk, "left_hand") - 90.0, abs=1e-9)
    s1r = bvh_to_skeletons(m, sk, TINY_MAPPING, method="relative", reference_frame=1)
    np.testing.assert_allclose(s1r[1].xy, sk.xy, atol=1e-9)


def test_fractional_frames_interpolate():
    m = tiny_motion([{}, {"LeftArm": {"Zrotation": 90.0}}, {}])
    sk = tiny_drawing()
    ints = bvh_to_skeletons(m, sk, TINY_MAPPING, frames=[0, 1, 2])
    frac = bvh_to_skeletons(m, sk, TINY_MAPPING, frames=[0.0, 1.0, 2.0, 0.5])
    for a, b in zip(ints, frac):
        np.testing.assert_array_equal(a.xy, b.xy)
    assert _angle(frac[3], "left_hand") == pytest.approx(-45.0, abs=1e-9)


def test_bad_inputs_raise_clear_errors():
    m = tiny_motion([{}, {}])
    sk = tiny_drawing()
    with pytest.raises(ValueError, match="does not have"):
        bvh_to_skeletons(m, sk, {"left_wing": ("LeftArm", "LeftHand")})
    with pytest.raises(ValueError, match="no joint 'LeftWing'"):
        bvh_to_skeletons(m, sk, {"left_hand": ("LeftArm", "LeftWing")})
    with pytest.raises(ValueError, match="root"):
        bvh_to_skeletons(m, sk, {"root": ("Hips", "Neck")})
    with pytest.raises(TypeError, match="mapping must be a dict"):
        bvh_to_skeletons(m, sk, [("left_hand", "LeftArm")])
    with pytest.raises(TypeError, match="pair"):
        bvh_to_skeletons(m, sk, {"left_hand": "LeftArm"})
    with pytest.raises(TypeError, match="motion must be"):
        bvh_to_skeletons(42, sk, TINY_MAPPING)
    with pytest.raises(TypeError, match="character must be"):
        bvh_to_skeletons(m, 42, TINY_MAPPING)
    with pytest.raises(FileNotFoundError, match="no BVH file"):
        bvh_to_skeletons("/nonexistent/clip.bvh", sk, TINY_MAPPING)
    with pytest.raises(IndexError, match=r"\[0, 1\]"):
        bvh_to_skeletons(m, sk, TINY_MAPPING, frames=[0, 2])
    with pytest.raises(IndexError, match=r"\[0, 1\]"):
        bvh_to_skeletons(m, sk, TINY_MAPPING, frames=-1)
    with pytest.raises(IndexError, match="reference_frame"):
        bvh_to_skeletons(m, sk, TINY_MAPPING, reference_frame=5)
    with pytest.raises(ValueError, match="view"):
        bvh_to_skeletons(m, sk, TINY_MAPPING, view="top")
    with pytest.raises(ValueError, match="not mapped"):
        bvh_to_skeletons(m, sk, TINY_MAPPING, view={"left_shoulder": "side"})
    with pytest.raises(ValueError, match="method"):
        bvh_to_skeletons(m, sk, TINY_MAPPING, method="magic")
    with pytest.raises(ValueError, match="up"):
        bvh_to_skeletons(m, sk, TINY_MAPPING, up="+w")
    with pytest.raises(ValueError, match="naming"):
        default_mapping(m, sk)
    with pytest.raises(ValueError, match="facing|faces"):
        bvh_to_skeletons(m, sk, {"neck": ("Hips", "Neck")})
    with pytest.raises(ValueError, match="n_inbetweens"):
        keyframe_poses(sk, m, 0, 1, n_inbetweens=-1, mapping=TINY_MAPPING)


# ----------------------------------------------------------------------------- real data
CHARS = ("char1", "char2", "char3", "char4")


@pytest.fixture(scope="module")
def motions(real_data):
    return {n: load_motion(n) for n in ANIMATED_DRAWINGS_MOTIONS}


@pytest.fixture(scope="module")
def characters(real_data):
    from physlab import datasets
    out = {}
    for c in datasets.ANIMATED_DRAWINGS:
        d = datasets.animated_drawing(c)
        out[c] = (Skeleton(**d.notes["skeleton"]), d.image.shape[:2])
    return out


@pytest.mark.parametrize("char", CHARS + ("char5", "char6"))
@pytest.mark.parametrize("name", sorted(ANIMATED_DRAWINGS_MOTIONS))
def test_real_clips_keep_lengths_stay_near_image_and_move(motions, characters, char, name):
    m = motions[name]
    sk, (H, W) = characters[char]
    frames = np.arange(ANIMATED_DRAWINGS_START_FRAMES[name], m.n_frames, 3)
    sks = bvh_to_skeletons(m, sk, frames=frames, reference_frame=frames[0])
    assert len(sks) == len(frames)
    xy = np.stack([s.xy for s in sks])                                  # (F, J, 2)
    for s in sks:
        assert s.same_topology(sk)
        np.testing.assert_allclose(s.bone_lengths(), sk.bone_lengths(), rtol=0, atol=1e-9)
    margin = 0.5 * max(H, W)   # limbs swung straight out can pass the drawing's bounding box
    assert xy[..., 0].min() > -margin and xy[..., 0].max() < W + margin
    assert xy[..., 1].min() > -margin and xy[..., 1].max() < H + margin
    # the motion is not frozen: some joint moves by more than 10% of the drawing's height
    # (char6 has no arms, and wave_hello moves little but the arms)
    assert np.ptp(xy, axis=0).max() > (0.1 * np.ptp(sk.xy[:, 1]) if char != "char6" else 1.0)
    # the character faces the camera and is upright on average: its left side on the
    # image's right, the neck above the root
    L = [j for j, n in enumerate(sk.names) if n.startswith("left_")]
    R = [j for j, n in enumerate(sk.names) if n.startswith("right_")]
    if char != "char6":                     # char6 is a four-legged animal drawn side-on
        assert xy[:, L, 0].mean() > xy[:, R, 0].mean()
    assert xy[:, sk.index("neck"), 1].mean() < xy[:, sk.root, 1].mean()


@pytest.mark.parametrize("char", CHARS)
@pytest.mark.parametrize("name", sorted(ANIMATED_DRAWINGS_MOTIONS))
def test_real_relative_reference_frame_is_rest(motions, characters, char, name):
    m = motions[name]
    sk, _ = characters[char]
    ref = ANIMATED_DRAWINGS_START_FRAMES[name] + 7
    s_ref, s_late = bvh_to_skeletons(m, sk, frames=[ref, m.n_frames - 1], method="relative",
                                     reference_frame=ref)
    np.testing.assert_allclose(s_ref.xy, sk.xy, rtol=0, atol=1e-9)
    np.testing.assert_allclose(s_late.bone_lengths(), sk.bone_lengths(), rtol=0, atol=1e-9)
    assert not np.allclose(s_late.xy, sk.xy, atol=1.0)


def test_real_dab_starts_in_a_t_pose(motions, characters):
    """fair1/dab.bvh frame 0 is a T-pose: arms horizontal (left to screen right), trunk up,
    legs down."""
    s = bvh_to_skeletons(motions["dab"], characters["char1"][0], frames=[0])[0]
    a = np.degrees(s.bone_angles())
    ang = {n: a[s.index(n)] for n in s.names}
    for n in ("left_elbow", "left_hand"):
        assert abs(ang[n]) < 10
    for n in ("right_elbow", "right_hand"):
        assert abs(abs(ang[n]) - 180) < 15
    for n in ("torso", "neck"):
        assert abs(ang[n] + 90) < 5
    for n in ("left_knee", "left_foot", "right_knee", "right_foot"):
        assert abs(ang[n] - 90) < 5


def test_real_reference_numbers(motions, characters):
    """Fixed numbers: char1 posed by jumping_jacks frame 25 (arms up mid-jump, root up)."""
    s = bvh_to_skeletons(motions["jumping_jacks"], characters["char1"][0], frames=[25])[0]
    np.testing.assert_allclose(s.xy[s.index("left_hand")], [454.80538314573096, 148.58394062401655],
                               atol=1e-6)
    np.testing.assert_allclose(s.xy[s.root], [264.190515748433, 371.5177562315405], atol=1e-6)


def _ad_retarget_mapping(real_data, cfg):
    """char_joint_bvh_joints_mapping of an AnimatedDrawings retarget config (with its
    ``!!python/tuple`` tags)."""
    import yaml

    class Loader(yaml.SafeLoader):
        pass

    Loader.add_constructor("tag:yaml.org,2002:python/tuple",
                           lambda loader, node: tuple(loader.construct_sequence(node)))
    path = real_data / "animated_drawings" / "examples" / "config" / "retarget" / f"{cfg}.yaml"
    with open(path, encoding="utf-8") as f:
        return {k: tuple(v) for k, v in yaml.load(f, Loader=Loader)
                ["char_joint_bvh_joints_mapping"].items()}


@pytest.mark.parametrize("char,name,cfg", [
    ("char1", "dab", "fair1_ppf"), ("char3", "jumping_jacks", "cmu1_pfp"),
    ("char3", "jesse_dance", "mixamo_fff"), ("char5", "dab", "six_arms"),
    ("char6", "zombie", "four_legs"), ("char4", "wave_hello", "fair1_spf")])
def test_default_mapping_matches_animated_drawings_configs(real_data, motions, characters,
                                                          char, name, cfg):
    """The pairings of AnimatedDrawings' mvc examples (config/mvc/*.yaml)."""
    assert default_mapping(motions[name], characters[char][0]) == _ad_retarget_mapping(
        real_data, cfg)


def test_default_mapping_drops_a_neck_drawn_below_the_shoulders(motions, characters):
    """AnimatedDrawings' char_runtime_checks: a head drawn below the shoulder line is not
    driven (it would flip); the bone then keeps its rest angle relative to the torso."""
    sk = characters["char1"][0]
    xy = sk.xy.copy()
    xy[sk.index("neck")] = [250, 300]
    low = sk.with_xy(xy)
    mp = default_mapping(motions["dab"], low)
    assert "neck" not in mp and "torso" in mp
    s = bvh_to_skeletons(motions["dab"], low, mp, frames=[100])[0]
    rel = s.local_angles()[s.index("neck")]
    assert rel == pytest.approx(low.local_angles()[low.index("neck")], abs=1e-9)


def test_mapping_tables_name_real_bvh_joints(motions):
    for table, name in ((FAIR1_MAPPING, "dab"), (CMU1_MAPPING, "jumping_jacks"),
                        (ROKOKO_MAPPING, "jesse_dance")):
        for a, b in table.values():
            motions[name].joint_index(a)
            motions[name].joint_index(b)


def test_keyframe_poses(real_data, motions):
    kp = keyframe_poses("char1", "jumping_jacks", 10, 40, n_inbetweens=9)
    assert isinstance(kp, KeyframePoses)
    assert len(kp.inbetweens) == 9
    np.testing.assert_allclose(kp.frames, np.linspace(10, 40, 11))
    sk = load_character("char1")
    full = bvh_to_skeletons(motions["jumping_jacks"], sk, frames=[10, 40])
    np.testing.assert_array_equal(kp.key0.xy, full[0].xy)
    np.testing.assert_array_equal(kp.key1.xy, full[1].xy)
    seq = np.stack([kp.key0.xy] + [s.xy for s in kp.inbetweens] + [kp.key1.xy])
    assert np.all(np.abs(np.diff(seq, axis=0)).max(axis=(1, 2)) > 0)   # every step moves
    for s in kp.inbetweens:
        np.testing.assert_allclose(s.bone_lengths(), sk.bone_lengths(), rtol=0, atol=1e-9)
    # named motions start where AnimatedDrawings starts them
    kp = keyframe_poses("char2", "jumping", 200, 260, n_inbetweens=0)
    assert kp.inbetweens == [] and len(kp.frames) == 2


# ----------------------------------------------------------------------------- joint depths
def test_tiny_depths_hand_swung_forward_is_nearer():
    """The left arm swung forward (Yrotation −90: the hand at +z, the actor's front) puts the
    left hand 1 unit nearer the front camera (depth −1), every other joint at the root's
    depth 0; the side camera (at the actor's left) sees the left arm 1 unit nearer than the
    root and the right hand 2 units farther."""
    m = tiny_motion([{}, {"LeftArm": {"Yrotation": -90.0}}])
    sk = tiny_drawing()
    d = bvh_joint_depths(m, sk, TINY_MAPPING)
    assert d.shape == (2, len(sk))
    np.testing.assert_allclose(d[0], 0.0, atol=1e-12)                # T-pose: a flat actor
    want = np.zeros(len(sk))
    want[sk.index("left_hand")] = -1.0
    np.testing.assert_allclose(d[1], want, atol=1e-9)
    side = bvh_joint_depths(m, sk, TINY_MAPPING, view="side")[1]
    assert side[sk.index("left_hand")] == pytest.approx(-1.0)
    assert side[sk.index("right_hand")] == pytest.approx(2.0)


def test_tiny_depths_invariant_to_turning():
    pose = {"LeftArm": {"Yrotation": -60.0}, "RightArm": {"Zrotation": -30.0}}
    sk = tiny_drawing()
    base = bvh_joint_depths(tiny_motion([{}, pose]), sk, TINY_MAPPING)[1]
    turned = bvh_joint_depths(tiny_motion([{}, {**pose, "Hips": {"Yrotation": 70.0}}]), sk,
                              TINY_MAPPING)[1]
    np.testing.assert_allclose(turned, base, atol=1e-9)


def test_depths_bad_view_names_the_argument():
    m = tiny_motion([{}])
    with pytest.raises(ValueError, match="view must be one of"):
        bvh_joint_depths(m, tiny_drawing(), TINY_MAPPING, view="auto")
