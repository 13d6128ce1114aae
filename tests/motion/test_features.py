"""Tests of physlab.motion.features: feature layout, canonicalisation, exact inverse, stats.

Real clips: Bandai-Namco-Research-Motiondataset (CC BY-NC 4.0, © 2022 Bandai Namco Research
Inc.), read from the external data folder (``real_data`` fixture).
"""
import itertools
import subprocess
import sys

import numpy as np
import pytest

from physlab.motion import features as F
from physlab.motion.features import (CONTACTS, FEATURE_DIM, FEATURE_GROUPS, LOCAL_VEL, RIC,
                                     ROOT_LIN_VEL, FeatureStats, canonicalize, foot_contacts,
                                     features_to_joints, joints_to_features, root_heading)
from physlab.motion.skeleton import FOOT_JOINTS, JOINT_NAMES

# Approximate SMPL rest pose (m), y up, facing +z, the person's left = +x.
TEMPLATE = np.array([
    [0.00, 0.95, 0.00], [0.08, 0.87, 0.00], [-0.08, 0.87, 0.00], [0.00, 1.05, 0.00],
    [0.09, 0.50, 0.00], [-0.09, 0.50, 0.00], [0.00, 1.18, 0.00], [0.09, 0.08, -0.03],
    [-0.09, 0.08, -0.03], [0.00, 1.25, 0.00], [0.10, 0.02, 0.10], [-0.10, 0.02, 0.10],
    [0.00, 1.45, 0.00], [0.07, 1.38, 0.00], [-0.07, 1.38, 0.00], [0.00, 1.60, 0.02],
    [0.17, 1.40, 0.00], [-0.17, 1.40, 0.00], [0.43, 1.40, 0.00], [-0.43, 1.40, 0.00],
    [0.68, 1.40, 0.00], [-0.68, 1.40, 0.00],
])

BANDAI_CLIPS = ["dataset-2_walk_normal_001", "dataset-2_walk-turn-left_normal_001"]


def rot_y(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def synthetic_motion(T=40, seed=0, heading0=0.7, turn=0.05, start=(1.0, -2.0)):
    """A wiggling body walking along a curve while turning: (T, 22, 3)."""
    rng = np.random.default_rng(seed)
    t = np.arange(T)[:, None, None]
    wiggle = 0.03 * np.sin(0.3 * t + rng.uniform(0, 2 * np.pi, (1, 22, 3)))
    theta = heading0 + turn * np.arange(T) + 0.05 * np.sin(0.2 * np.arange(T))
    body = TEMPLATE + wiggle                                                  # (T, 22, 3)
    x = np.einsum("tab,tjb->tja", np.stack([rot_y(a) for a in theta]), body)
    path = np.stack([start[0] + 0.04 * np.arange(T) + 0.1 * np.sin(0.1 * np.arange(T)),
                     0.02 * np.sin(0.5 * np.arange(T)),
                     start[1] + 0.03 * np.arange(T)], axis=1)
    return x + path[:, None]


@pytest.fixture(scope="module")
def bandai(real_data, tmp_path_factory):
    from physlab.motion.dataset import load_clips

    return load_clips(real_data / "mocap" / "bandai_namco", clip_ids=BANDAI_CLIPS,
                      cache_dir=tmp_path_factory.mktemp("cache"))


# ----------------------------------------------------------------------------- layout


def test_feature_layout_is_contiguous():
    assert FEATURE_DIM == 137 == 4 + 21 * 3 + 22 * 3 + 4
    slices = list(FEATURE_GROUPS.values())
    assert slices[0].start == 0 and slices[-1].stop == FEATURE_DIM
    for a, b in itertools.pairwise(slices):
        assert a.stop == b.start
    assert (RIC.stop - RIC.start, LOCAL_VEL.stop - LOCAL_VEL.start) == (63, 66)
    assert [JOINT_NAMES[j] for j in F.CONTACT_JOINTS] == ["left_ankle", "left_foot",
                                                         "right_ankle", "right_foot"]
    assert set(F.STD_FLOORS) == set(FEATURE_GROUPS)


def test_import_does_not_pull_torch():
    code = ("import sys; import physlab.motion.features, physlab.motion.dataset, "
            "physlab.motion.metrics; assert 'torch' not in sys.modules, 'torch imported'")
    subprocess.run([sys.executable, "-c", code], check=True)


# ----------------------------------------------------------------------------- heading


@pytest.mark.parametrize("a", [0.0, 0.5, -2.0, np.pi - 1e-9])
def test_root_heading_analytic(a):
    x = np.einsum("ab,jb->ja", rot_y(a), TEMPLATE)[None]
    assert root_heading(TEMPLATE[None])[0] == pytest.approx(0.0, abs=1e-15)
    assert root_heading(x)[0] == pytest.approx(a, abs=1e-12)


def test_root_heading_degenerate_raises():
    x = np.repeat(TEMPLATE[None], 2, axis=0)
    x[1, list(F.FACE_JOINTS), 0] = 0.0                # hips and shoulders on one vertical line
    x[1, list(F.FACE_JOINTS), 2] = 0.0
    with pytest.raises(ValueError, match=r"frames \[1\]"):
        root_heading(x)


# ----------------------------------------------------------------------------- canonicalize


def test_canonicalize_puts_first_frame_at_origin_facing_z():
    x = synthetic_motion()
    c, theta0, offset = canonicalize(x, return_transform=True)
    np.testing.assert_allclose(c[0, 0, [0, 2]], 0.0, atol=1e-12)
    assert root_heading(c)[0] == pytest.approx(0.0, abs=1e-12)
    assert c[:, list(FOOT_JOINTS), 1].min() == pytest.approx(0.0, abs=1e-12)
    # the transform undoes it
    np.testing.assert_allclose(np.einsum("ab,tjb->tja", rot_y(theta0), c) + offset, x,
                               atol=1e-12)
    # ground=False keeps the heights
    np.testing.assert_allclose(canonicalize(x, ground=False)[..., 1], x[..., 1], atol=1e-12)


def test_canonicalize_is_invariant_to_yaw_and_translation():
    x = synthetic_motion()
    moved = np.einsum("ab,tjb->tja", rot_y(2.5), x) + np.array([3.0, 0.4, -7.0])
    np.testing.assert_allclose(canonicalize(moved), canonicalize(x), atol=1e-12)


# ----------------------------------------------------------------------------- features


def test_features_of_straight_walk_analytic():
    """A rigid body gliding at 3 cm/frame along +z while facing +z."""
    T, v = 6, 0.03
    x = TEMPLATE[None] + np.arange(T)[:, None, None] * np.array([0.0, 0.0, v])
    f = joints_to_features(x)
    assert f.shape == (T - 1, FEATURE_DIM)
    np.testing.assert_allclose(f[:, 0], 0.0, atol=1e-15)
    np.testing.assert_allclose(f[:, ROOT_LIN_VEL], np.tile([0.0, v], (T - 1, 1)), atol=1e-15)
    np.testing.assert_allclose(f[:, 3], 0.95)
    ric = TEMPLATE[1:] - TEMPLATE[0] * np.array([1, 0, 1])
    np.testing.assert_allclose(f[:, RIC], np.tile(ric.ravel(), (T - 1, 1)), atol=1e-12)
    np.testing.assert_allclose(f[:, LOCAL_VEL].reshape(T - 1, 22, 3),
                               np.broadcast_to([0.0, 0.0, v], (T - 1, 22, 3)), atol=1e-15)
    # 3 cm/frame = 0.6 m/s > 0.5 m/s: no contact though the toes are low
    np.testing.assert_array_equal(f[:, CONTACTS], 0.0)


def test_features_of_turn_in_place_and_wrap():
    """Turning in place by 0.3 rad/frame through the +-pi seam: a constant angular velocity."""
    T, w = 25, 0.3
    x = np.stack([np.einsum("ab,jb->ja", rot_y(2.0 + w * t), TEMPLATE) for t in range(T)])
    f = joints_to_features(x)
    np.testing.assert_allclose(f[:, 0], w, atol=1e-12)
    np.testing.assert_allclose(f[:, ROOT_LIN_VEL], 0.0, atol=1e-12)
    # ric is the template in every frame: turning does not change root-relative coordinates
    np.testing.assert_allclose(f[:, RIC], f[:1, RIC].repeat(T - 1, axis=0), atol=1e-12)
    back = features_to_joints(f, initial_heading=2.0)
    np.testing.assert_allclose(back, x, atol=1e-12)


def test_foot_contacts_analytic():
    T = 5
    x = np.repeat(TEMPLATE[None], T, axis=0)
    x[:, 8, 1] = 0.20                                     # right ankle lifted: no contact
    x[:, 11, 2] += 0.04 * np.arange(T)                    # right toes slide 0.8 m/s: no contact
    c = foot_contacts(x, fps=20)
    np.testing.assert_array_equal(c, np.tile([1.0, 1.0, 0.0, 0.0], (T - 1, 1)))
    # at 10 fps the toes move 0.4 m/s < 0.5 m/s: contact again
    np.testing.assert_array_equal(foot_contacts(x, fps=10)[:, 3], 1.0)


def test_round_trip_synthetic_exact():
    x = synthetic_motion(T=40)
    c = canonicalize(x)
    f = joints_to_features(c)
    np.testing.assert_allclose(features_to_joints(f), c, atol=1e-12)
    np.testing.assert_allclose(features_to_joints(f, include_last=False), c[:-1], atol=1e-12)
    # a non-canonical motion comes back given its initial heading and pelvis
    back = features_to_joints(joints_to_features(x), initial_heading=root_heading(x)[0],
                              initial_root_xz=x[0, 0, [0, 2]])
    np.testing.assert_allclose(back, x, atol=1e-12)


def test_features_are_invariant_to_yaw_and_horizontal_translation():
    x = synthetic_motion(T=30, seed=3)
    moved = np.einsum("ab,tjb->tja", rot_y(-1.2), x) + np.array([5.0, 0.0, 2.0])
    np.testing.assert_allclose(joints_to_features(moved), joints_to_features(x), atol=1e-12)


@pytest.mark.parametrize("bad, message", [
    (np.zeros((10, 21, 3)), r"shape \(T, 22, 3\)"),
    (np.zeros((1, 22, 3)), "at least 2 frames"),
    (np.full((3, 22, 3), np.nan), "NaN"),
])
def test_joints_to_features_rejects_bad_input(bad, message):
    with pytest.raises(ValueError, match=message):
        joints_to_features(bad)


def test_features_to_joints_rejects_bad_input():
    with pytest.raises(ValueError, match=r"shape \(T-1, 137\)"):
        features_to_joints(np.zeros((5, 263)))
    with pytest.raises(ValueError, match="no rows"):
        features_to_joints(np.zeros((0, FEATURE_DIM)))
    f = np.zeros((3, FEATURE_DIM))
    f[1, 5] = np.inf
    with pytest.raises(ValueError, match=r"rows \[1\]"):
        features_to_joints(f)


# ----------------------------------------------------------------------------- stats


def test_feature_stats_normalise_floors_and_save(tmp_path):
    feats = np.stack([joints_to_features(canonicalize(synthetic_motion(T=20, seed=s)))
                      for s in range(4)])                                   # (4, 19, D)
    stats = FeatureStats.from_features(feats)
    z = stats.normalize(feats)
    np.testing.assert_allclose(stats.denormalize(z), feats, atol=1e-12)
    # the body glides at > 0.8 m/s, so no contact ever fires: a constant column gets its
    # group's floor instead of a zero std
    const = feats.reshape(-1, FEATURE_DIM).std(axis=0) == 0
    assert const[CONTACTS].any()
    for name, s in FEATURE_GROUPS.items():
        assert np.all(stats.std[s] >= F.STD_FLOORS[name])
    np.testing.assert_allclose(stats.std[CONTACTS][const[CONTACTS]], F.STD_FLOORS["contacts"])
    varying = ~const & (feats.reshape(-1, FEATURE_DIM).std(axis=0) > 0.1)
    np.testing.assert_allclose(z.reshape(-1, FEATURE_DIM)[:, varying].std(axis=0), 1.0)
    # list input and custom floors
    s2 = FeatureStats.from_features(list(feats), floors={"contacts": 0.5})
    np.testing.assert_allclose(s2.std[CONTACTS][const[CONTACTS]], 0.5)
    # save / load
    path = stats.save(tmp_path / "stats" / "bandai.npz")
    loaded = FeatureStats.load(path)
    np.testing.assert_array_equal(loaded.mean, stats.mean)
    np.testing.assert_array_equal(loaded.std, stats.std)
    assert not list((tmp_path / "stats").glob(".*"))                  # no temp file left


def test_feature_stats_errors(tmp_path):
    with pytest.raises(ValueError, match=r"shape \(..., 137\)"):
        FeatureStats.from_features(np.zeros((5, 10)))
    with pytest.raises(ValueError, match="at least 2"):
        FeatureStats.from_features(np.zeros((1, FEATURE_DIM)))
    with pytest.raises(ValueError, match="unknown feature groups"):
        FeatureStats.from_features(np.zeros((3, FEATURE_DIM)), floors={"rotations": 1.0})
    with pytest.raises(ValueError, match="std > 0"):
        FeatureStats(mean=np.zeros(3), std=np.array([1.0, 0.0, 1.0]))
    stats = FeatureStats(mean=np.zeros(FEATURE_DIM), std=np.ones(FEATURE_DIM))
    with pytest.raises(ValueError, match=r"shape \(..., 137\)"):
        stats.normalize(np.zeros((2, 3)))
    with pytest.raises(FileNotFoundError, match="from_features"):
        FeatureStats.load(tmp_path / "missing.npz")


# ----------------------------------------------------------------------------- real data


def test_real_windows_round_trip(bandai):
    from physlab.motion.dataset import make_windows

    w = make_windows(bandai, length=40, stride=20)
    feats = np.stack([joints_to_features(x) for x in w.joints])              # (N, 39, D)
    assert feats.shape[1:] == (39, FEATURE_DIM)
    back = np.stack([features_to_joints(f) for f in feats])
    err = np.abs(back - w.joints).max()
    assert err < 1e-9                                                    # measured ~4e-15 m
    # the contacts fire for about half the frames of walking (stance phases)
    walk = [k for k, c in enumerate(w.content) if c == "walk"]
    assert 0.3 < feats[walk][..., CONTACTS].mean() < 0.7


def test_real_walk_faces_and_moves_forward(bandai):
    walk = next(c for c in bandai if c.content == "walk")
    c = canonicalize(walk.joints[:40])
    step = c[-1, 0] - c[0, 0]
    assert step[2] > 1.0 and abs(step[0]) < 0.3 * step[2]     # walks along +z, the facing


def test_real_turn_left_heading_reference(bandai):
    """walk-turn-left turns left (positive yaw about +y) by a measured 102.4 degrees."""
    turn = next(c for c in bandai if c.content == "walk-turn-left")
    f = joints_to_features(turn.joints)
    assert np.degrees(f[:, 0].sum()) == pytest.approx(102.43, abs=0.05)


# ----------------------------------------------------------------------------- absolute


def test_absolute_features_round_trip_and_layout():
    x = synthetic_motion(T=40)
    f = F.joints_to_absolute_features(x)
    assert f.shape == (40, F.ABS_FEATURE_DIM) == (40, 70)
    np.testing.assert_array_equal(f[:, F.ABS_PELVIS], x[:, 0])
    np.testing.assert_allclose(f[:, F.ABS_BODY].reshape(40, 21, 3), x[:, 1:] - x[:, :1])
    np.testing.assert_allclose(F.absolute_features_to_joints(f), x, atol=1e-12)
    # contacts: the relative rows' contacts, the last frame repeating the one before
    c = F.foot_contacts(x)
    np.testing.assert_array_equal(f[:-1, F.ABS_CONTACTS], c)
    np.testing.assert_array_equal(f[-1, F.ABS_CONTACTS], c[-1])
    # a joint at frame i depends on row i only (the point of the representation)
    g = f.copy()
    g[7] += 1.0
    d = np.abs(F.absolute_features_to_joints(g) - x).max(axis=(1, 2))
    assert d[7] > 0.5 and np.all(np.delete(d, 7) < 1e-12)


def test_encode_decode_dispatch_and_stats():
    c = canonicalize(synthetic_motion(T=40))
    for rep, shape in (("relative", (39, 137)), ("absolute", (40, 70))):
        f = F.encode_motion(c, rep)
        assert f.shape == shape and F.REPRESENTATIONS[rep] == (shape[1], shape[0] - 40)
        np.testing.assert_allclose(F.decode_motion(f, rep), c, atol=1e-12)
    f = np.stack([F.encode_motion(canonicalize(synthetic_motion(seed=s)), "absolute")
                  for s in range(4)])
    st = F.FeatureStats.from_features(f, representation="absolute")
    assert st.mean.shape == (70,) and np.all(st.std >= F.ABS_STD_FLOORS["body"])
    np.testing.assert_allclose(st.denormalize(st.normalize(f)), f, atol=1e-12)
    with pytest.raises(ValueError, match="representation must be one of"):
        F.encode_motion(c, "global")
    with pytest.raises(ValueError, match=r"shape \(\.\.\., 70\)"):
        F.FeatureStats.from_features(np.zeros((5, 137)), representation="absolute")
    with pytest.raises(ValueError, match="unknown feature groups"):
        F.FeatureStats.from_features(f, floors={"ric": 1.0}, representation="absolute")
    with pytest.raises(ValueError, match=r"shape \(T, 70\)"):
        F.absolute_features_to_joints(np.zeros((3, 69)))
    with pytest.raises(ValueError, match="NaN"):
        F.absolute_features_to_joints(np.full((3, 70), np.nan))
