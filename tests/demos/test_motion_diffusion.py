"""physlab.demos.motion_diffusion: lesson 09 callbacks (Sketch2Anim Secs. 3–4, Eqs. 1–9, 14;
DDPM Eq. 4, DDIM Eq. 12), run on smoke checkpoints trained in a temporary folder."""
import itertools
import re
import warnings

import numpy as np
import pytest
import torch
from matplotlib.figure import Figure

from physlab.demos import motion_diffusion as demo
from physlab.motion.export import TPOSE_OFFSETS
from physlab.motion.skeleton import PARENTS, forward_kinematics
from physlab.motion.train import hash_encoder, train

SMOKE = {"smoke": True, "progress": False, "steps": 2, "num_threads": 1}
MPL = {"backend": "matplotlib"}                  # fast, no OpenGL probe


@pytest.fixture(scope="module")
def ckpts(real_data, tmp_path_factory):
    d = tmp_path_factory.mktemp("lesson09")
    base = train(stage="base", out=str(d / "base.pt"), **SMOKE)["path"]
    control = train(stage="control", base_ckpt=str(base), out=str(d / "control.pt"),
                    **SMOKE)["path"]
    return {"base": str(base), "control": str(control)}


@pytest.fixture(scope="module")
def ckpt(ckpts):
    return ckpts["control"]


@pytest.fixture(scope="module")
def walk(real_data):
    return demo.walk_window()


def _drawable(fig, tmp_path, n_axes):
    assert isinstance(fig, Figure)
    assert len(fig.axes) == n_axes, [a.get_title() for a in fig.axes]
    fig.savefig(tmp_path / "f.png")
    assert (tmp_path / "f.png").stat().st_size > 5_000


def _tpose_clip(T=40, speed=1.0, fps=demo.FPS, height=0.965):
    """A rigid T-pose gliding along +z at ``speed`` m/s (pelvis at ``height`` m)."""
    R = np.broadcast_to(np.eye(3), (T, 22, 3, 3))
    root = np.zeros((T, 3))
    root[:, 1] = height
    root[:, 2] = speed * np.arange(T) / fps
    return forward_kinematics(R, TPOSE_OFFSETS, PARENTS, root_positions=root)


# ---------------------------------------------------------------------------- Sec. 2: data
def test_walk_window_is_a_canonical_walk(walk):
    x, text = walk
    assert x.shape == (40, 22, 3) and text == "a person walks"
    assert np.allclose(x[0, 0, [0, 2]], 0.0)                     # canonical: pelvis at x=z=0
    v = demo.root_speed(x)
    assert 0.6 < v.mean() < 2.0                                 # a walk, m/s
    assert x[-1, 0, 2] > 1.0                                    # forward along +z


def test_feature_channels_of_a_gliding_tpose():
    ch = demo.feature_channels(_tpose_clip(speed=1.3))
    assert np.allclose(ch["forward speed (m/s)"], 1.3)
    assert np.allclose(ch["turning rate (°/s)"], 0.0)
    assert np.allclose(ch["pelvis height (m)"], 0.965)
    assert np.all(ch["left toe contact"] == 0.0)                # 1.3 m/s > contact speed


def test_walk_figure_with_the_default_backend(walk, tmp_path):
    _drawable(demo.walk_figure(*walk), tmp_path, 2)


# ---------------------------------------------------------------------------- Sec. 3: noising
def test_noised_features_match_the_closed_form(ckpt):
    sched = demo.generator(ckpt).scheduler
    x0 = np.random.default_rng(1).standard_normal((39, 137))
    ts = (0, 10, 400, 999)
    xt = demo.noised_features(x0, sched, ts, seed=3)
    eps = np.random.default_rng(3).standard_normal(x0.shape)   # the same ε by contract
    abar = sched.alphas_cumprod.numpy()
    for k, t in enumerate(ts):
        np.testing.assert_allclose(xt[k], np.sqrt(abar[t]) * x0 + np.sqrt(1 - abar[t]) * eps,
                                   rtol=1e-12, atol=1e-12)
    dist = np.linalg.norm(xt - x0, axis=(1, 2))
    assert np.all(np.diff(dist) > 0) and dist[0] < 0.1 * dist[-1]


def test_noising_moments_agree_with_the_closed_form(ckpt):
    sched = demo.generator(ckpt).scheduler
    x0 = np.random.default_rng(0).standard_normal((39, 137))
    m = demo.noising_moments(x0, sched, ts=(20, 300, 999), n=128, seed=5)
    np.testing.assert_allclose(m["slope"], m["sqrt_alpha_bar"], atol=0.01)
    np.testing.assert_allclose(m["variance"], m["one_minus_alpha_bar"], rtol=0.02)
    assert np.all(np.diff(m["variance"]) > 0)
    with pytest.raises(ValueError, match="n must be >= 2"):
        demo.noising_moments(x0, sched, n=1)


def test_decode_inverts_normalized_features(walk, ckpt):
    x, _ = walk
    x0 = demo.normalized_features(x, ckpt)
    g = demo.generator(ckpt)
    assert x0.shape == (g.config.n_frames, g.config.feature_dim)
    np.testing.assert_allclose(demo.decode(x0, ckpt), x, atol=1e-9)


def test_noising_figure_dissolves_the_walk(walk, ckpt, tmp_path):
    x, _ = walk
    fig, decoded = demo.noising_figure(x, ts=(0, 500, 999), checkpoint=ckpt, **MPL)
    _drawable(fig, tmp_path, 3)
    assert decoded.shape == (3, 40, 22, 3)
    err = [np.abs(d - x).mean() for d in decoded]
    assert err[0] < 0.01 < err[1] < err[2]          # t = 0 is (almost) the walk itself
    assert "t = 999" in fig.axes[2].get_title()


def test_schedule_figure(ckpt, tmp_path):
    _drawable(demo.schedule_figure(demo.generator(ckpt).scheduler), tmp_path, 2)


# ---------------------------------------------------------------------------- Sec. 4: samplers
def test_sampler_comparison_times_and_measures(ckpt, walk, tmp_path):
    samplers = {"DDPM, 40 steps": ("ddpm", 40), "DDIM, 4 steps": ("ddim", 4)}
    res = demo.sampler_comparison(samplers=samplers, checkpoint=ckpt)
    assert list(res) == list(samplers)
    for r in res.values():
        assert r["joints"].shape == (40, 22, 3) and r["seconds"] > 0
        assert 0 <= r["foot_skating"] <= 1 and r["pj"] > 0 and np.isfinite(r["auj"])
    assert res["DDPM, 40 steps"]["seconds"] > res["DDIM, 4 steps"]["seconds"]
    assert not np.allclose(res["DDPM, 40 steps"]["joints"], res["DDIM, 4 steps"]["joints"])
    _drawable(demo.sampler_figure(res, real=walk[0], **MPL), tmp_path, 3)


def test_motion_stats_of_a_gliding_tpose():
    st = demo.motion_stats(_tpose_clip(speed=1.5, height=1.2))
    assert np.isclose(st["speed"], 1.5)
    assert st["foot_skating"] == 0.0                  # feet far above 5 cm
    assert np.isclose(st["pj"], 0.0, atol=1e-12)      # constant velocity: no jerk
    gliding = _tpose_clip(speed=1.5, height=1.2)
    gliding[..., 1] -= gliding[:, [10, 11], 1].min()  # toes on the floor, still gliding
    assert demo.motion_stats(gliding)["foot_skating"] > 0.9


# ---------------------------------------------------------------------------- Sec. 5: guidance
def _speed_line(fig):
    return fig.axes[1].get_lines()[0].get_ydata()


def test_guidance_demo_redraws_and_w_changes_the_motion(ckpt, tmp_path):
    kw = dict(action="a person walks", seed=0, steps=6, checkpoint=ckpt, **MPL)
    f0 = demo.guidance_demo(guidance_scale=0.0, **kw)
    f1 = demo.guidance_demo(guidance_scale=7.5, **kw)
    f1b = demo.guidance_demo(guidance_scale=7.5, **kw)
    _drawable(f1, tmp_path, 2)
    assert "w = 7.5" in f1.axes[0].get_title() and "w = 0" in f0.axes[0].get_title()
    assert not np.allclose(_speed_line(f0), _speed_line(f1))    # guidance changed the motion
    np.testing.assert_array_equal(_speed_line(f1), _speed_line(f1b))   # seeded: same again
    m = re.search(r"mean ([\d.]+) m/s", f1.axes[1].get_legend().get_texts()[1].get_text())
    assert m and np.isclose(float(m.group(1)), _speed_line(f1).mean(), atol=0.006)


def test_guidance_demo_action_dropdown_changes_the_motion(ckpt):
    kw = dict(guidance_scale=7.5, seed=0, steps=6, checkpoint=ckpt, **MPL)
    a = demo.guidance_demo(action=demo.GUIDANCE_ACTIONS[0], **kw)
    b = demo.guidance_demo(action=demo.GUIDANCE_ACTIONS[-1], **kw)   # unseen: encoded once
    assert not np.allclose(_speed_line(a), _speed_line(b))


def test_guidance_sweep_ignores_the_text_at_w0(ckpt, tmp_path):
    """Eq. (14) with w = 0 is the unconditional prediction: two texts, same x_T -> the same
    motion; at w = 7.5 they differ."""
    sw = demo.guidance_sweep(("a person walks", "a person runs"), scales=(0.0, 7.5),
                             seeds=(0,), steps=6, checkpoint=ckpt)
    walks, runs = sw["a person walks"], sw["a person runs"]
    for key in ("speed", "foot_skating", "auj", "pj"):
        assert walks[key].shape == (2,)
        assert np.isclose(walks[key][0], runs[key][0], rtol=1e-6)
    assert not np.isclose(walks["speed"][1], runs["speed"][1], rtol=1e-6)
    _drawable(demo.guidance_sweep_figure(sw, real={"a person walks": _tpose_clip()[None]}),
              tmp_path, 3)


def test_guidance_by_level_samples_each_setting_with_the_same_seeds(ckpt, tmp_path):
    """guidance_by_level: a single scale and a pair (w_high, w_low); the pair (w, w) gives
    the single scale's speeds; default settings come from the generator's own guidance."""
    res = demo.guidance_by_level(("a person walks",), settings=(2.0, (2.0, 2.0), (6.0, 1.0)),
                                 seeds=(0, 1), steps=4, checkpoint=ckpt)
    v = res["per_seed"]["a person walks"]
    assert v.shape == (3, 2) and res["settings"] == [2.0, (2.0, 2.0), (6.0, 1.0)]
    np.testing.assert_array_equal(v[0], v[1])
    assert not np.allclose(v[0], v[2])
    x = demo.generator(ckpt)("a person walks", seed=1, steps=4, guidance_scale=(6.0, 1.0))
    assert np.isclose(v[2, 1], demo.root_speed(x).mean())
    np.testing.assert_allclose(res["speed"]["a person walks"], v.mean(1))
    w = demo.generator(ckpt).text_guidance                            # 2.5, no pair
    default = demo.guidance_by_level(("a person walks",), seeds=(0,), steps=4, checkpoint=ckpt)
    assert default["settings"] == [w, 2 * w, (2 * w, w)]
    real = {"a person walks": _tpose_clip()[None]}
    _drawable(demo.guidance_by_level_figure(res, real=real), tmp_path, 1)
    with pytest.raises(ValueError, match="settings"):
        demo.guidance_by_level(settings=((1.0, -1.0),), seeds=(0,), steps=4, checkpoint=ckpt)


def test_action_speeds_match_root_speed(ckpt):
    sp = demo.action_speeds(("a person walks",), seeds=(0,), steps=4, guidance_scale=7.5,
                            checkpoint=ckpt)
    x = demo.generator(ckpt)("a person walks", seed=0, steps=4, guidance_scale=7.5)
    assert np.isclose(sp["a person walks"], demo.root_speed(x).mean())
    default = demo.action_speeds(("a person walks",), seeds=(0,), steps=4,
                                 guidance_scale=None, checkpoint=ckpt)   # the generator's w
    x = demo.generator(ckpt)("a person walks", seed=0, steps=4)
    assert np.isclose(default["a person walks"], demo.root_speed(x).mean())


@pytest.mark.parametrize("call, match", [
    (lambda c: demo.guidance_demo(guidance_scale=-1.0, checkpoint=c), "guidance_scale"),
    (lambda c: demo.guidance_demo(guidance_scale=float("nan"), checkpoint=c), "guidance_scale"),
    (lambda c: demo.guidance_demo(action="  ", checkpoint=c), "action"),
    (lambda c: demo.guidance_sweep(scales=(1.0, -2.0), checkpoint=c), "guidance_scale"),
    (lambda c: demo.walk_window(start=-1), "start"),
    (lambda c: demo.walk_window(start=10_000), "start"),
    (lambda c: demo.embedding_neighbourhood(queries=[], checkpoint=c), "non-empty"),
])
def test_bad_parameters_raise_value_error(ckpt, call, match):
    with pytest.raises(ValueError, match=match):
        call(ckpt)


def test_guidance_scale_must_be_a_number(ckpt):
    with pytest.raises(TypeError, match="guidance_scale"):
        demo.guidance_demo(guidance_scale="7.5", checkpoint=ckpt)


# ---------------------------------------------------------------------------- Sec. 6: words
def test_embedding_neighbourhood_ranks_by_cosine(tmp_path):
    vocab = ["a person walks", "a person runs", "a person bows", "a person kicks"]
    nb = demo.embedding_neighbourhood(queries=["a person runs", "a person hops"],
                                      vocabulary=vocab, extra=["a person claps"], k=3,
                                      encoder=hash_encoder)
    assert nb["S"].shape == (2, 4) and nb["X"].shape == (1, 384)
    np.testing.assert_allclose(nb["S"], nb["Q"] @ nb["V"].T, atol=1e-12)
    first = nb["neighbours"]["a person runs"]
    assert first[0] == ("a person runs", pytest.approx(1.0))      # itself, cosine 1
    for nbrs in nb["neighbours"].values():
        assert len(nbrs) == 3
        assert all(a[1] >= b[1] for a, b in itertools.pairwise(nbrs))
    _drawable(demo.embedding_figure(nb), tmp_path, 2)


def test_embedding_neighbourhood_uses_the_checkpoint_table(ckpt):
    """Default encoder = the checkpoint's embedding cache: known texts get its stored rows."""
    cache = demo.generator(ckpt).text_cache
    nb = demo.embedding_neighbourhood(queries=["a person jogs"], checkpoint=ckpt)
    np.testing.assert_allclose(nb["V"], cache.get(nb["vocabulary"]), atol=1e-6)
    assert len(nb["vocabulary"]) == 24 and "a person jogs" not in nb["extra"]


@pytest.mark.slow
def test_minilm_puts_jogs_next_to_runs():
    from physlab.motion.text import ActionEncoder

    nb = demo.embedding_neighbourhood(encoder=ActionEncoder(num_threads=1), k=2)
    assert nb["neighbours"]["a person jogs"][0][0] == "a person runs"
    assert nb["neighbours"]["a person jogs"][0][1] > 0.6


# ---------------------------------------------------------------------------- Sec. 7: control
@pytest.fixture(scope="module")
def control(ckpt):
    return demo.control_comparison(windows=3, steps=4, checkpoint=ckpt,
                                   body_constraints=False)     # smoke model: raw joints


def test_control_comparison_returns_the_metrics(control):
    assert control["real"].shape == control["guided"].shape == (3, 40, 22, 3)
    rows = control["rows"]
    assert list(rows) == ["real clips", "text only", "keypose + trajectory",
                          "keypose + trajectory + guidance"]
    assert rows["real clips"]["keypose_mpjpe_3d"] == 0.0
    assert rows["real clips"]["trajectory_error_3d"] == 0.0
    for key, (name, _) in demo.CONTROL_ROWS.items():
        assert rows[name]["keypose_mpjpe_3d"] > 0 and rows[name]["seconds_per_clip"] > 0
        per = control["per_window"][key]
        assert per.shape == (3, 2)
        # the keypose column is the mean of the per-window errors (22 joints each)
        assert np.isclose(per[:, 0].mean(), rows[name]["keypose_mpjpe_3d"])
    assert not np.allclose(control["text_only"], control["controlled"])
    for i, c in enumerate(control["conds"]):
        assert c.key_frame == (0 if i % 2 == 0 else 39)


def test_inference_guidance_cuts_the_control_errors(control):
    """The L-BFGS post-optimisation minimises the keypose / trajectory losses on the decoded
    joints: even on an untrained smoke model it must land much nearer the condition."""
    text, guided = control["rows"]["text only"], control["rows"]["keypose + trajectory + guidance"]
    assert guided["trajectory_error_3d"] < 0.5 * text["trajectory_error_3d"]
    assert guided["keypose_mpjpe_3d"] < 0.5 * text["keypose_mpjpe_3d"]


def test_condition_kwargs_round_trip(control):
    from physlab.motion.sampling import build_condition

    for c in control["conds"]:
        kw = demo.condition_kwargs(c)
        b = build_condition(**kw)
        np.testing.assert_array_equal(b["traj_mask"], c.mask)
        np.testing.assert_allclose(b["trajectory"], c.trajectory)
        assert b["key_frame"] == c.key_frame


def test_control_figure(control, tmp_path):
    fig = demo.control_figure(control, index=1, **MPL)
    _drawable(fig, tmp_path, 4)
    assert "keypose at frame 40/40" in fig.get_suptitle()
    assert re.search(r"traj\. [\d.]+ cm", fig.axes[3].get_title())


def test_control_needs_a_control_checkpoint(ckpts):
    with pytest.raises(ValueError, match="control checkpoint"):
        demo.control_comparison(windows=1, steps=2, checkpoint=ckpts["base"])


# ---------------------------------------------------------------------------- Sec. 8: BVH
def test_export_bvh_is_exact_for_a_rigid_clip(tmp_path):
    x = _tpose_clip(speed=0.8)
    path, err, bone_std = demo.export_bvh(x, tmp_path / "rigid.bvh")
    assert path.is_file() and err < 1e-6 and bone_std < 1e-12


def test_export_bvh_reports_the_error_of_a_non_rigid_clip(tmp_path):
    x = _tpose_clip() + np.random.default_rng(0).normal(0, 0.01, (40, 22, 3))
    with warnings.catch_warnings(record=True) as log:
        warnings.simplefilter("always")
        _path, err, bone_std = demo.export_bvh(x, tmp_path / "noisy.bvh")
    assert not [w for w in log if "BVH reproduces" in str(w.message)]   # replaced by err
    assert 0.005 < err < 0.2 and bone_std > 0.003


# ---------------------------------------------------------------------------- helpers
def test_encoder_loading_is_quiet_and_restored():
    hf_logging = pytest.importorskip("transformers.utils.logging")
    before = hf_logging.is_progress_bar_enabled()
    with demo._quiet_encoder_loading():
        assert not hf_logging.is_progress_bar_enabled()
    assert hf_logging.is_progress_bar_enabled() == before


def test_one_thread_restores_the_setting():
    before = torch.get_num_threads()
    with demo.one_thread():
        assert torch.get_num_threads() == 1
    assert torch.get_num_threads() == before


# ------------------------------------------------------ shipped windows (no ../shared/data)
def test_shipped_lesson_windows_are_the_windows_of_the_clips(real_data, tmp_path):
    """data/motion/lesson_windows.npz is what write_lesson_windows cuts from the clips: the
    same texts and ids, and the same joints up to float rounding (1e-12 m; the BVH
    retargeting's last bits differ between CPUs: 7e-17 m on an AVX2-only EPYC, 2026-11-28)."""
    path = demo.write_lesson_windows(tmp_path / "w.npz")
    with np.load(path, allow_pickle=False) as fresh:
        shipped = demo.lesson_windows()
        assert sorted(fresh.files) == sorted(shipped)
        for k in fresh.files:
            assert fresh[k].dtype == shipped[k].dtype and fresh[k].shape == shipped[k].shape, k
            if fresh[k].dtype.kind == "f":
                np.testing.assert_allclose(fresh[k], shipped[k], rtol=0, atol=1e-12, err_msg=k)
            else:
                assert np.array_equal(fresh[k], shipped[k]), k
    root = real_data / "mocap" / "bandai_namco"
    speeds = demo.real_speeds({"a person runs": "run"}, data_root=root)
    shipped_speed = demo.real_speeds({"a person runs": "run"})["a person runs"]
    assert speeds["a person runs"] == pytest.approx(shipped_speed, rel=1e-9) and 1.5 < shipped_speed
    x, text = demo.walk_window(data_root=root)
    np.testing.assert_allclose(x, shipped["walk"], rtol=0, atol=1e-12)
    assert text == "a person walks"


def test_lesson_defaults_need_no_external_data(monkeypatch, tmp_path):
    monkeypatch.setenv("PHYSLAB_EXTERNAL_DATA", str(tmp_path))      # an empty folder
    x, text = demo.walk_window()
    assert x.shape == (40, 22, 3) and text == "a person walks"
    real = demo.real_windows({"a person walks": "walk", "a person runs": "run"})
    assert {k: v.shape[1:] for k, v in real.items()} == {
        "a person walks": (40, 22, 3), "a person runs": (40, 22, 3)}
    held = demo._held_out(3, None, None)
    assert held["joints"].shape == (3, 40, 22, 3) and len(held["text"]) == 3
    with pytest.raises(FileNotFoundError, match="lesson_windows.npz"):
        demo.walk_window(start=21)
    with pytest.raises(FileNotFoundError, match="lesson_windows.npz"):
        demo.real_windows({"a person kicks": "kick"})
    with pytest.raises(FileNotFoundError, match="lesson_windows.npz"):
        demo._held_out(7, None, None)


@pytest.mark.parametrize("windows", [0, -1, 2.5, True, float("nan")])
def test_held_out_window_count_is_checked(windows):
    with pytest.raises(ValueError, match="windows must be an integer"):
        demo._held_out(windows, None, None)


def test_text_model_comparison_samples_both_networks(ckpts, tmp_path):
    """Lesson 09's text-model figure: the same seed through the attached text model and the
    control base (smoke models: a text base attached in fp32, so its row equals the base's
    own clips), statistics per clip, a 2-row figure; a checkpoint without a text model and bad
    actions are refused."""
    from physlab.motion.checkpoint import attach_text_model
    from physlab.motion.evaluate import motion_statistics
    from physlab.motion.sampling import Generator

    text = train(stage="base", out=str(tmp_path / "text.pt"), skip=True, skip_pelvis=False,
                 seed=1, **SMOKE)["path"]
    attached = attach_text_model(ckpts["control"], text, tmp_path / "attached.pt",
                                 dtype=torch.float32)
    actions = Generator.from_checkpoint(text).text_cache.texts[:2]
    res = demo.text_model_comparison(actions, seed=1, steps=3, checkpoint=attached)
    assert res["actions"] == tuple(actions)
    own = Generator.from_checkpoint(text)
    for a, x in zip(actions, res["text model"]):
        np.testing.assert_array_equal(x, own(a, seed=1, steps=3))
    plain = Generator.from_checkpoint(ckpts["control"])
    for a, x in zip(actions, res["control base"]):
        np.testing.assert_array_equal(x, plain(a, seed=1, steps=3))
    for row in ("text model", "control base"):
        np.testing.assert_allclose(res["statistics"][row], motion_statistics(np.stack(res[row])))
    assert demo.generator(attached).text_model is not None              # restored after
    fig = demo.text_model_figure(res, **MPL)
    _drawable(fig, tmp_path, 4)
    assert fig.axes[0].get_title().startswith("text model") and "wrist" in fig.axes[0].get_title()
    assert fig.axes[2].get_title().startswith("control base")
    with pytest.raises(ValueError, match="has no text model"):
        demo.text_model_comparison(actions, checkpoint=ckpts["control"])
    with pytest.raises(ValueError, match="actions must be non-empty texts"):
        demo.text_model_comparison(("",), checkpoint=attached)
