"""Tests of physlab.motion.metrics: foot skating, MPJPE, trajectory error, jerk (AUJ / PJ).

Real clips: Bandai-Namco-Research-Motiondataset (CC BY-NC 4.0, © 2022 Bandai Namco Research
Inc.), read from the external data folder (``real_data`` fixture).
"""
import numpy as np
import pytest

from physlab.motion.dataset import (TRAJECTORY_JOINTS, condition_from_window, load_clips,
                                    make_windows)
from physlab.motion.metrics import (HUMANML3D_GT_PEAK_JERK, foot_skating_ratio, jerk,
                                    jerk_curve, mpjpe, trajectory_error)

CLIPS = ["dataset-1_walk_normal_001", "dataset-2_walk_normal_001", "dataset-1_bow_happy_001"]


def _still(T=30, seed=0):
    """A static random pose with both toes (10, 11) on the ground: (T, 22, 3)."""
    rng = np.random.default_rng(seed)
    pose = rng.uniform(-0.3, 0.3, (22, 3)) + np.array([0.0, 1.0, 0.0])
    pose[[10, 11], 1] = 0.0
    return np.repeat(pose[None], T, axis=0)


def _rot_y(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


@pytest.fixture(scope="module")
def clips(real_data, tmp_path_factory):
    return load_clips(real_data / "mocap" / "bandai_namco", clip_ids=CLIPS,
                      cache_dir=tmp_path_factory.mktemp("cache"))


# ----------------------------------------------------------------------------- skating


def test_skating_analytic():
    T = 30
    x = _still(T)
    assert foot_skating_ratio(x) == 0.0                       # a still foot never skates
    slide = x.copy()
    slide[:, 10, 0] += 0.05 * np.arange(T)                    # 5 cm/frame = 1 m/s on the ground
    assert foot_skating_ratio(slide) == 1.0
    lifted = slide.copy()
    lifted[:, 10, 1] = 0.06                                   # above 5 cm: swinging, not skating
    assert foot_skating_ratio(lifted) == 0.0
    vertical = x.copy()
    vertical[:, 11, 1] = 0.04 * np.abs(np.sin(np.arange(T)))  # fast but only vertical
    assert foot_skating_ratio(vertical) == 0.0


def test_skating_window_edges_reference():
    """At 0.6 m/s the zero-padded 5-frame average is 0.36 / 0.48 m/s at the two first and
    last frame pairs, below 0.5 m/s, so 4 of the T-1 pairs do not count (GMD semantics)."""
    T = 30
    x = _still(T)
    x[:, 11, 2] += 0.03 * np.arange(T)                        # 3 cm/frame = 0.6 m/s
    assert foot_skating_ratio(x) == pytest.approx((T - 1 - 4) / (T - 1))
    # at 10 fps the same displacement is 0.3 m/s: below the threshold
    assert foot_skating_ratio(x, fps=10) == 0.0
    assert foot_skating_ratio(x, vel_thresh=0.2, window=1) == 1.0


def test_skating_batch_and_yaw_invariance():
    x = _still(20)
    slide = x.copy()
    slide[:, 10, [0, 2]] += 0.04 * np.arange(20)[:, None]
    turned = np.einsum("ab,tjb->tja", _rot_y(1.1), slide) + np.array([2.0, 0.0, -1.0])
    r = foot_skating_ratio(np.stack([x, slide, turned]))
    assert r.shape == (3,)
    assert r[0] == 0.0 and r[1] == r[2] > 0.8


def test_skating_errors():
    with pytest.raises(ValueError, match="at least 2 frames"):
        foot_skating_ratio(np.zeros((1, 22, 3)))
    with pytest.raises(ValueError, match="fps"):
        foot_skating_ratio(np.zeros((4, 22, 3)), fps=0)
    with pytest.raises(ValueError, match=r"shape \(T, J, 3\)"):
        foot_skating_ratio(np.zeros((4, 22)))


def test_skating_real(clips):
    """GMD's ratio on real mocap. Measured: walks 0.186 (dataset-1) and 0.232 (dataset-2),
    bow 0.0. Walks are not 0: in late swing the Bandai toe joint passes 3 cm above the ground
    at 3-4 m/s, which the metric counts (HumanML3D's ground truth also scores ~0.05-0.075,
    GMD issue #8, OmniControl issue #22). Sliding the whole body at 1 m/s gives 1.0."""
    r = {c.clip_id: foot_skating_ratio(c.joints) for c in clips}
    assert r["dataset-1_walk_normal_001"] == pytest.approx(0.186, abs=0.005)
    assert r["dataset-2_walk_normal_001"] == pytest.approx(0.232, abs=0.005)
    assert r["dataset-1_bow_happy_001"] == 0.0
    walk = clips[1].joints
    drift = walk + np.arange(len(walk))[:, None, None] * np.array([0.05, 0.0, 0.0])
    assert foot_skating_ratio(drift) == 1.0


# ----------------------------------------------------------------------------- mpjpe


def test_mpjpe_translation_is_its_norm():
    pose = _still(1)[0]
    t = np.array([0.03, -0.04, 0.0])
    assert mpjpe(pose + t, pose) == pytest.approx(0.05)
    assert mpjpe(pose + t, pose, root_relative=True) == pytest.approx(0.0, abs=1e-15)
    motion = _still(10)
    pred = motion.copy()
    pred[4] += t
    assert mpjpe(pred, motion, frames=4) == pytest.approx(0.05)
    assert mpjpe(pred, motion, frames=[3, 4]) == pytest.approx(0.025)
    assert mpjpe(pred, motion) == pytest.approx(0.005)
    assert mpjpe(pred[None], motion[None], frames=-6) == pytest.approx(0.05)   # batched


def test_mpjpe_xz_keeps_heights():
    """root_relative="xz" ignores where the pose stands on the floor, not how high it is."""
    pose = _still(1)[0]
    assert mpjpe(pose + [0.3, 0.0, -0.4], pose, root_relative="xz") == pytest.approx(0, abs=1e-15)
    assert mpjpe(pose + [0.3, 0.02, -0.4], pose, root_relative="xz") == pytest.approx(0.02)
    bent = pose.copy()
    bent[5] += [0.0, 0.0, 0.22]                                     # one joint of 22 moved
    assert mpjpe(bent + [1.0, 0.0, 1.0], pose, root_relative="xz") == pytest.approx(0.01)
    with pytest.raises(ValueError, match="root_relative"):
        mpjpe(pose, pose, root_relative="y")


def test_mpjpe_errors():
    with pytest.raises(ValueError, match="same shape"):
        mpjpe(np.zeros((22, 3)), np.zeros((21, 3)))
    with pytest.raises(ValueError, match="out of range"):
        mpjpe(np.zeros((5, 22, 3)), np.zeros((5, 22, 3)), frames=5)
    with pytest.raises(ValueError, match="NaN"):
        mpjpe(np.full((22, 3), np.nan), np.zeros((22, 3)))


# ----------------------------------------------------------------------------- trajectory


def test_trajectory_error_only_counts_controlled_frames():
    gt = _still(40, 1)
    cond = condition_from_window(gt, t_r=10, keypose_at="first", joints=("pelvis", "head"))
    pred = gt + 5.0                                          # far off everywhere ...
    pred[:10, [0, 15]] = gt[:10, [0, 15]] + np.array([0.0, 0.0, 0.02])   # ... but controlled
    assert trajectory_error(pred, cond.trajectory, TRAJECTORY_JOINTS, cond.mask) == \
        pytest.approx(0.02)
    # the same with full gt joints and a (T, K) mask of only the controlled joints
    assert trajectory_error(pred, gt, ["pelvis", "head"], cond.mask[:, [0, 3]]) == \
        pytest.approx(0.02)
    batch = trajectory_error(np.stack([pred, pred]), cond.trajectory, TRAJECTORY_JOINTS,
                             cond.mask)
    assert batch == pytest.approx(0.02)


def test_trajectory_error_errors():
    x = _still(10)
    with pytest.raises(ValueError, match="selects no frame"):
        trajectory_error(x, x, [0], np.zeros((10, 1), bool))
    with pytest.raises(ValueError, match="unknown joint 'tail'"):
        trajectory_error(x, x, ["tail"], np.ones((10, 1), bool))
    with pytest.raises(ValueError, match="gt has 5 joints"):
        trajectory_error(x, np.zeros((10, 5, 3)), [0, 1], np.ones((10, 2), bool))
    with pytest.raises(ValueError, match="do not match"):
        trajectory_error(x, x, [0], np.ones((9, 1), bool))


# ----------------------------------------------------------------------------- jerk


def test_jerk_of_constant_velocity_is_zero():
    x = _still(20) + np.arange(20)[:, None, None] * np.array([0.01, 0.02, -0.03])
    np.testing.assert_allclose(jerk_curve(x), 0.0, atol=1e-14)
    auj, pj = jerk(x)
    assert auj == pytest.approx(0.0, abs=1e-12) and pj == pytest.approx(0.0, abs=1e-14)


def test_jerk_of_cubic_reference():
    """x(t) = a t^3 (t in frames) has third difference 6 a; with y(t) = b t^3 as well the L1
    norm is 6 (a + b); with fps, x = c tau^3 (tau in s) has jerk 6 c m/s^3."""
    T, a, b = 12, 1e-3, 2e-3
    t = np.arange(T, dtype=float)
    x = _still(T)
    x[:, 20, 0] += a * t ** 3
    x[:, 20, 1] += b * t ** 3
    np.testing.assert_allclose(jerk_curve(x), 6 * (a + b), rtol=1e-9)
    auj, pj = jerk(x)
    assert pj == pytest.approx(0.018) and auj == pytest.approx(0.018 * (T - 3))
    auj_ref, _ = jerk(x, reference=0.01)
    assert auj_ref == pytest.approx(0.008 * (T - 3))
    fps, c = 20.0, 0.7
    y = _still(T)
    y[:, 3, 2] += c * (t / fps) ** 3
    np.testing.assert_allclose(jerk_curve(y, fps=fps), 6 * c, rtol=1e-9)
    auj_s, pj_s = jerk(y, fps=fps)
    assert pj_s == pytest.approx(4.2) and auj_s == pytest.approx(4.2 * (T - 3) / fps)


def test_jerk_batch_averages_curves_first():
    T = 10
    x, y = _still(T), _still(T)
    x[5:, 0, 0] += 0.1                                        # a step at frame 5 in one motion
    cx = jerk_curve(x)
    auj, pj = jerk(np.stack([x, y]))
    assert pj == pytest.approx(cx.max() / 2) and auj == pytest.approx(cx.sum() / 2)
    with pytest.raises(ValueError, match="at least 4 frames"):
        jerk(np.zeros((3, 22, 3)))
    with pytest.raises(ValueError, match="fps"):
        jerk_curve(np.zeros((5, 22, 3)), fps=-1)


def test_jerk_real(clips):
    """FlowMDM's PJ / AUJ of a batch of real 40-frame windows (m / frame^3, 20 fps).
    Measured for the two walks (25 windows): PJ 0.068, AUJ 2.03 (reference 0) and 0.80
    (reference = HumanML3D's GT peak jerk 0.0330)."""
    w = make_windows([c for c in clips if c.content == "walk"])
    assert len(w) == 25
    auj, pj = jerk(w.joints)
    assert pj == pytest.approx(0.0676, abs=0.001) and auj == pytest.approx(2.026, abs=0.01)
    auj_gt, pj_gt = jerk(w.joints, reference=HUMANML3D_GT_PEAK_JERK)
    assert pj_gt == pj and auj_gt == pytest.approx(0.804, abs=0.01)


def test_mpjpe_and_trajectory_error_on_projected_2d_points():
    """The same definitions on (..., 2) image points: analytic offsets."""
    from physlab.motion.metrics import mpjpe, trajectory_error

    p = np.zeros((10, 22, 2))
    g = p + [0.3, 0.4]                                               # 0.5 everywhere
    assert mpjpe(p, g) == pytest.approx(0.5)
    assert mpjpe(p, g, root_relative=True) == pytest.approx(0.0)
    mask = np.zeros((10, 2), bool)
    mask[:4, 0] = True
    assert trajectory_error(p, g[:, [0, 15]], (0, 15), mask) == pytest.approx(0.5)
    with pytest.raises(ValueError, match="3D only"):
        mpjpe(p, g, root_relative="xz")
    with pytest.raises(ValueError, match=r"gt must have shape \(T, K, 2\)"):
        trajectory_error(p, np.zeros((10, 2, 3)), (0, 15), mask)
