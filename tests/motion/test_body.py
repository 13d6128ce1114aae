"""Body constraints of generated clips (physlab.motion.body) and the body checks of
physlab.motion.metrics, against analytic cases."""
import numpy as np
import pytest

from physlab.motion import metrics as M
from physlab.motion.body import clip_bone_lengths, constrain_body, ground_feet, rigid_bones
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


def test_boundary_step_ratio_analytic():
    T = 20
    x = np.zeros((T, 22, 3))
    x[:, :, 2] = np.arange(T)[:, None] * 0.05                              # 5 cm / frame
    mask = np.zeros((T, 6), bool)
    mask[:8, 0] = True                                                     # stroke ends: step 7->8
    assert M.boundary_step_ratio(x, mask) == pytest.approx(1.0)
    x[8:, :, 2] += 0.1                                                     # a 10 cm jump there
    assert M.boundary_step_ratio(x, mask) == pytest.approx(3.0)
    assert np.isnan(M.boundary_step_ratio(x, np.ones((T, 6), bool)))       # no boundary


@pytest.mark.parametrize("call, match", [
    (lambda: rigid_bones(np.zeros((5, 21, 3))), r"shape \(T, 22, 3\)"),
    (lambda: rigid_bones(np.full((5, 22, 3), np.nan)), "NaN"),
    (lambda: rigid_bones(np.zeros((5, 22, 3)), lengths=np.ones(3)), "lengths must be"),
    (lambda: rigid_bones(np.zeros((5, 22, 3)), lengths=-np.ones(22)), "non-negative"),
    (lambda: ground_feet(np.zeros((0, 22, 3))), r"shape \(T, 22, 3\)"),
])
def test_bad_input(call, match):
    with pytest.raises(ValueError, match=match):
        call()
