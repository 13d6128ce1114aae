"""The motion checkpoints shipped in data/motion/ (issue 5): present, within the 25 MB budget,
loadable without the text encoder, and actually trained — on held-out Bandai-Namco windows the
keypose + trajectory conditioning lands far closer to the targets than text only, and the
text-only model moves like the action it is asked for.

These test the trained weights, not the code paths (tests/motion/test_generate.py does that
with smoke models); they fail if a broken or untrained checkpoint is committed."""
from pathlib import Path

import numpy as np
import pytest
import torch

from physlab.motion.evaluate import GUIDED, UNGUIDED, clip_metrics, eval_conditions, \
    held_out_windows
from physlab.motion.metrics import bone_length_variation, floor_penetration
from physlab.motion.sampling import DEFAULT_CHECKPOINT, Generator
from physlab.motion.dataset import load_clips, make_windows, split_by_take

DATA = Path(DEFAULT_CHECKPOINT).parent
SINGLE = DATA / "sketch2anim_single_controlnet.pt"
LIFTER = DATA / "sketch_lifter.pt"
SHIPPED = [DEFAULT_CHECKPOINT, SINGLE, LIFTER]
#: Bounds of the networks-only control on 8 held-out windows, 20 DDIM steps, with margins
#: (measured 2026-11-28 with the shipped networks, the `make motion-model` recipe with its
#: keypose continuation, runs/s34: trajectory 0.083 m, keypose placed 0.082 m / pose 0.023 m,
#: 3.7x below text only; text only 0.167 / 0.239 / 0.084 m; the 12,000-step networks shipped
#: before: 0.086 / 0.075 / 0.027 m). On 64 windows (README): networks only 0.083 m trajectory,
#: 0.076 m placed, 0.028 m pose error (3.2x below text only) — issue 12's 0.15 m / 0.06 m / 3x
#: targets (its keypose MPJPE is the pose error: a Sketch2Anim keypose carries no placement).
TRAJ_LIMIT, KEY_LIMIT, POSE_LIMIT, TRAJ_GAIN, KEY_GAIN, POSE_GAIN = 0.15, 0.10, 0.05, 1.8, 2.5, 2.5
#: Largest joint step where a partial stroke starts or ends, over the clip's median step, of
#: guided clips: issue 12's bound (measured 2.50 here; on 64 windows at 50 steps 2.67, every
#: clip below 3; models shipped before had one clip of 63 at 3.34,
#: docs/motion_experiments.md). The networks alone jump more there (2.63 here, 4.0 on 64
#: windows; real clips 6.0): not asserted, in the README's held-out table.
EDGE_LIMIT = 3.0


@pytest.fixture(scope="module")
def gen():
    torch.set_num_threads(1)
    return Generator.from_checkpoint(DEFAULT_CHECKPOINT)


def test_shipped_checkpoints_exist_within_budget():
    for p in SHIPPED:
        assert p.is_file(), f"{p} is missing: run `make motion-model`"
    total = sum(p.stat().st_size for p in DATA.glob("*.pt"))
    assert total <= 25 * 2**20, f"data/motion/*.pt total {total / 2**20:.1f} MiB > 25 MiB"
    assert (DATA / "README.md").read_text().count("CC BY-NC 4.0") >= 1


def test_checkpoint_is_a_trained_control_model(gen):
    assert gen.has_control and not gen.model.single_controlnet
    single = Generator.from_checkpoint(SINGLE)
    assert single.has_control and single.model.single_controlnet
    # the frozen base of both is the same network
    a = dict(gen.denoiser.named_parameters())
    for name, p in single.denoiser.named_parameters():
        torch.testing.assert_close(p, a[name])
    # zero-initialised layers have moved away from zero: the control stage was trained
    zero = [p.abs().max().item() for m in gen.model.adapter.zero for p in m.parameters()]
    assert max(zero) > 1e-3


def _trained_takes(gen):
    """The Bandai-Namco takes the shipped checkpoint was trained on: its ``train_takes`` when
    it records them, else take 001 — the shipped models were trained when ../shared/data held
    only takes 001 and 002 (002 held out), before dataset-2 takes 003-010 were added."""
    return tuple(getattr(gen, "train_takes", None) or ("001",))


def test_training_texts_are_cached_and_never_load_the_encoder(real_data, gen):
    train_clips, _ = split_by_take(load_clips())
    seen = [c for c in train_clips if c.take in _trained_takes(gen)]
    texts = set(make_windows(seen, length=40, stride=10).text)  # as physlab.motion.train
    assert len(texts) > 100 and texts <= set(gen.text_cache.texts)
    for t in sorted(texts)[:3]:
        gen(t, steps=5)
    assert gen.text_cache.n_encoded == 0


@pytest.fixture(scope="module")
def held_out(real_data, gen):
    """Text only (the attached text model; ``"base"``: the control model's own base, Table 2's
    text only), networks only and guided clips of 8 held-out windows (Cross protocol)."""
    data = held_out_windows(8)
    conds = eval_conditions(data["joints"], seed=0)
    rows, clips = {}, {}
    text_model = gen.text_model
    for label, opts in (("text", None), ("base", None), ("networks", UNGUIDED),
                        ("guided", GUIDED)):
        gen.text_model = None if label == "base" else text_model
        try:
            x = np.stack([gen(data["text"][i], seed=i, steps=20,
                              **({} if opts is None else {**c.generator_kwargs(), **opts}))
                          for i, c in enumerate(conds)])
        finally:
            gen.text_model = text_model
        rows[label], clips[label] = clip_metrics(x, conds), x
    rows["real"] = clip_metrics(data["joints"], conds)
    return rows, clips, conds


def test_networks_alone_follow_the_conditions(held_out):
    """The ControlNet and keypose adapter, without any inference guidance, land much nearer
    the conditions than text only from the same base (bounds and measured values at
    ``TRAJ_LIMIT``). The attached text model's clips are as far from the conditions on 64
    windows (0.293 / 0.296 / 0.088 m against the base's 0.297 / 0.295 / 0.089 m, README); on
    these 8 its placed keypose error is 0.22 m against the base's 0.24 (2026-11-29)."""
    rows = held_out[0]
    t, n = rows["base"], rows["networks"]
    assert n["trajectory_error_3d"] < TRAJ_LIMIT and n["keypose_mpjpe_3d"] < KEY_LIMIT, rows
    assert n["keypose_pose_3d"] < POSE_LIMIT, rows
    assert n["trajectory_error_3d"] < t["trajectory_error_3d"] / TRAJ_GAIN, rows
    assert n["keypose_mpjpe_3d"] < t["keypose_mpjpe_3d"] / KEY_GAIN, rows
    assert n["keypose_pose_3d"] < t["keypose_pose_3d"] / POSE_GAIN, rows


def test_guidance_lands_on_the_conditions_and_keeps_the_body(held_out):
    rows, clips, conds = held_out
    g = rows["guided"]
    assert g["trajectory_error_3d"] < 0.05 and g["keypose_mpjpe_3d"] < 0.05, rows
    for label in ("networks", "guided"):
        x = clips[label]
        assert bone_length_variation(x).max() <= 0.01                    # rigid bones (m)
        assert floor_penetration(x).mean() <= 0.01                       # feet < -2 cm
    r = g["boundary_step_ratio"]
    assert np.isnan(r) or r <= EDGE_LIMIT, rows                          # no jump at stroke ends


def test_motion_is_about_as_smooth_as_mocap_and_feet_do_not_skate_far_more(held_out):
    """Issue 12's quality targets (jerk AUJ and PJ <= 3x real, foot skating <= 1.5x real on 64
    windows at 50 steps, README) with margins for 8 windows at 20 steps (measured 2026-11-28
    with the shipped networks, the foot lock holding unguided strokes' feet: AUJ 0.44 / 0.22 /
    0.37 and PJ 0.071 / 0.049 / 0.059 for text / networks / guided against 0.30 and 0.050
    real; skating 0.15 / 0.22 / 0.19 against 0.15; text only from the text model shipped since
    2026-11-29, its legs and trunk keeping 8 DCT frequencies (sampling.BODY_FREQUENCIES):
    AUJ 0.51, PJ 0.074, skating 0.18 against 0.30 / 0.050 / 0.15 real, so text only is held to
    issue 12's bounds themselves; with 10 frequencies 0.58 / 0.084 / 0.22)."""
    rows = held_out[0]
    real = rows["real"]
    for label in ("text", "networks", "guided"):
        r = rows[label]
        assert r["auj"] <= 3.5 * real["auj"] and r["pj"] <= 3.5 * real["pj"], (label, rows)
        assert r["foot_skating"] <= 2 * real["foot_skating"], (label, rows)
    text = rows["text"]
    assert text["auj"] <= 3 * real["auj"] and text["pj"] <= 3 * real["pj"], rows
    assert text["foot_skating"] <= 1.5 * real["foot_skating"], rows


def test_text_only_motion_follows_the_action(gen):
    """Root travel over the 2 s clip: 'runs' > 'walks' > 'bows' (seed-averaged)."""
    def travel(text):
        d = []
        for s in range(3):
            j = gen(text, seed=s, steps=20)
            d.append(np.linalg.norm(j[-1, 0, [0, 2]] - j[0, 0, [0, 2]]))
        return float(np.mean(d))

    run, walk, bow = travel("a person runs"), travel("a person walks"), travel("a person bows")
    assert run > walk > bow, (run, walk, bow)
    assert bow < 0.5 and walk > 1.0, (run, walk, bow)


def test_text_only_runs_move_their_pelvis_like_real_runs(real_data, gen):
    """Issue 12's speed target for runs (mean pelvis path speed within 30 % of the real clips
    of the action) and a pelvis that does not surge back and forth along its path (mean
    horizontal acceleration <= 4x real): measured on these 4 seeds 1.05x the real speed and
    1.5x its acceleration (2026-11-29, with BODY_FREQUENCIES; 2.8x before); without the path
    low-pass (PATH_FREQUENCIES) 1.48x and 9.1x; the text model with the finer path scale
    (2026-12-02) 0.87x and 1.03x; the text model trained longer and sampled with its own
    text guidance (6 above T/2, 4.5 below; shipped since the evening of 2026-12-02) 0.98x and
    0.89x."""
    from physlab.motion.evaluate import motion_statistics

    real = make_windows(load_clips(contents=["run"], progress=False)).joints
    fake = np.stack([gen("a person runs", seed=s) for s in range(4)])

    def acceleration(x):
        return np.linalg.norm(np.diff(x[:, :, 0][..., [0, 2]], 2, axis=1), axis=-1).mean()

    speed_real, speed = motion_statistics(real)[:, 2].mean(), motion_statistics(fake)[:, 2].mean()
    assert abs(speed / speed_real - 1) <= 0.3, (speed, speed_real)
    assert acceleration(fake) <= 4 * acceleration(real), (acceleration(fake), acceleration(real))


def test_the_text_model_walks_backwards_and_waves(real_data, gen):
    """Text only comes from the attached text model (checkpoint.attach_text_model), which does
    the rare actions that the control model's x₀ base overwrites with its own (issue 12's
    text-adherence targets, docs/motion_experiments.md). Measured on these 4 seeds
    (2026-11-29, the text model trained with ``--style-drop 0.3``): backwards walk -1.74 m and
    0.90 m/s, +28 % (real -1.34 m, 0.71 m/s; the base -0.14 m, 0.17 m/s; the text model before
    ``--style-drop`` -1.99 m, 1.03 m/s, +46 %); the wave's wrist travel 0.023 m/frame, 55 % of
    real (real 0.043; the base 0.007; before ``--style-drop`` 0.022). The text model shipped
    on 2026-12-02 (``--pelvis-scale 4``): -1.79 m and 0.92 m/s, +31 %; the wave 0.024,
    56 %. The text model shipped since (``--pelvis-scale 5``, 20,000 steps, its own text
    guidance 6 / 4.5): -1.51 m and 0.78 m/s, +10 %; the wave 0.028, 65 %."""
    from physlab.motion.evaluate import motion_statistics

    assert gen.text_model is not None, "the shipped checkpoint should carry a text model"
    real = {c: motion_statistics(make_windows(load_clips(contents=[c], progress=False)).joints)
            .mean(0) for c in ("walk-back", "wave-right-hand")}
    back = motion_statistics(np.stack([gen("a person walks backwards", seed=s)
                                       for s in range(4)])).mean(0)
    wave = motion_statistics(np.stack([gen("a person waves the right hand", seed=s)
                                       for s in range(4)])).mean(0)
    assert back[0] < 0.5 * real["walk-back"][0] < 0, (back, real)             # forward (m)
    assert abs(back[2] / real["walk-back"][2] - 1) < 0.45, (back, real)       # speed (m/s)
    assert wave[4] > 0.4 * real["wave-right-hand"][4], (wave, real)           # wrist travel


def test_the_text_model_keeps_near_still_actions_on_the_spot(real_data, gen):
    """A wave or raised hands barely move the pelvis (0.02 m/s real). The text model trained
    with the pelvis path's feature scale 4x finer (``train --pelvis-scale 4``) moved it at
    1.31x / 1.55x the real speed on these 4 seeds (2026-12-02); the shipped one (5x finer,
    20,000 steps, its text guidance 4.5 on the lower half of the noise levels) at 1.30x /
    0.62x; the text model before both, at the data's scale, swayed at 3.97x / 3.59x
    (docs/motion_experiments.md)."""
    from physlab.motion.evaluate import motion_statistics

    for text, content in (("a person waves the right hand", "wave-right-hand"),
                          ("a person raises both hands", "raise-up-both-hands")):
        real = motion_statistics(make_windows(load_clips(contents=[content],
                                                         progress=False)).joints).mean(0)
        fake = motion_statistics(np.stack([gen(text, seed=s) for s in range(4)])).mean(0)
        assert fake[2] <= 2 * real[2], (text, fake[2], real[2])             # pelvis speed


def test_a_2d_sketch_steers_the_shipped_model_through_the_guidance(real_data, gen):
    """Held-out windows projected in random storyboard views (supp. B ranges), pelvis path
    and the first keypose drawn in 2D: the guidance (Eq. (16) + the 2D keypose term) brings
    the projection much nearer the sketch than text only (measured on 8 windows, 50 steps:
    pelvis path 0.126 -> 0.044 units, keypose 0.055 -> 0.008, and the 3D pelvis path
    0.219 -> 0.173 m, depth being unseen)."""
    from physlab.motion.camera import random_camera

    data = held_out_windows(4)
    e = []
    for i in range(4):
        cam = random_camera(i)
        p = cam.project(data["joints"][i])
        sketch = {"trajectories_2d": {"pelvis": p[:, 0]}, "keypose_2d": p[0], "camera": cam}
        for kw in ({}, sketch):
            q = cam.project(gen(data["text"][i], seed=i, steps=20, **kw))
            e.append((np.linalg.norm(q[:, 0] - p[:, 0], axis=-1).mean(),
                      np.linalg.norm((q[0] - q[0, :1]) - (p[0] - p[0, :1]), axis=-1).mean()))
    text, drawn = np.array(e[0::2]).mean(0), np.array(e[1::2]).mean(0)
    assert drawn[0] < text[0] / 2 and drawn[1] < text[1] / 3, (text, drawn)


@pytest.fixture(scope="module")
def drawn(real_data, gen):
    """8 held-out windows, each Cross condition drawn in a random storyboard view (supp. B
    ranges, the evaluation's construction): text only, the 2D encoders alone and with the 2D
    guidance, 20 DDIM steps."""
    from physlab.motion.evaluate import draw_conditions, sketch_conditions, sketch_metrics

    data = held_out_windows(8)
    conds = sketch_conditions(data["joints"], "cross", seed=0)
    cams, sk = draw_conditions(conds, seed=0)
    rows, clips = {}, {}
    for label, opts in (("text", None), ("networks", UNGUIDED), ("guided", GUIDED)):
        x = np.stack([gen(data["text"][i], seed=i, steps=20,
                          **({} if opts is None else {**sk[i], **opts})) for i in range(8)])
        rows[label], clips[label] = sketch_metrics(x, conds, cams), x
    return rows, clips


def test_the_shipped_2d_encoders_read_a_drawing(gen, drawn):
    """Sec. 5: the aligned 2D encoders steer the networks towards the drawing without any
    guidance, and with the 2D guidance the projection lands on it (measured 2026-11-28 on
    these 8 windows at 20 steps, the encoders aligned 15,000 steps on the shipped networks:
    trajectory text only 0.101, networks only 0.072, guided 0.011 units; keypose 0.044 /
    0.017 / 0.004; README: 64 windows). Bones stay rigid and feet on the floor."""
    assert gen.has_sketch_encoders
    rows, clips = drawn
    t, n, g = rows["text"], rows["networks"], rows["guided"]
    assert n["trajectory_error_2d"] < 0.8 * t["trajectory_error_2d"], rows
    assert n["keypose_mpjpe_2d"] < 0.65 * t["keypose_mpjpe_2d"], rows
    assert g["trajectory_error_2d"] < 0.035 and g["keypose_mpjpe_2d"] < 0.02, rows
    for x in clips.values():
        assert bone_length_variation(x).max() <= 0.01
        assert floor_penetration(x).mean() <= 0.01


def test_the_shipped_lifter_lifts_a_drawing_towards_its_3d_condition(real_data):
    """The lift-and-control baseline's lifter (Table 1) puts drawn points much nearer their 3D
    origin than the drawing's own 2D coordinates put back at the origin's depth (measured on
    these 8 windows: 0.084 m against 0.474 m)."""
    from physlab.motion.baselines import lift, load_lifter
    from physlab.motion.camera import random_camera, sketch_kwargs
    from physlab.motion.evaluate import eval_conditions

    from physlab.motion.dataset import TRAJECTORY_JOINT_NAMES

    lifter = load_lifter(LIFTER)
    data = held_out_windows(8)
    errs, naive = [], []
    for i, c in enumerate(eval_conditions(data["joints"], seed=0)):
        cam = random_camera(i)
        kw = sketch_kwargs(c, cam)
        k3, t3 = lift(lifter, **kw)
        for name, pts in t3.items():
            j = TRAJECTORY_JOINT_NAMES.index(name)
            true = c.trajectory[c.mask[:, j], j]
            errs.append(np.linalg.norm(pts - true, axis=-1).mean())
            uv = kw["trajectories_2d"][name] / cam.scale          # back along the view ray,
            flat = np.c_[uv, np.zeros(len(uv))] @ cam.rotation     # at the origin's depth
            naive.append(np.linalg.norm(flat - true, axis=-1).mean())
    assert np.mean(errs) < 0.6 * np.mean(naive), (np.mean(errs), np.mean(naive))



def test_denoise_from_keeps_the_clip_at_low_noise_and_forgets_it_from_pure_noise(gen,
                                                                                  real_data):
    """:meth:`Generator.denoise_from` noises a real clip to a level and denoises it back: at
    level 0 the shipped network returns a clip near the given one (mean joint error 0.15 m,
    measured 2026-11-26: the damping docs/motion_experiments.md describes; a base with the skip
    connection, 0.02 m), from pure noise one of its own (0.54 m)."""
    win = make_windows(split_by_take(load_clips(contents=["walk"]))[1], length=40, stride=40)
    J = win.joints[0]
    near = gen.denoise_from(J, 0, "a person walks", guidance_scale=1.0)
    far = gen.denoise_from(J, None, "a person walks", guidance_scale=1.0)
    err = lambda X: np.linalg.norm(X - J, axis=-1).mean()                # noqa: E731
    assert err(near) < 0.2 and err(near) < 0.5 * err(far)
    for bad, match in (((J, 1000), "level"), ((J, -1), "level"), ((J, 2.5), "level"),
                       ((J[:10], 5), "joints must be")):
        with pytest.raises(ValueError, match=match):
            gen.denoise_from(*bad, "a person walks")


def test_detail_kept_reports_each_level(real_data):
    """:func:`detail_kept` measures the asked statistic on windows of the asked action, each
    level on its own (the same value whatever other levels are asked), noise apart."""
    from physlab.motion.evaluate import detail_kept, format_detail

    kw = {"content": "walk-back", "windows": 2, "statistic": "forward_m", "steps": 10,
          "progress": False}
    res = detail_kept(DEFAULT_CHECKPOINT, levels=(20, None), **kw)
    assert set(res["levels"]) == {20, "noise"} and res["windows"] == 2
    assert res["real"] < -0.5                                          # walks backwards
    assert detail_kept(DEFAULT_CHECKPOINT, levels=(20,), **kw)["levels"][20] == \
        res["levels"][20]
    assert res["levels"][20] != res["levels"]["noise"]
    assert set(res["slopes"]) == {20, "noise"}
    assert all(np.isfinite(v) for v in res["slopes"].values())      # two windows: a slope
    assert "from noise" in format_detail(res) and "slope on real" in format_detail(res)
    with pytest.raises(ValueError, match="statistic"):
        detail_kept(DEFAULT_CHECKPOINT, statistic="speed")
    with pytest.raises(ValueError, match="content"):
        detail_kept(DEFAULT_CHECKPOINT, content="juggle")
