"""Body constraints of generated clips (physlab.motion.body) and the body checks of
physlab.motion.metrics, against analytic cases."""
import numpy as np
import pytest

from physlab.motion import metrics as M
from physlab.motion.body import (LEG_CHAINS, clip_bone_lengths, constrain_body, foot_contacts,
                                 ground_feet, lock_feet, rigid_bones, two_bone_ik,
                                 FADE_STEP)
from physlab.motion.skeleton import FOOT_JOINTS, PARENTS, bone_lengths


def _clip(T=30, seed=0, stretch=0.0):
    """A rigid random-direction skeleton walking forward, optionally with bones stretched
    by up to ``stretch`` (relative) at random."""
    rng = np.random.default_rng(seed)
    L = rng.uniform(0.08, 0.4, len(PARENTS))
    dirs = rng.normal(size=(len(PARENTS), 3))
    dirs[:, 1] -= 1.5                                   # mostly pointing down from the pelvis
    x = np.zeros((T, len(PARENTS), 3))
    x[:, 0] = np.stack([np.zeros(T), np.full(T, 1.5), np.linspace(0, 2, T)], axis=1)
    for j in range(1, len(PARENTS)):
        d = dirs[j] + 0.2 * np.sin(np.arange(T)[:, None] * 0.3 + j)
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        s = 1 + stretch * rng.uniform(-1, 1, (T, 1))
        x[:, j] = x[:, PARENTS[j]] + L[j] * s * d
    L[0] = 0.0
    return x, L


def test_rigid_bones_sets_every_length_and_keeps_directions():
    x, L = _clip(stretch=0.3)
    y = rigid_bones(x, lengths=L)
    np.testing.assert_allclose(bone_lengths(y), np.broadcast_to(L[1:], (len(x), 21)), atol=1e-12)
    child = np.arange(1, 22)
    dx = x[:, child] - x[:, PARENTS[child]]
    dy = y[:, child] - y[:, PARENTS[child]]
    cos = (dx * dy).sum(-1) / np.linalg.norm(dx, axis=-1) / np.linalg.norm(dy, axis=-1)
    np.testing.assert_allclose(cos, 1.0, atol=1e-12)
    np.testing.assert_array_equal(y[:, 0], x[:, 0])                        # pelvis untouched


def test_rigid_bones_is_the_identity_on_a_rigid_clip_and_batches():
    x, L = _clip(stretch=0.0)
    np.testing.assert_allclose(rigid_bones(x), x, atol=1e-12)              # median lengths = L
    np.testing.assert_allclose(clip_bone_lengths(x), L, atol=1e-12)
    b = np.stack([_clip(stretch=0.2, seed=s)[0] for s in range(3)])
    np.testing.assert_allclose(rigid_bones(b), np.stack([rigid_bones(c) for c in b]), atol=1e-12)
    assert M.bone_length_variation(rigid_bones(b)).max() < 1e-12
    assert M.bone_length_variation(b).min() > 0.005


def test_ground_feet_lifts_only_sinking_frames_by_their_depth():
    x, _ = _clip()
    x[..., 1] -= x[:, list(FOOT_JOINTS), 1].min() - 0.01                   # lowest foot at 1 cm
    x[5, :, 1] -= 0.05 + x[5, list(FOOT_JOINTS), 1].min() - 0.01         # frame 5 sinks 4 cm
    y = ground_feet(x)
    np.testing.assert_array_equal(np.delete(y, 5, axis=0), np.delete(x, 5, axis=0))
    np.testing.assert_allclose(y[5, list(FOOT_JOINTS), 1].min(), 0.0, atol=1e-12)
    np.testing.assert_allclose(y[5] - x[5], np.broadcast_to([0, 0.04, 0], (22, 3)), atol=1e-12)
    assert M.floor_penetration(x) == pytest.approx(1 / len(x))
    assert M.floor_penetration(y) == 0.0
    z = constrain_body(x)
    assert M.bone_length_variation(z) < 1e-12 and M.floor_penetration(z, tolerance=0) == 0.0


def test_boundary_step_and_jump_ratios_analytic():
    T = 20
    x = np.zeros((T, 22, 3))
    x[:, :, 2] = np.arange(T)[:, None] * 0.05                              # 5 cm / frame
    mask = np.zeros((T, 6), bool)
    mask[:8, 0] = True                                                     # stroke ends: step 7->8
    assert M.boundary_step_ratio(x, mask) == pytest.approx(1.0)
    assert M.boundary_jump_ratio(x, mask) == pytest.approx(1.0)
    x[8:, :, 2] += 0.1                                                     # a 10 cm jump there
    assert M.boundary_step_ratio(x, mask) == pytest.approx(3.0)
    assert M.boundary_jump_ratio(x, mask) == pytest.approx(3.0)            # 0.15 / 0.05
    assert np.isnan(M.boundary_step_ratio(x, np.ones((T, 6), bool)))       # no boundary
    assert np.isnan(M.boundary_jump_ratio(x, np.ones((T, 6), bool)))
    # a slow clip whose wrist swings fastest at the edge: the step ratio flags it, the jump
    # ratio does not (its neighbouring steps are as fast)
    y = np.zeros((T, 22, 3))
    y[:, :, 2] = np.arange(T)[:, None] * 0.005                             # the body: 5 mm / frame
    t = np.clip(np.arange(T) - 4, 0, 8)
    y[:, 20, 1] = 0.05 * (1 - np.cos(np.pi * t / 8))                       # a swing, fastest at 8
    assert M.boundary_step_ratio(y, mask) > 3
    assert M.boundary_jump_ratio(y, mask) == pytest.approx(1.0)            # steps 7, 8 are equal
    first = np.zeros((3, 6), bool)
    first[0, 0] = True                                                     # edge at step 0
    assert M.boundary_jump_ratio(x[:3], first) == pytest.approx(1.0)


def test_two_bone_ik_reaches_the_target_with_both_lengths_in_the_old_bend_plane():
    rng = np.random.default_rng(1)
    root, mid = rng.normal(size=(50, 3)), rng.normal(size=(50, 3))
    l1, l2 = rng.uniform(0.3, 0.5, 50), rng.uniform(0.3, 0.5, 50)
    d = rng.normal(size=(50, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    target = root + d * rng.uniform(np.abs(l1 - l2) + 0.01, l1 + l2 - 0.01)[:, None]
    knee, end = two_bone_ik(root, mid, target, l1, l2)
    np.testing.assert_allclose(end, target, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(knee - root, axis=1), l1, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(end - knee, axis=1), l2, atol=1e-9)
    normal = np.cross(target - root, mid - root)                  # the old bend plane
    np.testing.assert_allclose(np.sum(normal * (knee - root), axis=1), 0.0, atol=1e-9)
    u = (target - root) / np.linalg.norm(target - root, axis=1, keepdims=True)

    def perp(p):                                                  # ⟂ part w.r.t. the chain
        return (p - root) - np.sum((p - root) * u, axis=1, keepdims=True) * u
    assert np.all(np.sum(perp(knee) * perp(mid), axis=1) > 0)    # bends towards the old knee
    far = root + d * (l1 + l2 + 1.0)[:, None]                    # out of reach: straight leg
    knee, end = two_bone_ik(root, mid, far, l1, l2)
    np.testing.assert_allclose(np.linalg.norm(end - root, axis=1), l1 + l2, atol=1e-5)
    np.testing.assert_allclose(np.cross(end - root, d), 0.0, atol=1e-9)


def _walker(T=30, slide=0.0):
    """A real standing pose (the first frame of the shipped lesson walk) moving its pelvis
    forward by 2 cm / frame; the left toe is on the floor and slides ``slide`` m / frame
    forward (the leg re-posed by IK), the right foot is 30 cm in the air."""
    from physlab.demos.motion_diffusion import lesson_windows

    x = np.repeat(np.asarray(lesson_windows()["walk"][:1], dtype=float), T, axis=0)
    x[..., 1] -= x[0, 10, 1]                                     # left toe on the floor
    x[:, :, 2] += np.arange(T)[:, None] * 0.02
    x[:, [8, 11], 1] += 0.3                                      # right foot up
    hip, knee, ankle, toe = LEG_CHAINS[0]
    foot = x[0, toe] - x[0, ankle]
    l1 = np.linalg.norm(x[0, knee] - x[0, hip])
    l2 = np.linalg.norm(x[0, ankle] - x[0, knee])
    target = x[0, ankle] + np.arange(T)[:, None] * [0, 0, slide]
    x[:, knee], x[:, ankle] = two_bone_ik(x[:, hip], x[:, knee], target, l1, l2)
    x[:, toe] = x[:, ankle] + foot
    return x


def test_foot_contacts_low_and_slow():
    x = _walker(slide=0.02)                                        # 0.4 m/s
    c = foot_contacts(x)
    assert c[:, 0].all() and not c[:, 1].any()
    assert not foot_contacts(_walker(slide=0.15))[:, 0].any()     # 3 m/s: a swinging foot
    y = x.copy()
    y[10, 10, 1] = 0.2                                            # one frame up: run of 1
    y[:, 10, 1][[9, 11]] = 0.2
    assert not foot_contacts(y)[9:12, 0].any() and foot_contacts(y)[:9, 0].all()


def test_lock_feet_stops_a_sliding_foot_and_keeps_the_bones():
    x = _walker(slide=0.03)
    assert M.foot_skating_ratio(x, height_thresh=0.1) > 0.8       # 0.6 m/s on the floor
    y = lock_feet(x, keep=0.0)
    np.testing.assert_allclose(y[:, 10, [0, 2]], np.median(x[:, 10, [0, 2]], axis=0)[None]
                               .repeat(len(x), 0), atol=1e-9)      # the toe stands still
    np.testing.assert_allclose(y[:, 10, 1], x[:, 10, 1], atol=1e-9)
    np.testing.assert_allclose(bone_lengths(y), bone_lengths(x), atol=1e-9)
    assert M.foot_skating_ratio(y, height_thresh=0.1) == 0.0
    untouched = [j for j in range(22) if j not in LEG_CHAINS[0][1:]]
    np.testing.assert_array_equal(y[:, untouched], x[:, untouched])
    pinned = np.zeros((len(x), 2), bool)
    pinned[:5, 0] = True                                          # a trajectory condition
    z = lock_feet(x, pinned=pinned, keep=0.0)
    np.testing.assert_array_equal(z[:5], x[:5])
    # the lock (offset 12 * 0.03 m at frame 5 to the median of 5..29) ramps in from the
    # pinned frame 4 at FADE_STEP per frame: from frame 9 on, (17 - 9) * 0.03 <= 5 * 0.05
    assert np.ptp(z[9:, 10, 2]) < 1e-9 and np.ptp(z[8:, 10, 2]) > 0.01
    steps = np.abs(np.diff(z[:, 10, 2]))
    assert steps.max() <= 0.03 + FADE_STEP + 1e-9                 # ramped in, no jump
    # two plants one frame apart (a shuffling foot): the locks hand over along a ramp, not
    # in one frame
    c2 = np.zeros((len(x), 2), bool)
    c2[:12, 0] = c2[13:, 0] = True
    hop = lock_feet(x, contacts=c2, keep=0.0)
    d = np.linalg.norm(np.diff(hop[:, 10] - x[:, 10], axis=0), axis=-1)
    assert d.max() <= FADE_STEP + 1e-9, d.max()          # the old fade: 0.36 m in one frame
    np.testing.assert_allclose(bone_lengths(hop), bone_lengths(x), atol=1e-9)
    blend = lock_feet(x, contacts=np.r_[np.zeros(10), np.ones(10), np.zeros(10)].astype(bool)
                      [:, None].repeat(2, 1) & [True, False], blend=3, keep=0.0)
    np.testing.assert_array_equal(blend[:6], x[:6])               # before the fade
    np.testing.assert_array_equal(blend[23:], x[23:])             # after it
    step = np.linalg.norm(np.diff(blend[:, 10], axis=0), axis=-1)
    offset = 4.5 * 0.03                           # run of 10 frames locked at its median
    assert step.max() == pytest.approx(0.03 + offset / 4, abs=1e-6)   # faded over 3 + 1 steps
    np.testing.assert_allclose(constrain_body(x, lock=True), ground_feet(lock_feet(x)),
                               atol=1e-9)
    soft = lock_feet(x, keep=0.3)                                 # 30 % of the slide kept
    np.testing.assert_allclose(np.diff(soft[:, 10, 2]), 0.3 * 0.03, atol=1e-9)
    np.testing.assert_allclose(soft[:, 10, 2].mean(), x[:, 10, 2].mean(), atol=1e-9)
    np.testing.assert_allclose(bone_lengths(soft), bone_lengths(x), atol=1e-9)


@pytest.mark.parametrize("call, match", [
    (lambda: lock_feet(np.zeros((5, 22, 3)), contacts=np.zeros((5, 3), bool)), "contacts must"),
    (lambda: lock_feet(np.zeros((5, 22, 3)), pinned=np.zeros((4, 2), bool)), "pinned must"),
    (lambda: lock_feet(np.zeros((5, 22, 3)), blend=-1), "blend must"),
    (lambda: lock_feet(np.zeros((5, 22, 3)), keep=1.5), "keep must"),
    (lambda: lock_feet(np.zeros((2, 5, 22, 3))), "one clip"),
    (lambda: foot_contacts(np.zeros((5, 22, 3)), speed=0), "speed must be > 0"),
    (lambda: foot_contacts(np.zeros((1, 22, 3))), r"T >= 2"),
    (lambda: rigid_bones(np.zeros((5, 21, 3))), r"shape \(T, 22, 3\)"),
    (lambda: rigid_bones(np.full((5, 22, 3), np.nan)), "NaN"),
    (lambda: rigid_bones(np.zeros((5, 22, 3)), lengths=np.ones(3)), "lengths must be"),
    (lambda: rigid_bones(np.zeros((5, 22, 3)), lengths=-np.ones(22)), "non-negative"),
    (lambda: ground_feet(np.zeros((0, 22, 3))), r"shape \(T, 22, 3\)"),
])
def test_bad_input(call, match):
    with pytest.raises(ValueError, match=match):
        call()
