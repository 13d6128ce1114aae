"""Tests of physlab.motion.bvh: reading, writing and retargeting BVH clips.

Real clips come from the external data folder (``real_data`` fixture): Bandai-Namco Research
Motiondataset (CC BY-NC 4.0, © 2022 Bandai Namco Research Inc.), CMU mocap ("The data used in
this project was obtained from mocap.cs.cmu.edu. The database was created with funding from
NSF EIA-0196217.") and the AnimatedDrawings examples (MIT, © Meta Platforms, Inc.).
"""
import re

import numpy as np
import pytest

from physlab.motion import (BANDAI_NAMCO_MAPPING, CMU_MAPPING, CMU_MAX_MAPPING, JOINT_NAMES,
                            BVHMotion, bone_lengths, read_bvh, retarget_to_smpl22, write_bvh)
from physlab.motion.skeleton import FOOT_JOINTS, euler_to_matrix

BANDAI_WALK = ("mocap/bandai_namco/dataset/Bandai-Namco-Research-Motiondataset-1/data/"
               "dataset-1_walk_normal_001.bvh")
CMU_WALK = "mocap/cmu_small/02_01.bvh"            # MotionBuilder naming
CMU_MAX_WALK = "mocap/cmu_small/131_01.bvh"       # 3dsMax naming, ZXY arms, odd indentation
ANIMATED_DRAWINGS_BVH = ("cmu1/jumping_jacks.bvh", "fair1/dab.bvh", "fair1/jumping.bvh",
                         "fair1/wave_hello.bvh", "fair1/zombie.bvh", "rokoko/jesse_dance.bvh")
REAL_CLIPS = (BANDAI_WALK, CMU_WALK, CMU_MAX_WALK) + tuple(
    f"animated_drawings/examples/bvh/{f}" for f in ANIMATED_DRAWINGS_BVH)

# A two-joint arm (root with 6 channels, child with 3, end site) in a tidy layout.
SMALL_BVH = """HIERARCHY
ROOT Hips
{
\tOFFSET 0 0 0
\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
\tJOINT Arm
\t{
\t\tOFFSET 0 2 0
\t\tCHANNELS 3 Xrotation Yrotation Zrotation
\t\tEnd Site
\t\t{
\t\t\tOFFSET 1 0 0
\t\t}
\t}
}
MOTION
Frames: 2
Frame Time: 0.05
0 0 0 0 0 0 0 0 0
1 2 3 90 0 0 0 0 90
"""

# The same file with braces on the keyword lines, CRLF, odd spacing and lower-case keywords.
MESSY_BVH = ("hierarchy\r\nROOT Hips {\r\n  offset 0   0 0\r\n channels 6 XPOSITION Yposition "
             "Zposition zrotation Xrotation Yrotation\r\n\r\n JOINT Arm{ OFFSET 0 2 0\r\n"
             "CHANNELS 3 Xrotation Yrotation Zrotation\r\n end site { OFFSET 1 0 0 } } }\r\n"
             "MOTION\r\nFrames:\t2\r\nFrame   Time:  0.05\r\n\r\n0 0 0 0 0 0 0 0 0\r\n"
             "  1\t2 3 90 0 0 0 0 90  \r\n\r\n")


def _write(tmp_path, text, name="clip.bvh"):
    p = tmp_path / name
    p.write_bytes(text.encode())
    return p


def _header_counts(path):
    """(frames, joints, end sites) counted from the raw text, independently of read_bvh."""
    text = path.read_text()
    joints = len(re.findall(r"^\s*(?:ROOT|JOINT)\s", text, flags=re.M))
    ends = len(re.findall(r"^\s*End\s+Site", text, flags=re.M))
    frames = int(re.search(r"^\s*Frames:\s*(\d+)", text, flags=re.M).group(1))
    return frames, joints, ends


def _assert_same(a, b, atol=1e-6):
    assert a.names == b.names
    np.testing.assert_array_equal(a.parents, b.parents)
    assert a.channels == b.channels
    np.testing.assert_allclose(a.offsets, b.offsets, atol=atol)
    np.testing.assert_allclose(a.motion, b.motion, atol=atol)
    assert a.frame_time == pytest.approx(b.frame_time, abs=1e-9)


# ----------------------------------------------------------------------------- synthetic


def test_read_small_bvh_analytic(tmp_path):
    m = read_bvh(_write(tmp_path, SMALL_BVH))
    assert m.names == ["Hips", "Arm", "Arm_End"]
    np.testing.assert_array_equal(m.parents, [-1, 0, 1])
    assert m.channels[2] == [] and m.n_frames == 2 and m.n_joints == 3
    assert m.fps == pytest.approx(20.0) and m.duration == pytest.approx(0.05)
    np.testing.assert_allclose(m.root_positions(), [[0, 0, 0], [1, 2, 3]])
    x = m.joint_positions()
    np.testing.assert_allclose(x[0], [[0, 0, 0], [0, 2, 0], [1, 2, 0]], atol=1e-12)
    # frame 1: root at (1,2,3) turned 90° about z: the arm offset (0,2,0) -> (-2,0,0); the arm
    # turns a further 90° about z, so the end site (1,0,0) -> Rz180 (1,0,0) = (-1,0,0)
    np.testing.assert_allclose(x[1], [[1, 2, 3], [-1, 2, 3], [-2, 2, 3]], atol=1e-12)
    np.testing.assert_allclose(m.joint_positions(scale=0.01), 0.01 * x)
    R = m.rotations()
    np.testing.assert_allclose(R[1, 0], euler_to_matrix([90, 0, 0], "ZXY"), atol=1e-15)
    np.testing.assert_allclose(R[1, 1], euler_to_matrix([0, 0, 90], "XYZ"), atol=1e-15)
    np.testing.assert_allclose(R[:, 2], np.broadcast_to(np.eye(3), (2, 3, 3)))
    dropped = read_bvh(_write(tmp_path, SMALL_BVH), end_sites=False)
    assert dropped.names == ["Hips", "Arm"]
    np.testing.assert_allclose(dropped.joint_positions(), x[:, :2])


def test_whitespace_and_case_variations(tmp_path):
    a = read_bvh(_write(tmp_path, SMALL_BVH, "a.bvh"))
    b = read_bvh(_write(tmp_path, MESSY_BVH, "b.bvh"))
    _assert_same(a, b, atol=0)


def test_write_small_round_trip(tmp_path):
    m = read_bvh(_write(tmp_path, SMALL_BVH))
    out = write_bvh(tmp_path / "out.bvh", m)
    assert out.exists() and "End Site" in out.read_text()
    _assert_same(m, read_bvh(out), atol=1e-12)
    assert not list(tmp_path.glob(".*.tmp"))          # no temp file left behind
    dropped = read_bvh(_write(tmp_path, SMALL_BVH), end_sites=False)
    _assert_same(dropped, read_bvh(write_bvh(tmp_path / "dropped.bvh", dropped)), atol=1e-12)


@pytest.mark.parametrize("old, new, message", [
    ("\t\tOFFSET 0 2 0", "\t\tOFFSET 0 two 0", r"line 8: expected an OFFSET coordinate"),
    ("Xrotation Yrotation Zrotation", "Xrotation Yrotation Wrotation",
     r"line 9: unknown channel 'Wrotation'"),
    ("1 2 3 90 0 0 0 0 90", "1 2 3 90 0 0 0 0", r"line 20: expected 9 channel values"),
    ("1 2 3 90 0 0 0 0 90", "1 2 3 90 0 0 0 0 abc", r"line 20: 'abc' is not a number"),
    ("Frames: 2", "Frames: 3", r"line \d+: the file declares Frames: 3 but has 2"),
    ("Frame Time: 0.05", "Frame Time 0.05", r"line 18: expected 'Frame Time:"),
    ("\t\tOFFSET 0 2 0\n", "", r"line \d+: joint 'Arm' has no OFFSET"),
    ("\t}\n}\nMOTION", "\t}\n\tbogus\n}\nMOTION", r"line 15: unexpected 'bogus'"),
    ("MOTION", "MOTON", r"line \d+: no MOTION section"),
    ("HIERARCHY", "HIERARCHIES", r"line 1: expected 'HIERARCHY'"),
])
def test_malformed_bvh_raises_with_line_number(tmp_path, old, new, message):
    assert old in SMALL_BVH
    path = _write(tmp_path, SMALL_BVH.replace(old, new, 1))
    with pytest.raises(ValueError, match=message) as err:
        read_bvh(path)
    assert str(path) in str(err.value)


def test_bvhmotion_validates(tmp_path):
    m = read_bvh(_write(tmp_path, SMALL_BVH))
    with pytest.raises(ValueError, match="frame_time"):
        BVHMotion(m.names, m.parents, m.offsets, m.channels, 0.0, m.motion)
    with pytest.raises(ValueError, match="parents"):
        BVHMotion(m.names, [1, -1, 0], m.offsets, m.channels, 0.05, m.motion)
    with pytest.raises(ValueError, match="no joint 'Leg'"):
        m.joint_index("Leg")


def test_retarget_input_checks(tmp_path):
    m = read_bvh(_write(tmp_path, SMALL_BVH))
    mapping = {n: "Hips" for n in JOINT_NAMES}
    with pytest.raises(ValueError, match="scale"):
        retarget_to_smpl22(m, mapping)
    with pytest.raises(ValueError, match="lacks the SMPL joints head"):
        retarget_to_smpl22(m, {k: v for k, v in mapping.items() if k != "head"}, scale=1.0)
    with pytest.raises(ValueError, match="no joint 'Chest'"):
        retarget_to_smpl22(m, dict(mapping, spine2=("mid", "Hips", "Chest")), scale=1.0)
    x = retarget_to_smpl22(m, dict(mapping, left_wrist="Arm_End"), scale=0.5, fps=40)
    assert x.shape == (3, 22, 3)                     # 0.05 s at 40 fps: t = 0, 0.025, 0.05
    # feet are all mapped to Hips, lowest (y = 0) in frame 0, so no vertical shift
    np.testing.assert_allclose(x[2, 20], 0.5 * np.array([-2, 2, 3]), atol=1e-12)
    np.testing.assert_allclose(x[1, 0], 0.5 * np.array([0.5, 1, 1.5]), atol=1e-12)


# ----------------------------------------------------------------------------- real clips


@pytest.mark.parametrize("rel", REAL_CLIPS)
def test_real_clips_read_and_round_trip(real_data, tmp_path, rel):
    path = real_data / rel
    m = read_bvh(path)
    frames, joints, ends = _header_counts(path)
    assert m.n_frames == frames and m.motion.shape[0] == frames
    assert m.n_joints == joints + ends
    assert read_bvh(path, end_sites=False).n_joints == joints
    assert m.motion.shape[1] == sum(len(c) for c in m.channels)
    _assert_same(m, read_bvh(write_bvh(tmp_path / "copy.bvh", m)))
    # forward kinematics keeps bones rigid: each joint's distance to its parent is the norm of
    # its local translation (the OFFSET, or its position channels when it has them)
    x = m.joint_positions()
    b = bone_lengths(x, m.parents)
    child = np.flatnonzero(m.parents >= 0)
    np.testing.assert_allclose(b, np.linalg.norm(m.translations()[:, child], axis=-1),
                               atol=1e-9)
    no_pos = [k for k, j in enumerate(child) if not any("position" in c for c in m.channels[j])]
    np.testing.assert_allclose(b[:, no_pos], np.broadcast_to(
        np.linalg.norm(m.offsets[child[no_pos]], axis=1), (m.n_frames, len(no_pos))), atol=1e-9)


def test_bandai_translation_channels_equal_offsets(real_data):
    m = read_bvh(real_data / BANDAI_WALK)
    assert all(len(c) == 6 for c in m.channels if c)
    assert m.joint_index("Hips") == 1
    t = m.translations()
    # below Hips, the position channels repeat the offsets (rigid bones, cm)
    np.testing.assert_allclose(t[:, 2:], np.broadcast_to(m.offsets[2:], t[:, 2:].shape),
                               atol=1e-3)


def _check_smpl22(x, duration, fps=20):
    T = x.shape[0]
    assert x.shape == (T, 22, 3) and np.all(np.isfinite(x))
    assert abs(T - duration * fps) <= 1
    y = x[..., 1]
    feet = y[:, list(FOOT_JOINTS)]
    pelvis, head = y[:, JOINT_NAMES.index("pelvis")], y[:, JOINT_NAMES.index("head")]
    # y up, feet on the ground
    assert head.mean() > pelvis.mean() > feet.mean()
    assert abs(feet.min()) < 0.01
    # plausible adult size (metres). Measured: pelvis median 0.86 (Bandai), 1.02 (CMU 02_01),
    # 0.89 (CMU 131_01). The "head" joint of these skeletons is the skull base, so head above
    # the lowest foot joint is 1.33 (Bandai), 1.42 (CMU 02_01), 1.24-1.30 (CMU 131) m, below
    # SMPL's head-centre joint; hence the lower bound 1.2.
    assert 0.8 < np.median(pelvis) < 1.1
    assert 1.2 < np.median(head - feet.min(axis=1)) < 2.0
    # left is left: with y up and the toes pointing forward, left = up x forward
    i = {n: k for k, n in enumerate(JOINT_NAMES)}
    fwd = (x[:, i["left_foot"]] - x[:, i["left_ankle"]] + x[:, i["right_foot"]]
           - x[:, i["right_ankle"]])
    fwd[:, 1] = 0
    left = np.cross([0.0, 1.0, 0.0], fwd)
    left /= np.linalg.norm(left, axis=1, keepdims=True)
    hip = np.einsum("td,td->t", x[:, i["left_hip"]] - x[:, i["pelvis"]], left)
    shoulder = np.einsum("td,td->t", x[:, i["left_shoulder"]] - x[:, i["pelvis"]], left)
    assert np.sign(hip.mean()) == np.sign(shoulder.mean()) == 1
    assert np.mean(hip > 0) > 0.9
    # bones stay rigid after resampling
    assert np.ptp(bone_lengths(x), axis=0).max() < 1e-3
    assert bone_lengths(x).min() > 0.03           # and none collapses to a point
    return x


@pytest.mark.parametrize("rel, mapping", [(BANDAI_WALK, BANDAI_NAMCO_MAPPING),
                                          (CMU_WALK, CMU_MAPPING),
                                          (CMU_MAX_WALK, CMU_MAX_MAPPING)])
def test_retarget_walk_clips(real_data, rel, mapping):
    m = read_bvh(real_data / rel)
    x = _check_smpl22(retarget_to_smpl22(m, mapping), m.duration)
    # walking moves the pelvis horizontally by more than a metre
    assert np.linalg.norm(x[-1, 0, [0, 2]] - x[0, 0, [0, 2]]) > 1.0


def test_retarget_resampling_and_axes(real_data):
    m = read_bvh(real_data / BANDAI_WALK)
    x30 = retarget_to_smpl22(m, BANDAI_NAMCO_MAPPING, fps=m.fps)
    # at the file's own rate, the result is plain FK of the mapped joints (scaled, grounded)
    fk = 0.01 * m.joint_positions()
    np.testing.assert_allclose(x30[:, 0] - x30[0, 0], fk[:, m.joint_index("Hips")]
                               - fk[0, m.joint_index("Hips")], atol=1e-9)
    # 20 fps frames interpolate the 30 fps ones: frame 2 (t = 0.1 s) is frame 3 at 30 fps
    x20 = retarget_to_smpl22(m, BANDAI_NAMCO_MAPPING)
    np.testing.assert_allclose(x20[2], x30[3], atol=1e-4)
    # z-up input: (x, y, z) -> (x, z, -y) up to the vertical grounding shift
    xz = retarget_to_smpl22(m, BANDAI_NAMCO_MAPPING, y_up=False)
    np.testing.assert_allclose(xz[..., 0], x20[..., 0], atol=1e-12)
    np.testing.assert_allclose(xz[..., 1], x20[..., 2] - x20[..., 2].min()
                               + (x20[..., 2].min() - x20[:, list(FOOT_JOINTS), 2].min()),
                               atol=1e-12)
    c = xz[..., 2] + x20[..., 1]
    np.testing.assert_allclose(c, c.flat[0], atol=1e-12)
