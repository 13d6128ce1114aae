"""Tests of physlab.motion.blend: placement of a clip after another, the transition methods
(plain cut, linear, slerp, SQUAD, Sketch2Anim's DDIM-inversion blending with the shipped
generator), the junction statistic, and bad input."""
import numpy as np
import pytest
import torch

from physlab.motion.blend import (BLEND_METHODS, BlendResult, blend, junction_step_ratio,
                                  junction_acceleration_ratio,
                                  place_after)
from physlab.motion.features import _rotate_y, root_heading
from physlab.motion.metrics import bone_length_variation, floor_penetration, jerk
from physlab.motion.sketch import template_pose


def _walk(T=40, v=(0.0, 0.0, 0.05), heading=0.0, start=(0.0, 0.0)):
    """A rigid standing pose sliding at constant velocity v (m/frame) along its facing
    direction rotated by ``heading``: an analytic "clip"."""
    pose = template_pose()                                            # faces +z
    x = np.repeat(pose[None], T, axis=0) + np.arange(T)[:, None, None] * np.asarray(v)
    x = _rotate_y(x, np.full(T, heading))
    x[..., 0] += start[0]
    x[..., 2] += start[1]
    return x


@pytest.fixture(scope="module")
def gen():
    from physlab.motion.sampling import load_generator

    torch.set_num_threads(1)
    return load_generator()


def test_place_after_continues_position_and_heading():
    a = _walk(heading=0.4, start=(1.0, 2.0))
    b = _walk(heading=-1.3, start=(-5.0, 7.0))                       # anywhere, any facing
    for l in (0, 5, 20):
        p = place_after(a, b, l)
        assert np.isclose(root_heading(p[:1])[0], root_heading(a[-1:])[0], atol=1e-9)
        # same speed on both sides: the pelvis continues the straight line exactly
        step = a[-1, 0] - a[-2, 0]
        assert np.allclose(p[0, 0], a[-1, 0] + (l + 1) * step, atol=1e-9)
        assert np.allclose(p[1:, 0] - p[:-1, 0], step, atol=1e-9)      # keeps going the same way
        assert np.allclose(p[..., 1], b[..., 1])                      # heights kept
    # the whole placed motion equals the continuation of the analytic walk
    a2 = _walk(T=80, heading=0.4, start=(1.0, 2.0))
    assert np.allclose(place_after(a, b, 0), a2[40:], atol=1e-9)


def test_concat_and_linear_on_a_steady_walk_have_no_seam():
    a = _walk()
    full = _walk(T=100)
    b = place_after(a, _walk(start=(3.0, -2.0)), 20)
    res = blend(a, b, 20, method="linear")
    assert isinstance(res, BlendResult) and res.joints.shape == (100, 22, 3)
    assert res.transition == slice(40, 60) == res.window
    assert np.allclose(res.joints, full, atol=1e-9)                   # exactly the walk
    assert junction_step_ratio(res.joints, res.window, [a, b]) == pytest.approx(1.0)
    cut = blend(a, _walk(start=(3.0, -2.0)), method="concat")
    assert cut.joints.shape == (80, 22, 3) and cut.window == slice(40, 40)
    assert junction_step_ratio(cut.joints, cut.window, [a, b]) > 50   # a 3.6 m pop


def test_junction_step_ratio_references_on_a_move_between_still_poses():
    """Two still clips in different poses joined over 10 frames: every 'local' ratio is huge
    (the clips do not move), 'straight' is 1 for a constant-speed join and π/2 (sampled:
    sin(π/22) · 11) for a cosine ease-in-out; a plain cut has no straight join."""
    rng = np.random.default_rng(0)
    A, B = rng.normal(size=(22, 3)), rng.normal(size=(22, 3))
    n = 10
    for s, expected in ((np.arange(1, n + 1) / (n + 1), 1.0),
                        ((1 - np.cos(np.pi * np.arange(1, n + 1) / (n + 1))) / 2,
                         np.sin(np.pi / (2 * (n + 1))) * (n + 1))):
        join = A + s[:, None, None] * (B - A)
        x = np.concatenate([np.repeat(A[None], 10, 0), join, np.repeat(B[None], 10, 0)])
        w, clips = slice(10, 20), [np.repeat(A[None], 10, 0), np.repeat(B[None], 10, 0)]
        assert junction_step_ratio(x, w, clips, "straight") == pytest.approx(expected)
        assert junction_step_ratio(x, w, clips, "local") > 1e6
    assert expected == pytest.approx(np.pi / 2, rel=0.01)
    with pytest.raises(ValueError, match="straight"):
        junction_step_ratio(x, slice(20, 20), clips, "straight")


def test_junction_acceleration_ratio_sees_a_change_of_velocity_only():
    """A swaying clip cut into two and joined back unchanged has no seam (ratio 1 up to the
    sampling of the sine's peak); the same cut with the second half shifted 5 cm pops (the
    jump against the sway's peak acceleration A ω² = 0.1 · (2π/20)² m/frame²: 3.6)."""
    t = np.arange(80)[:, None, None]
    x = 0.1 * np.sin(2 * np.pi * t / 20 + np.arange(22)[None, :, None]) * np.ones((1, 1, 3))
    a, b = x[:40], x[40:]
    r = junction_acceleration_ratio(x, slice(40, 40), [a, b])
    assert r == pytest.approx(1.0, abs=0.05)
    y = x.copy()
    y[40:] += [0.05, 0.0, 0.0]
    assert junction_acceleration_ratio(y, slice(40, 40), [a, b + [0.05, 0, 0]]) > 3   # 3.6
    with pytest.raises(ValueError, match="2 frames on each side"):
        junction_acceleration_ratio(x, slice(1, 5), [a, b])


@pytest.mark.parametrize("method", ["slerp", "squad"])
def test_rotational_transitions_keep_bones(method):
    a = _walk()
    b = place_after(a, _walk(heading=0.8), 20)
    res = blend(a, b, 20, method=method)
    assert res.joints.shape == (100, 22, 3)
    assert bone_length_variation(res.joints[res.transition]) < 1e-6
    # the fill joins both clips without a jump larger than the clips' own steps
    assert junction_step_ratio(res.joints, res.window, [a, b], "local") < 1.5


def test_junction_step_ratio_by_hand():
    x = np.zeros((6, 22, 3))
    x[:, :, 0] = np.array([0, 1, 2, 3, 7, 8])[:, None] * 0.1          # one 0.4 m step 3 -> 4
    clip = x[:3]
    assert junction_step_ratio(x, slice(4, 4), [clip, clip]) == pytest.approx(4.0)
    assert junction_step_ratio(x, slice(1, 3), [clip, clip]) == pytest.approx(1.0)
    with pytest.raises(ValueError, match="window"):
        junction_step_ratio(x, slice(0, 2), [clip, clip])
    # local reference: the largest step of each clip next to the junction (0.1 here)
    assert junction_step_ratio(x, slice(4, 4), [clip, x[4:]], "local") == pytest.approx(4.0)
    with pytest.raises(ValueError, match="reference"):
        junction_step_ratio(x, slice(4, 4), [clip, clip], "mean")


def test_inversion_blend_joins_two_generated_clips(gen):
    """Sketch2Anim supp. D with the shipped model: a walk, then a bow. The result keeps both
    clips outside the blending window, is deterministic, rigid, on the floor, and far
    smoother at the junction than the plain cut."""
    a = gen("a person walks", seed=0, steps=20)
    b0 = gen("a person bows", seed=1, steps=20)
    b = place_after(a, b0, 20)
    kw = dict(actions=("a person walks", "a person bows"), generator=gen)
    res = blend(a, b, 20, method="inversion", **kw)
    j = res.joints
    assert j.shape == (100, 22, 3) and res.transition == slice(40, 60)
    assert res.window == slice(30, 70)                                # 10 context frames a side
    assert np.array_equal(j[:30], a[:30]) and np.array_equal(j[70:], b[10:])
    assert np.array_equal(j, blend(a, b, 20, method="inversion", **kw).joints)
    w = j[res.window]
    assert bone_length_variation(w) < 0.01
    assert floor_penetration(w) <= 0.01
    cut = blend(a, place_after(a, b0, 0), method="concat")
    r_blend = junction_step_ratio(j, res.window, [a, b])
    r_cut = junction_step_ratio(cut.joints, cut.window, [a, b])
    assert r_blend < r_cut
    # the context frames stay on the clips (G_m of Eq. (18)): a few cm at most
    assert np.linalg.norm(j[[30, 69]] - np.stack([a[30], b[9]]), axis=-1).mean() < 0.05
    # smoother than the cut over the junction
    assert jerk(j[35:65])[1] < jerk(cut.joints[25:55])[1]


def test_bad_input(gen):
    a = _walk()
    with pytest.raises(ValueError, match="method must be one of"):
        blend(a, a, method="cubic")
    with pytest.raises(ValueError, match="transition"):
        blend(a, a, 0, method="linear")
    with pytest.raises(ValueError, match="transition"):
        blend(a, a, -1, method="linear")
    with pytest.raises(ValueError, match="transition must be at most 38"):
        blend(a, a, 39, method="inversion", actions=("a", "b"), generator=gen)
    with pytest.raises(ValueError, match="actions"):
        blend(a, a, 20, method="inversion", generator=gen)
    with pytest.raises(ValueError, match="clip_a needs >= 10"):
        blend(a[:5], a, 20, method="inversion", actions=("a person walks",) * 2, generator=gen)
    with pytest.raises(ValueError, match=r"clip_b must be a \(T, 22, 3\)"):
        blend(a, a[..., :2], method="linear")
    with pytest.raises(ValueError, match="NaN"):
        place_after(a, np.full_like(a, np.nan))
    with pytest.raises(ValueError, match="guidance"):
        blend(a, a, 20, method="inversion", actions=("a person walks",) * 2, generator=gen,
              guidance=(1,))
    for bad in (0, -5, True, "x"):
        with pytest.raises(ValueError, match="steps must be an integer >= 1"):
            blend(a, a, 20, method="inpaint", actions=("a person walks",) * 2, generator=gen,
                  steps=bad)
    assert set(BLEND_METHODS) == {"concat", "linear", "slerp", "squad", "inpaint", "inversion"}


def test_model_blends_leave_the_scheduler_as_they_found_it(gen):
    """Blending sets its own DDIM timesteps; the generator's scheduler gets its previous
    sampling order back (also when the blend fails), and 'inpaint' needs one feature row
    per frame ('absolute' features)."""
    import copy

    a = _walk()
    sched = gen.scheduler
    sched.set_timesteps(7)
    before = sched.timesteps.clone()
    for method in ("inversion", "inpaint"):
        blend(a, place_after(a, a, 20), 20, method, actions=("a person walks",) * 2,
              generator=gen, steps=3, guidance=(0, 0))
        assert sched.num_inference_steps == 7 and torch.equal(sched.timesteps, before)
    rel = copy.copy(gen)
    rel.config = copy.copy(gen.config)
    rel.config.representation = "relative"
    with pytest.raises(ValueError, match="method='inpaint' needs a checkpoint of 'absolute'"):
        blend(a, place_after(a, a, 20), 20, "inpaint", actions=("a person walks",) * 2,
              generator=rel)


def test_place_after_uses_the_mean_speed_of_both_clips():
    a = _walk(v=(0.0, 0.0, 0.04))
    b = _walk(v=(0.0, 0.0, 0.08), heading=1.0, start=(4.0, 4.0))
    p = place_after(a, b, 9)
    # heading of b turned onto a's: both move along +z; gap of 10 steps at (0.04 + 0.08) / 2
    assert np.allclose(p[0, 0, [0, 2]], a[-1, 0, [0, 2]] + [0.0, 10 * 0.06], atol=1e-9)
    placed, theta, offset = place_after(a, b, 9, return_transform=True)
    assert np.allclose(placed, p)
    assert np.allclose(_rotate_y(b, np.full(len(b), theta)) + offset, p, atol=1e-9)


def test_inversion_options_and_their_errors(gen):
    a = gen("a person walks", seed=0, steps=20)
    b = place_after(a, gen("a person bows", seed=1, steps=20), 20)
    kw = dict(actions=("a person walks", "a person bows"), generator=gen, steps=10)
    z = blend(a, b, 20, "inversion", guidance_space="network", guidance=(1, 10), **kw)
    x = blend(a, b, 20, "inversion", guidance=(1, 10), **kw)
    assert z.joints.shape == x.joints.shape == (100, 22, 3)
    assert not np.allclose(z.joints, x.joints)              # a different guidance path
    for r in (z, x):                                        # both hold the context
        assert np.linalg.norm(r.joints[[30, 69]] - np.stack([a[30], b[9]]), axis=-1).mean() < 0.05
    loose = blend(a, b, 20, "inversion", body_constraints=False, init_weight=0.0, **kw)
    assert bone_length_variation(loose.joints[loose.window]) > 1e-3   # constraints were on
    for bad, match in [(dict(guidance_space="z"), "guidance_space"),
                       (dict(init_weight=-1.0), "init_weight"),
                       (dict(fixed_point=-1), "fixed_point"),
                       (dict(guidance_scale=float("nan")), "guidance_scale"),
                       (dict(steps=0), "steps")]:
        with pytest.raises(ValueError, match=match):
            blend(a, b, 20, "inversion", **{**kw, **bad})
    with pytest.raises(TypeError, match="body_constraints"):
        blend(a, b, 20, "inversion", body_constraints="yes", **kw)
    with pytest.raises(ValueError, match="window must be a slice"):
        junction_step_ratio(a, slice(None, 3), [a, b])
    with pytest.raises(ValueError, match="two clips"):
        junction_step_ratio(a, slice(3, 3), [a])


def test_inpaint_baseline_keeps_the_context_and_depends_on_the_seed(gen):
    a = gen("a person walks", seed=0, steps=20)
    b = place_after(a, gen("a person bows", seed=1, steps=20), 20)
    kw = dict(actions=("a person walks", "a person bows"), generator=gen)
    r0 = blend(a, b, 20, "inpaint", seed=0, **kw)
    r1 = blend(a, b, 20, "inpaint", seed=1, **kw)
    assert r0.joints.shape == (100, 22, 3) and r0.window == slice(30, 70)
    assert not np.allclose(r0.joints[40:60], r1.joints[40:60])          # fresh noise
    assert np.array_equal(r0.joints, blend(a, b, 20, "inpaint", seed=0, **kw).joints)
    # inpainting holds the context without any guidance: within a few cm
    ctx = np.linalg.norm(r0.joints[[30, 69]] - np.stack([a[30], b[9]]), axis=-1).mean()
    assert ctx < 0.1
    assert bone_length_variation(r0.joints[r0.window]) < 1e-3
