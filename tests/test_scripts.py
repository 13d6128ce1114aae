"""The measurement scripts in scripts/ that the README cites: they run and refuse bad input."""
import importlib.util
from pathlib import Path

import numpy as np
import pytest

SCRIPTS = Path(__file__).resolve().parents[1] / "scripts"


def _load(name):
    spec = importlib.util.spec_from_file_location(name, SCRIPTS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_storyboard_seams_prints_one_row_per_method_and_seed(capsys):
    seams = _load("storyboard_seams")
    seams.main(["concat", "linear", "--seeds", "1"])
    rows = [r for r in capsys.readouterr().out.splitlines()[1:] if r.strip()]
    assert [r.split(" |")[0] for r in rows] == ["concat 0", "linear 0"]
    cut, linear = ([float(v) for v in r.split("|")[1].split()] for r in rows)
    assert len(cut) == len(linear) == 2                      # two junctions in three frames
    assert max(cut) > max(linear)                            # a plain cut jerks most
    assert float(rows[1].split("|")[3]) > 0.005              # linear blends shrink bones
    assert float(rows[0].split("|")[3]) < 1e-3               # one skeleton throughout


@pytest.mark.parametrize("argv, match", [(["wobble"], "unknown join method 'wobble'"),
                                         (["--seeds", "0"], "--seeds must be >= 1")])
def test_storyboard_seams_refuses_bad_input(argv, match, capsys):
    with pytest.raises(SystemExit):
        _load("storyboard_seams").main(argv)
    assert match in capsys.readouterr().err


def test_expert_denoisers_switches_network_at_the_level(real_data, tmp_path):
    """T_S = -1 samples with HI alone, 999 with LO alone, a level between mixes them."""
    import numpy as np
    import torch

    from physlab.motion.sampling import Generator
    from physlab.motion.train import train

    smoke = {"smoke": True, "progress": False, "steps": 2, "num_threads": 1}
    lo = train(stage="base", out=str(tmp_path / "lo.pt"), **smoke)["path"]
    hi = train(stage="base", out=str(tmp_path / "hi.pt"), skip=True, skip_pelvis=False, seed=1,
               **smoke)["path"]
    torch.set_num_threads(1)
    experts = _load("expert_denoisers")
    text = Generator.from_checkpoint(lo).text_cache.texts[0]
    own = {k: Generator.from_checkpoint(p)(text, seed=2, steps=6) for k, p in (("hi", hi),
                                                                               ("lo", lo))}
    got = {ts: experts.switched_generator(hi, lo, ts)(text, seed=2, steps=6)
           for ts in (-1, 500, 999)}
    np.testing.assert_array_equal(got[-1], own["hi"])
    np.testing.assert_array_equal(got[999], own["lo"])
    assert not np.array_equal(got[500], own["hi"]) and not np.array_equal(got[500], own["lo"])


def test_expert_denoisers_refuses_bad_input(capsys):
    with pytest.raises(SystemExit):
        _load("expert_denoisers").main(["a.pt", "b.pt", "1000"])
    assert "T_S must be in -1..999" in capsys.readouterr().err


def test_pelvis_speed_analytic():
    """A pelvis that steps 5 cm forward per frame at 20 fps moves at 1 m/s; sideways steps
    count, height does not."""
    import numpy as np

    x = np.zeros((40, 22, 3))
    x[:, 0, 2] = 0.05 * np.arange(40)
    x[:, 0, 1] = np.sin(np.arange(40))                        # height: ignored
    speed, forward = _load("pelvis_speed_by_level").pelvis_speed(x)
    assert speed == pytest.approx(1.0) and forward == pytest.approx(0.05 * 39)
    x[:, 0, 0] = 0.05 * np.arange(40)                         # and as much sideways
    assert _load("pelvis_speed_by_level").pelvis_speed(x)[0] == pytest.approx(np.sqrt(2))


def test_pelvis_speed_by_level_last_row_is_the_clip(capsys):
    """One row per DDIM step; the last is the returned clip before the body constraints."""
    import torch

    from physlab.motion.sampling import DEFAULT_STEPS, load_generator

    script = _load("pelvis_speed_by_level")
    ckpt = str(Path(__file__).resolve().parents[1] / "data/motion/sketch2anim_control.pt")
    text = "a person waves the right hand"
    script.main([ckpt, text, "--seeds", "1", "--num-threads", "1"])
    rows = [r for r in capsys.readouterr().out.splitlines() if r.startswith("| ")
            and r[2].isdigit()]
    assert len(rows) == DEFAULT_STEPS
    assert int(rows[-1].split("|")[1]) < int(rows[0].split("|")[1])   # high levels first
    torch.set_num_threads(1)
    clip = load_generator(ckpt)(text, seed=0, body_constraints=False)
    speed, _ = script.pelvis_speed(clip)
    assert float(rows[-1].split("|")[2]) == pytest.approx(speed, abs=5e-4)


def test_pelvis_speed_by_level_refuses_bad_input(capsys):
    with pytest.raises(SystemExit):
        _load("pelvis_speed_by_level").main(["x.pt", "--seeds", "0"])
    assert "--seeds must be >= 1" in capsys.readouterr().err


def _smoke_loss(argv, capsys):
    _load("pelvis_step_loss").main(argv)
    line = [r for r in capsys.readouterr().out.splitlines() if r.startswith("stage base:")][-1]
    return float(line.split("loss ")[1].split(",")[0])


def test_pelvis_step_loss_follows_weight_and_levels(real_data, tmp_path, capsys, monkeypatch):
    """A huge weight raises the loss; on a band of levels no window falls in, it changes
    nothing (same seed: same windows, levels and noise)."""
    import physlab.motion.train as train

    plain_fns = {"velocity_loss": train.velocity_loss, "recon_loss": train.recon_loss}
    ckpt = str(Path(__file__).resolve().parents[1] / "data/motion/sketch2anim_control.pt")

    def loss(lam, *levels):
        for name, fn in plain_fns.items():        # the script patches train; undo it each time
            monkeypatch.setattr(train, name, fn)
        return _smoke_loss([str(lam), *levels, "--scale-from", ckpt, "--smoke", "--stage",
                            "base", "--steps", "2", "--num-threads", "1", "--lambda-vel", "4",
                            "--out", str(tmp_path / f"{lam}_{'_'.join(levels)}.pt")], capsys)

    plain = loss(0)
    heavy = loss(1e4)
    assert heavy > 10 * plain
    assert loss(1e4, "--levels", "0", "1") == heavy                   # every level: the default
    assert loss(1e4, "--levels", "0.9999", "1") == plain              # t < 1000: no window


def test_pelvis_step_loss_refuses_bad_levels(capsys):
    with pytest.raises(SystemExit, match="0 <= LO < HI <= 1"):
        _load("pelvis_step_loss").main(["1", "--levels", "0.6", "0.5", "--scale-from",
                                        "x.pt", "--lambda-vel", "4"])


def test_jerk_by_joints_finds_the_jerking_group():
    """A wrist that jerks alone: the arms carry all of the clip's jerk, the other groups none;
    the groups cover every joint once."""
    script = _load("jerk_by_joints")
    groups = script.joint_groups()
    assert sorted(sum(groups.values(), [])) == list(range(22))
    x = np.zeros((2, 40, 22, 3))
    x[:, 20:, 20, 0] = 0.01                                    # the left wrist steps once
    r = script.jerk_by_group(x)
    assert r["arms"] == pytest.approx(r["all"]) and r["all"] > 0
    assert r["legs"] == r["pelvis"] == r["trunk"] == 0
    x[:, :, 0, 2] = 0.05 * np.arange(40)                       # a steady walk adds no jerk
    assert script.jerk_by_group(x)["pelvis"] == pytest.approx(0, abs=1e-12)


def test_jerk_by_joints_refuses_bad_input(capsys):
    with pytest.raises(SystemExit):
        _load("jerk_by_joints").main(["x.pt", "--windows", "0"])
    assert "--windows must be >= 1" in capsys.readouterr().err
