"""A text model attached to a control checkpoint (physlab.motion.checkpoint.attach_text_model):
text-only requests are sampled with it, everything with a keypose, trajectories or a drawing
with the control model as before; attaching refuses checkpoints that do not fit together."""
import numpy as np
import pytest
import torch

from physlab.motion.camera import Camera
from physlab.motion.checkpoint import attach_text_model, load_checkpoint, main, \
    save_checkpoint
from physlab.motion.evaluate import _load
from physlab.motion.sampling import Generator
from physlab.motion.train import train

SMOKE = {"smoke": True, "progress": False, "steps": 2, "num_threads": 1}
STEPS = 6


@pytest.fixture(scope="module")
def ckpts(real_data, tmp_path_factory):
    d = tmp_path_factory.mktemp("text_model")
    base = train(stage="base", out=str(d / "base.pt"), **SMOKE)["path"]
    control = train(stage="control", base_ckpt=str(base), out=str(d / "control.pt"),
                    **SMOKE)["path"]
    # the text base: another network (EDM's skip connection, another seed), same data
    text = train(stage="base", out=str(d / "text.pt"), skip=True, skip_pelvis=False, seed=1,
                 **SMOKE)["path"]
    torch.set_num_threads(1)                         # train() sets its own thread count
    attached = attach_text_model(control, text, d / "attached.pt", dtype=torch.float32)
    return {"base": base, "control": control, "text": text, "attached": attached, "dir": d}


def test_text_only_requests_use_the_text_model_and_controlled_ones_do_not(ckpts):
    g = Generator.from_checkpoint(ckpts["attached"])
    plain = Generator.from_checkpoint(ckpts["control"])
    text = Generator.from_checkpoint(ckpts["text"])
    assert g.text_model is not None and plain.text_model is None and "text_model=True" in repr(g)
    action = g.text_cache.texts[0]
    got = g(action, seed=3, steps=STEPS)
    np.testing.assert_array_equal(got, text(action, seed=3, steps=STEPS))      # fp32 attached
    assert np.abs(got - plain(action, seed=3, steps=STEPS)).max() > 1e-3
    pose, cam = got[0], Camera(yaw=30.0)
    for kw in ({"keypose_3d": pose}, {"trajectories_3d": {"pelvis": got[:10, 0]}},
               {"keypose_2d": cam.project(pose), "camera": cam, "guidance_final": 5}):
        np.testing.assert_array_equal(g(action, seed=3, steps=STEPS, **kw),
                                      plain(action, seed=3, steps=STEPS, **kw))
    assert g.denoiser is g.model.base                # outside a text-only call: the base
    g.text_model = None                              # the paper's behaviour
    np.testing.assert_array_equal(g(action, seed=3, steps=STEPS),
                                  plain(action, seed=3, steps=STEPS))
    assert _load(ckpts["attached"], "--control").text_model is not None
    assert _load(ckpts["attached"], "--control", text_model=False).text_model is None


def test_the_default_attachment_is_fp16_and_close(ckpts, tmp_path):
    out = attach_text_model(ckpts["control"], ckpts["text"], tmp_path / "fp16.pt")
    weights = load_checkpoint(out)["text_model"]["model"]
    assert {v.dtype for v in weights.values() if v.is_floating_point()} == {torch.float16}
    g, text = Generator.from_checkpoint(out), Generator.from_checkpoint(ckpts["text"])
    action = g.text_cache.texts[1]
    a, b = g(action, seed=0, steps=STEPS), text(action, seed=0, steps=STEPS)
    assert np.abs(a - b).max() < 0.05 * np.abs(b).max()


def _altered(ckpts, name, change):
    ck = load_checkpoint(ckpts["text"])
    change(ck)
    return save_checkpoint(ckpts["dir"] / name, ck)


@pytest.mark.parametrize("case, match", [
    ("text is a control checkpoint", "must be a base"),
    ("control is a base checkpoint", "give a control checkpoint"),
    ("smooth basis", r"model_config\.smooth_basis differs"),
    ("feature stats", r"feature_stats\.mean differs"),
    ("train takes", "train_takes differ"),
])
def test_attaching_refuses_checkpoints_that_do_not_fit(ckpts, case, match, tmp_path):
    control, text = ckpts["control"], ckpts["text"]
    if case == "text is a control checkpoint":
        text = control
    elif case == "control is a base checkpoint":
        control = ckpts["base"]
    elif case == "smooth basis":
        text = _altered(ckpts, "k.pt", lambda c: c["model_config"].update(smooth_basis=3))
    elif case == "feature stats":
        text = _altered(ckpts, "m.pt", lambda c: c["feature_stats"].update(
            mean=c["feature_stats"]["mean"] + 0.1))
    else:
        text = _altered(ckpts, "t.pt", lambda c: c.update(train_takes=["001", "002"]))
    before = ckpts["control"].read_bytes()
    with pytest.raises(ValueError, match=match):
        attach_text_model(control, text)
    assert ckpts["control"].read_bytes() == before            # nothing written on failure


def test_a_text_model_with_its_own_feature_scale_decodes_with_it(ckpts, tmp_path):
    """A text base whose pelvis path std differs (train --pelvis-scale) attaches; its
    text-only clips equal the stand-alone base's, decoded with its own statistics, and the
    controlled ones stay the control model's."""
    def finer(c):
        std = np.asarray(c["feature_stats"]["std"], dtype=float).copy()
        std[[0, 2]] /= 4
        c["feature_stats"]["std"] = std
    text = _altered(ckpts, "finer.pt", finer)
    out = attach_text_model(ckpts["control"], text, tmp_path / "finer_attached.pt",
                            dtype=torch.float32)
    g = Generator.from_checkpoint(out)
    np.testing.assert_allclose(g.text_stats.std, load_checkpoint(text)["feature_stats"]["std"])
    assert g.stats is g._stats                                 # outside a text-only call
    action = g.text_cache.texts[0]
    alone = Generator.from_checkpoint(text)(action, seed=4, steps=STEPS)
    np.testing.assert_array_equal(g(action, seed=4, steps=STEPS), alone)
    assert np.abs(alone - Generator.from_checkpoint(ckpts["attached"])(
        action, seed=4, steps=STEPS)).max() > 1e-3             # the scale matters
    pose = alone[0]
    np.testing.assert_array_equal(
        g(action, seed=4, steps=STEPS, keypose_3d=pose),
        Generator.from_checkpoint(ckpts["control"])(action, seed=4, steps=STEPS, keypose_3d=pose))
    # the same std: no statistics of its own
    assert Generator.from_checkpoint(ckpts["attached"]).text_stats is None


def test_the_command_line_attaches_and_reports_errors_in_one_line(ckpts, tmp_path, capsys):
    out = tmp_path / "cli.pt"
    main(["attach-text", str(ckpts["control"]), str(ckpts["text"]), "--out", str(out)])
    assert "attached" in capsys.readouterr().out
    assert Generator.from_checkpoint(out).text_model is not None
    with pytest.raises(SystemExit) as e:
        main(["attach-text", str(ckpts["base"]), str(ckpts["text"])])
    assert e.value.code == 2 and "give a control checkpoint" in capsys.readouterr().err


def test_a_corrupt_text_model_entry_is_refused_by_name(ckpts, tmp_path):
    ck = load_checkpoint(ckpts["attached"])
    name = next(k for k, v in ck["text_model"]["model"].items() if v.is_floating_point())
    ck["text_model"]["model"][name] = torch.full_like(ck["text_model"]["model"][name], np.nan)
    bad = save_checkpoint(tmp_path / "nan.pt", ck)
    with pytest.raises(ValueError, match=f"non-finite weights.*{name}"):
        Generator.from_checkpoint(bad)
    ck["text_model"] = {"model": {}}
    with pytest.raises(ValueError, match="without a 'model_config'"):
        Generator.from_checkpoint(save_checkpoint(tmp_path / "cfg.pt", ck))


def test_evaluate_samples_text_only_with_the_text_model_unless_told_not_to(ckpts, tmp_path):
    """`evaluate`'s text-only row comes from the attached text model; `--no-text-model` gives
    the control model's base (Sketch2Anim's text only); the controlled rows are the same either
    way, and rows.json records which."""
    import json

    from physlab.motion import evaluate as E

    runs = {}
    for flag in ([], ["--no-text-model"]):
        out = tmp_path / ("base" if flag else "text")
        runs[bool(flag)] = E.main(["--control", str(ckpts["attached"]), "--windows", "2",
                                   "--steps", "2", "--no-progress", "--no-evaluator",
                                   "--no-body-constraints", "--out", str(out), *flag])
        assert json.loads((out / "rows.json").read_text())["config"]["text_model"] == (not flag)
    text, base = runs[False], runs[True]
    assert text["text only"]["trajectory_error_3d"] != base["text only"]["trajectory_error_3d"]
    row = "keypose + trajectory"
    assert text[row]["trajectory_error_3d"] == base[row]["trajectory_error_3d"]


def test_a_text_model_carries_its_own_text_guidance(ckpts, tmp_path, capsys):
    """attach-text --guidance W stores W with the text model: text-only requests default to
    it (the same clip as asking for W), controlled ones keep CONTROL_TEXT_GUIDANCE, and
    without a text model (or without W) the default is TEXT_GUIDANCE; evaluate and the
    adherence check use it unless given --guidance, and bad values are refused by name."""
    import json

    from physlab.motion import evaluate as E
    from physlab.motion.sampling import CONTROL_TEXT_GUIDANCE, TEXT_GUIDANCE

    out = tmp_path / "w.pt"
    main(["attach-text", str(ckpts["control"]), str(ckpts["text"]), "--out", str(out),
          "--guidance", "4.5"])
    assert "w = 4.5" in capsys.readouterr().out
    assert load_checkpoint(out)["text_model"]["guidance"] == 4.5
    g = Generator.from_checkpoint(out)
    assert g.text_guidance == 4.5 != TEXT_GUIDANCE
    assert Generator.from_checkpoint(ckpts["attached"]).text_guidance == TEXT_GUIDANCE
    action = g.text_cache.texts[0]
    got = g(action, seed=2, steps=STEPS)
    np.testing.assert_array_equal(got, g(action, seed=2, steps=STEPS, guidance_scale=4.5))
    assert np.abs(got - g(action, seed=2, steps=STEPS,
                          guidance_scale=TEXT_GUIDANCE)).max() > 1e-4
    pose = got[0]
    np.testing.assert_array_equal(
        g(action, seed=2, steps=STEPS, keypose_3d=pose),
        g(action, seed=2, steps=STEPS, keypose_3d=pose, guidance_scale=CONTROL_TEXT_GUIDANCE))
    g.text_model = None                              # the base samples: its default
    assert g.text_guidance == TEXT_GUIDANCE
    assert _load(out, "--control", text_model=False).text_guidance == TEXT_GUIDANCE

    res = E.text_adherence(out, contents=("walk", "run"), seeds=1, steps=2, progress=False)
    assert res["guidance"] == 4.5
    assert E.text_adherence(out, contents=("walk",), seeds=1, steps=2, progress=False,
                            guidance=1.0)["guidance"] == 1.0
    E.main(["--control", str(out), "--windows", "1", "--steps", "2", "--no-progress",
            "--no-evaluator", "--no-body-constraints", "--out", str(tmp_path / "ev")])
    assert json.loads((tmp_path / "ev" / "rows.json").read_text())["config"]["guidance"] == 4.5

    for bad in (-1.0, float("nan"), 1e6, True, "5", (1.0, 2.0, 3.0), (1.0, -2.0)):
        with pytest.raises(ValueError, match=r"guidance must be a number .* or a pair"):
            attach_text_model(ckpts["control"], ckpts["text"], tmp_path / "bad.pt",
                              guidance=bad)
    assert not (tmp_path / "bad.pt").exists()
    ck = load_checkpoint(out)
    ck["text_model"]["guidance"] = -3.0
    with pytest.raises(ValueError, match=r"corrupt_w\.pt: text_model\.guidance must be"):
        Generator.from_checkpoint(save_checkpoint(tmp_path / "corrupt_w.pt", ck))


def test_a_guidance_pair_guides_each_half_of_the_noise_levels(ckpts, monkeypatch):
    """guidance_scale=(w_high, w_low): w_high at t >= GUIDANCE_SPLIT * T, w_low below (spied
    on the network calls); (w, w) is the same clip as w; a pair can be the text model's own
    default (attach-text --guidance HIGH,LOW)."""
    from physlab.motion.sampling import GUIDANCE_SPLIT

    g = Generator.from_checkpoint(ckpts["attached"])
    action = g.text_cache.texts[0]
    np.testing.assert_array_equal(g(action, seed=1, steps=STEPS, guidance_scale=(3.0, 3.0)),
                                  g(action, seed=1, steps=STEPS, guidance_scale=3.0))
    pair = g(action, seed=1, steps=STEPS, guidance_scale=(6.0, 2.0))
    for w in (6.0, 2.0):
        assert np.abs(pair - g(action, seed=1, steps=STEPS, guidance_scale=w)).max() > 1e-4
    seen, predict = [], Generator._predict

    def spy(self, x, t, a, cond, w, w_c=1.0):
        seen.append((int(t[0]), w))
        return predict(self, x, t, a, cond, w, w_c)

    monkeypatch.setattr(Generator, "_predict", spy)
    g(action, seed=1, steps=STEPS, guidance_scale=(6.0, 2.0))
    T = g.scheduler.num_train_timesteps
    assert len(seen) == STEPS and {w for _, w in seen} == {6.0, 2.0}
    assert all(w == (6.0 if t >= GUIDANCE_SPLIT * T else 2.0) for t, w in seen)
    monkeypatch.undo()

    out = ckpts["dir"] / "pair.pt"
    main(["attach-text", str(ckpts["control"]), str(ckpts["text"]), "--out", str(out),
          "--guidance", "6,2"])
    h = Generator.from_checkpoint(out)
    assert h.text_guidance == (6.0, 2.0)
    np.testing.assert_array_equal(h(action, seed=1, steps=STEPS),
                                  h(action, seed=1, steps=STEPS, guidance_scale=(6.0, 2.0)))
    with pytest.raises(ValueError, match=r"guidance_scale must be .* or a pair"):
        g(action, steps=STEPS, guidance_scale=(6.0, -1.0))


@pytest.mark.parametrize("bad", ["x", "1,2,3", "nan", "-1", "3,", "200"])
def test_a_bad_guidance_argument_is_one_line_naming_the_option(ckpts, tmp_path, capsys, bad):
    with pytest.raises(SystemExit) as e:
        main(["attach-text", str(ckpts["control"]), str(ckpts["text"]), "--out",
              str(tmp_path / "x.pt"), "--guidance", bad])
    err = capsys.readouterr().err
    assert e.value.code == 2 and "--guidance" in err and "HIGH,LOW" in err
    assert not (tmp_path / "x.pt").exists()
