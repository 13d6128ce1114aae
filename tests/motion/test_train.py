"""Tests of physlab.motion.train: losses, conditions, checkpoints (save / load / resume /
corrupt), the smoke runs of both stages on a few Bandai-Namco clips, and DDP with gloo."""
import dataclasses
import os
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from physlab.motion.dataset import (MIRROR_PERMUTATION, TRAJECTORY_JOINTS,
                                    condition_from_window, mirror_text)
from physlab.motion.features import FeatureStats, joints_to_features
from physlab.motion.model import ControlledDenoiser, MotionDenoiser
from physlab.motion.train import (
    PRECISIONS,
    TrainConfig,
    action_weights,
    condition_batch,
    prepare_data,
    control_losses,
    export_weights,
    hash_encoder,
    load_checkpoint,
    load_model,
    save_checkpoint,
    train,
)

from .test_model import _walk

# constant learning rate after one warm-up step, so that a run cut in two equals one run
SMOKE = {"smoke": True, "progress": False, "warmup": 1, "min_lr": 1e-3, "lr": 1e-3}


def _windows(n=4):
    return np.stack([_walk(seed=s) for s in range(n)])                      # (n, 40, 22, 3)


# ----------------------------------------------------------------------------- pure parts


def test_train_config_validation():
    with pytest.raises(ValueError, match="--base-ckpt"):
        TrainConfig(stage="control")
    with pytest.raises(ValueError, match="stage"):
        TrainConfig(stage="finetune")
    with pytest.raises(ValueError, match="steps"):
        TrainConfig(steps=0)
    with pytest.raises(ValueError, match="unknown options"):
        train(stage="base", d_modle=3)


def test_condition_batch_shapes_and_errors():
    w = _windows(3)
    c = condition_batch(w, np.random.default_rng(0))
    assert c["trajectory"].shape == (3, 40, 6, 3) and c["traj_mask"].dtype == torch.bool
    assert c["keypose"].shape == (3, 22, 3) and set(c["key_frame"].tolist()) <= {0, 39}
    k = c["key_frame"]
    assert torch.allclose(c["keypose"], torch.tensor(w, dtype=torch.float32)[torch.arange(3), k])
    with pytest.raises(ValueError, match="22"):
        condition_batch(w[:, :, :21], np.random.default_rng(0))
    bad = w.copy()
    bad[0, 3, 4, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        condition_batch(bad, np.random.default_rng(0))
    with pytest.raises(ValueError, match="no trajectory condition"):
        condition_from_window(w[0], joints=["left_knee"])                  # unknown joint


def test_control_losses_zero_at_ground_truth_and_analytic_shift():
    w = _windows(2)
    f = np.stack([joints_to_features(x) for x in w])                       # (2, 39, 137)
    stats = FeatureStats.from_features(f)
    mean, std = (torch.tensor(v, dtype=torch.float64) for v in (stats.mean, stats.std))
    x0 = torch.tensor(stats.normalize(f))
    cond = {k: v for k, v in condition_batch(w, np.random.default_rng(1)).items()}
    joints = torch.tensor(w)
    l_tr, l_key = control_losses(x0, joints, cond, mean, std)
    assert l_tr < 1e-20 and l_key < 1e-20
    # raise every pelvis height by 0.1 m (column root_height): only the pelvis moves, in
    # every frame (the last frame is frame 38 + velocities); the trajectory loss sees it on
    # the pelvis column only, the root-relative keypose loss on the other 21 joints
    shifted = torch.tensor(f.copy())
    shifted[..., 3] += 0.1
    l_tr, l_key = control_losses((shifted - mean) / std, joints, cond, mean, std)
    m = cond["traj_mask"].double()
    pelvis_share = m[..., 0].sum(1) / m.sum((1, 2))                        # (B,)
    assert TRAJECTORY_JOINTS[0] == 0
    assert torch.allclose(l_tr, (0.01 * pelvis_share).mean())
    assert torch.allclose(l_key, torch.tensor(21 * 0.01, dtype=torch.float64))
    # the guidance decodes x̂₀ once and reads both losses from the joints
    from physlab.motion.guidance import joint_control_losses
    from physlab.motion.model import features_to_joints_torch

    pred = features_to_joints_torch(shifted)
    for got, want in zip(joint_control_losses(pred, joints, cond), (l_tr, l_key)):
        torch.testing.assert_close(got, want)


def test_projected_trajectory_loss_is_the_drawn_error_and_ignores_depth():
    from physlab.motion.align import camera_projections
    from physlab.motion.camera import Camera
    from physlab.motion.guidance import projected_trajectory_loss

    w = _windows(2)
    f = np.stack([joints_to_features(x) for x in w])
    stats = FeatureStats.from_features(f)
    mean, std = (torch.tensor(v, dtype=torch.float64) for v in (stats.mean, stats.std))
    cond = condition_batch(w, np.random.default_rng(1))
    cams = [Camera(0.9, 20, 30), Camera(1.2, 10, -45)]
    proj = camera_projections(torch.tensor([[c.scale, c.pitch, c.yaw, c.roll] for c in cams]))
    for c, P in zip(cams, proj):                          # s R[:2], as Camera.project
        x = np.random.default_rng(0).normal(size=(5, 3))
        np.testing.assert_allclose(x @ P.double().numpy().T, c.project(x), atol=1e-6)
    joints, m = torch.tensor(w), cond["traj_mask"]
    x0 = torch.tensor(stats.normalize(f))
    assert projected_trajectory_loss(x0, joints, m, proj, mean, std) < 1e-20
    # the pelvis raised 0.1 m in every frame: seen as s R[:2] (0, 0.1, 0) on the pelvis column
    shifted = torch.tensor(f.copy())
    shifted[..., 3] += 0.1
    got = projected_trajectory_loss((shifted - mean) / std, joints, m, proj, mean, std)
    share = m[..., 0].double().sum(1) / m.double().sum((1, 2))
    up = torch.stack([(P.double() @ torch.tensor([0, 0.1, 0.0], dtype=torch.float64)).pow(2).sum()
                      for P in proj])
    assert torch.allclose(got, (share * up).mean())
    # a shift along each camera's view direction is invisible in its drawing
    depth = torch.tensor(np.stack([0.3 * c.view_direction for c in cams]))
    moved = joints + depth[:, None, None]
    assert projected_trajectory_loss(x0, moved, m, proj, mean, std) < 1e-12    # float32 P
    assert control_losses(x0, moved, cond, mean, std)[0] > 0.08     # the 3D L_tr sees 0.3 m
    with pytest.raises(ValueError, match="camera must have shape"):
        camera_projections(torch.zeros(2, 3))


def test_velocity_loss_ignores_offsets_and_sees_jitter():
    from physlab.motion.train import velocity_loss

    g = torch.Generator().manual_seed(0)
    x0 = torch.randn(3, 39, 137, generator=g, dtype=torch.float64)
    assert velocity_loss(x0, x0) == 0
    # a per-sequence constant offset has no velocity: no loss
    assert velocity_loss(x0 + torch.randn(3, 1, 137, generator=g, dtype=torch.float64),
                         x0) < 1e-24
    # alternating jitter ±e on every row: every difference is off by ±2e -> loss 4e²
    e = 0.1
    sign = (-1.0) ** torch.arange(39, dtype=torch.float64)
    jitter = x0 + e * sign[None, :, None]
    assert torch.allclose(velocity_loss(jitter, x0), torch.tensor(4 * e**2, dtype=torch.float64))


def test_hash_encoder_is_deterministic_unit():
    e = hash_encoder(["a person walks", "a person runs", "a person walks"])
    assert e.shape == (3, 384) and np.allclose(np.linalg.norm(e, axis=1), 1)
    assert np.array_equal(e[0], e[2]) and not np.allclose(e[0], e[1])


def test_missing_and_corrupt_checkpoints(tmp_path):
    with pytest.raises(FileNotFoundError, match="train one"):
        load_checkpoint(tmp_path / "none.pt")
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"\x80\x02 not a checkpoint")
    with pytest.raises(ValueError, match="corrupt"):
        load_checkpoint(bad)
    other = tmp_path / "other.pt"
    torch.save({"weights": 1}, other)
    with pytest.raises(ValueError, match="not a physlab"):
        load_model(other)


# ----------------------------------------------------------------------------- smoke runs


@pytest.fixture(scope="module")
def base_run(real_data, tmp_path_factory):
    out = tmp_path_factory.mktemp("motion_train") / "base.pt"
    res = train(stage="base", out=str(out), steps=2, **SMOKE)
    return res


def test_base_smoke_checkpoint_contents(base_run):
    ckpt = load_checkpoint(base_run["path"])
    assert ckpt["stage"] == "base" and ckpt["step"] == 2
    assert {"model_config", "train_config", "optimizer", "rng", "feature_stats", "scheduler",
            "text_cache", "param_digests"} <= set(ckpt)
    assert np.isfinite(base_run["loss"])
    loaded = load_model(base_run["path"])
    assert isinstance(loaded["model"], MotionDenoiser) and loaded["step"] == 2
    assert "a person walks" in loaded["text_cache"] or len(loaded["text_cache"]) > 0
    with pytest.raises(ValueError, match="empty"):
        loaded["text_cache"].get("   ")                                  # empty action text


def test_save_load_identical_outputs(base_run, tmp_path):
    a = load_model(base_run["path"])
    copy = save_checkpoint(tmp_path / "copy.pt", load_checkpoint(base_run["path"]))
    b = load_model(copy)
    cfg = a["config"]
    g = torch.Generator().manual_seed(0)
    x = torch.randn(2, cfg.n_frames, cfg.feature_dim, generator=g)
    t = torch.tensor([3, 500])
    e = torch.tensor(a["text_cache"].embeddings[:1]).expand(2, -1)
    with torch.no_grad():
        ya, yb = a["model"](x, t, e), b["model"](x, t, e)
    assert torch.equal(ya, yb)
    half = load_model(export_weights(base_run["path"], tmp_path / "fp16.pt"))
    assert (tmp_path / "fp16.pt").stat().st_size < Path(base_run["path"]).stat().st_size
    with torch.no_grad():
        assert torch.allclose(half["model"](x, t, e), ya, atol=2e-2)


def test_resume_continues_from_saved_step_and_matches_one_run(base_run, tmp_path):
    split = tmp_path / "split.pt"
    save_checkpoint(split, load_checkpoint(base_run["path"]))           # stopped at step 2
    res = train(stage="base", out=str(split), steps=4, **SMOKE)
    assert res["step"] == 4 and load_checkpoint(split)["step"] == 4
    whole = train(stage="base", out=str(tmp_path / "whole.pt"), steps=4, **SMOKE)
    assert res["param_digests"] == whole["param_digests"]               # bit-identical
    again = train(stage="base", out=str(split), steps=4, **SMOKE)       # nothing left to do
    assert again["step"] == 4 and again["trained"] == 0 and res["trained"] == 2
    assert again["loss"] == load_checkpoint(split)["loss"] == res["loss"]   # not NaN
    assert again["param_digests"] == res["param_digests"]
    with pytest.raises(ValueError, match="holds a 'base' checkpoint"):
        train(stage="control", base_ckpt=base_run["path"], out=str(split), steps=5, **SMOKE)


def test_interrupt_writes_a_checkpoint_and_resume_finishes(real_data, tmp_path, monkeypatch):
    calls = []
    real_clip = torch.nn.utils.clip_grad_norm_

    def clip_then_interrupt(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:                           # Ctrl-C during the second step
            raise KeyboardInterrupt
        return real_clip(*args, **kwargs)

    out = tmp_path / "int.pt"
    monkeypatch.setattr(torch.nn.utils, "clip_grad_norm_", clip_then_interrupt)
    with pytest.raises(KeyboardInterrupt):
        train(stage="base", out=str(out), steps=3, checkpoint_every=100, **SMOKE)
    assert load_checkpoint(out)["step"] == 1
    monkeypatch.setattr(torch.nn.utils, "clip_grad_norm_", real_clip)
    assert train(stage="base", out=str(out), steps=3, **SMOKE)["step"] == 3


@pytest.mark.timeout(180)
@pytest.mark.parametrize("sig", ["SIGTERM", "SIGINT"])
def test_a_background_run_stops_on_a_signal_with_a_checkpoint(real_data, tmp_path, sig):
    """`python -m physlab.motion.train ... &` from a script ignores SIGINT (POSIX shells do
    that to background jobs), and `kill PID` sends SIGTERM: both stop the run the way Ctrl-C
    does (:func:`physlab._cli.stop_like_ctrl_c`), with the checkpoint of the last step and
    exit status 130."""
    import signal
    import time

    out = tmp_path / "bg.pt"
    cmd = [sys.executable, "-m", "physlab.motion.train", "--stage", "base", "--smoke",
           "--steps", "100000", "--checkpoint-every", "2", "--no-progress",
           "--num-threads", "1", "--out", str(out)]
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True,
                            cwd=Path(__file__).resolve().parents[2],
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    try:
        deadline = time.monotonic() + 150
        while not out.is_file() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.2)                               # training has begun
        assert out.is_file(), proc.stderr.read() if proc.poll() is not None else "no checkpoint"
        proc.send_signal(getattr(signal, sig))
        err = proc.communicate(timeout=60)[1]
    finally:
        proc.kill()
    assert proc.returncode == 130, err[-2000:]
    assert "interrupted: checkpoint of step" in err, err[-2000:]
    step = int(err.split("interrupted: checkpoint of step")[1].split()[0])
    assert load_checkpoint(out)["step"] == step >= 2


def test_control_smoke(base_run, tmp_path):
    out = tmp_path / "control.pt"
    res = train(stage="control", base_ckpt=str(base_run["path"]), out=str(out), steps=2,
                **SMOKE)
    assert res["step"] == 2 and np.isfinite(res["loss"])
    assert res["n_trainable"] < res["n_params"]
    loaded = load_model(out)
    assert isinstance(loaded["model"], ControlledDenoiser)
    base = load_model(base_run["path"])["model"]
    sd = loaded["model"].base.state_dict()
    assert all(torch.equal(v, sd[k]) for k, v in base.state_dict().items())  # base frozen
    # a control checkpoint as --base-ckpt: its frozen base (another variant on the same base)
    single = train(stage="control", base_ckpt=str(out), out=str(tmp_path / "c2.pt"),
                   single_controlnet=True, steps=1, **SMOKE)
    sd2 = load_model(single["path"])["model"].base.state_dict()
    assert all(torch.equal(v, sd2[k]) for k, v in base.state_dict().items())



def test_control_head_smoke_saves_reloads_aligns_and_guards_its_variant(base_run, tmp_path):
    out = tmp_path / "head.pt"
    res = train(stage="control", base_ckpt=str(base_run["path"]), out=str(out),
                control_head=True, steps=1, **SMOKE)
    assert res["step"] == 1 and np.isfinite(res["loss"])
    model = load_model(out)["model"]
    assert model.control_head is not None
    assert load_model(base_run["path"])["model"] is not None
    with pytest.raises(ValueError, match="control_head=True"):            # resume as another
        train(stage="control", base_ckpt=str(base_run["path"]), out=str(out), steps=2,
              **SMOKE)
    aligned = train(stage="align", base_ckpt=str(out), out=str(tmp_path / "a.pt"), steps=1,
                    **SMOKE)                                # the head comes with the generator
    assert load_model(aligned["path"])["model"].control_head is not None
    with pytest.raises(ValueError, match="--control-head is a part of the ControlNet stage"):
        TrainConfig(stage="base", control_head=True)


def test_double_controlnet_smoke_saves_reloads_and_guards_its_variant(base_run, tmp_path):
    out = tmp_path / "double.pt"
    res = train(stage="control", base_ckpt=str(base_run["path"]), out=str(out),
                double_controlnet=True, steps=1, **SMOKE)
    assert res["step"] == 1 and np.isfinite(res["loss"])
    assert load_checkpoint(out)["double_controlnet"] is True
    model = load_model(out)["model"]
    assert model.double_controlnet and not model.single_controlnet
    with pytest.raises(ValueError, match="double_controlnet=True"):      # resume as another
        train(stage="control", base_ckpt=str(base_run["path"]), out=str(out), steps=2,
              **SMOKE)
    with pytest.raises(ValueError, match="needs the ControlNet \\+ adapter model"):
        train(stage="align", base_ckpt=str(out), out=str(tmp_path / "a.pt"), steps=1, **SMOKE)
    with pytest.raises(ValueError, match="at most one"):
        TrainConfig(stage="control", base_ckpt="b.pt", single_controlnet=True,
                    double_controlnet=True)
    with pytest.raises(ValueError, match="variants of --stage control"):
        TrainConfig(stage="base", double_controlnet=True)


def test_bf16_precision_runs_every_stage_close_to_float32(base_run, tmp_path):
    """--precision bf16 puts the forward passes under bfloat16 autocast: the first step's
    loss moves by bfloat16 rounding only (same seed, same batch), and the weights, optimiser
    and checkpoint stay float32."""
    losses = {}
    for prec in ("fp32", "bf16"):
        res = train(stage="base", out=str(tmp_path / f"b_{prec}.pt"), steps=1, precision=prec,
                    **SMOKE)
        losses[prec] = res["loss"]
    assert losses["bf16"] != losses["fp32"]                           # autocast is on
    assert losses["bf16"] == pytest.approx(losses["fp32"], rel=0.05)
    ckpt = load_checkpoint(tmp_path / "b_bf16.pt")
    assert all(v.dtype == torch.float32 for v in ckpt["model"].values() if v.is_floating_point())
    control = train(stage="control", base_ckpt=str(base_run["path"]), precision="bf16",
                    out=str(tmp_path / "c.pt"), steps=1, **SMOKE)
    align = train(stage="align", base_ckpt=str(control["path"]), precision="bf16",
                  out=str(tmp_path / "a.pt"), steps=1, **SMOKE)
    assert np.isfinite(control["loss"]) and np.isfinite(align["loss"])
    with pytest.raises(ValueError, match="precision must be one of"):
        TrainConfig(stage="base", precision="fp16")


def test_precision_auto_takes_bf16_only_on_a_cpu_with_native_bfloat16(monkeypatch):
    """--precision auto resolves when the config is made, so the checkpoint records what ran:
    bf16 where native_bf16() (oneDNN's AVX512-BF16 / AMX check), fp32 elsewhere."""
    import physlab.motion.train as train_mod

    assert isinstance(train_mod.native_bf16(), bool)
    assert "auto" in PRECISIONS
    for native, want in ((True, "bf16"), (False, "fp32")):
        monkeypatch.setattr(train_mod, "native_bf16", lambda native=native: native)
        cfg = TrainConfig(stage="base", precision="auto")
        assert cfg.precision == want
        assert TrainConfig(**dataclasses.asdict(cfg)).precision == want   # as saved, reloaded
    monkeypatch.undo()
    assert TrainConfig(stage="base", precision="auto").precision == (
        "bf16" if train_mod.native_bf16() else "fp32")


def test_align_smoke_trains_only_the_2d_encoders(base_run, tmp_path):
    control = train(stage="control", base_ckpt=str(base_run["path"]),
                    out=str(tmp_path / "control.pt"), steps=2, **SMOKE)
    out = tmp_path / "align.pt"
    res = train(stage="align", base_ckpt=str(control["path"]), out=str(out), steps=2, **SMOKE)
    assert res["step"] == 2 and np.isfinite(res["loss"])
    loaded = load_model(out)
    model = loaded["model"]
    assert isinstance(model, ControlledDenoiser) and model.has_sketch_encoders
    assert loaded["stage"] == "align"
    n_sketch = sum(p.numel() for n, p in model.named_parameters() if n.startswith("sketch_"))
    assert res["n_trainable"] == n_sketch > 0
    before = load_model(control["path"])["model"].state_dict()
    after = model.state_dict()
    assert all(torch.equal(v, after[k]) for k, v in before.items())        # generator frozen
    res = train(stage="align", base_ckpt=str(control["path"]), out=str(out), steps=3,
                lambda_tr_2d=8.0, **SMOKE)      # resumes, with the 2D term (the shipped recipe)
    assert res["step"] == 3 and np.isfinite(res["loss"])
    assert all(torch.equal(v, load_model(out)["model"].state_dict()[k]) for k, v in before.items())
    ab = train(stage="align", base_ckpt=str(control["path"]), out=str(tmp_path / "ab.pt"),
               steps=1, lambda_recon=0.0, **SMOKE)                          # Table A2 variant
    assert np.isfinite(ab["loss"])
    with pytest.raises(ValueError, match="needs the ControlNet \\+ adapter model"):
        train(stage="align", base_ckpt=str(base_run["path"]), out=str(tmp_path / "x.pt"),
              steps=1, **SMOKE)
    direct = train(stage="control", base_ckpt=str(base_run["path"]), direct_2d=True,
                   out=str(tmp_path / "d2.pt"), steps=1, **SMOKE)          # Table 1 baseline
    assert load_model(direct["path"])["model"].has_sketch_encoders
    with pytest.raises(ValueError, match="direct_2d=True"):
        train(stage="control", base_ckpt=str(base_run["path"]), out=str(tmp_path / "d2.pt"),
              steps=2, **SMOKE)
    with pytest.raises(ValueError, match="--direct-2d trains"):
        TrainConfig(stage="base", direct_2d=True)
    with pytest.raises(ValueError, match="at least one of"):
        TrainConfig(stage="align", base_ckpt="c.pt", lambda_match=0, lambda_recon=0,
                    lambda_contrast=0)
    with pytest.raises(ValueError, match="needs --base-ckpt"):
        TrainConfig(stage="align")
    for bad in ({"stage": "control"}, {"stage": "align", "lambda_recon": 0}):
        with pytest.raises(ValueError, match="--lambda-tr-2d 2.0 is a term of L_recon"):
            TrainConfig(base_ckpt="c.pt", lambda_tr_2d=2.0, **bad)
    with pytest.raises(ValueError, match="lambda_tr_2d must be >= 0"):
        TrainConfig(stage="align", base_ckpt="c.pt", lambda_tr_2d=-1.0)



# ----------------------------------------------------------------------------- DDP


def _free_port():
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            s.bind(("127.0.0.1", 0))
            return s.getsockname()[1]
    except OSError as e:
        pytest.skip(f"cannot bind a local TCP port for gloo: {e}")


@pytest.mark.timeout(180)
@pytest.mark.parametrize("precision", ["fp32", "bf16"])   # bf16: make motion-model on bf16 CPUs
def test_ddp_two_ranks_end_with_identical_parameters(real_data, tmp_path, precision):
    """torchrun with 2 gloo processes, 2 smoke steps; both ranks' parameter digests must be
    equal. Skipped (not failed) if gloo cannot set up its sockets on this machine."""
    out = tmp_path / "ddp.pt"
    env = dict(os.environ, GLOO_SOCKET_IFNAME=os.environ.get("GLOO_SOCKET_IFNAME", "lo"),
               OMP_NUM_THREADS="1")
    cmd = [sys.executable, "-m", "torch.distributed.run", "--nnodes=1", "--nproc_per_node=2",
           "--master_addr=127.0.0.1", f"--master_port={_free_port()}",
           "-m", "physlab.motion.train", "--stage", "base", "--smoke", "--steps", "2",
           "--no-progress", "--num-threads", "1", "--precision", precision, "--out", str(out)]
    proc = subprocess.run(cmd, check=False, env=env, capture_output=True, text=True, timeout=170,
                          cwd=Path(__file__).resolve().parents[2])
    if proc.returncode != 0:
        log = proc.stdout + proc.stderr
        if any(s in log.lower() for s in ("gloo", "connection refused", "address", "bind")):
            pytest.skip(f"gloo process group could not start here: {log[-400:]}")
        pytest.fail(f"torchrun failed:\n{log[-3000:]}")
    ckpt = load_checkpoint(out)
    assert ckpt["world_size"] == 2 and ckpt["step"] == 2
    assert ckpt["train_config"]["precision"] == precision
    d = ckpt["param_digests"]
    assert len(d) == 2 and d[0] == d[1]
    assert len(ckpt["rng"]) == 2


def test_condition_batch_drops_keypose_or_trajectory_never_both():
    import numpy as np

    from physlab.motion.train import condition_batch

    rng = np.random.default_rng(0)
    w = np.cumsum(rng.normal(0, 0.01, (400, 40, 22, 3)), axis=1)
    c = condition_batch(w, np.random.default_rng(1), drop_keypose=0.3, drop_trajectory=0.2)
    key = c["keypose_mask"].numpy()
    traj = c["traj_mask"].numpy().any(axis=(1, 2))
    assert np.all(key | traj)                                       # never both dropped
    assert abs((~key).mean() - 0.3) < 0.07 and abs((~traj).mean() - 0.2) < 0.07
    assert np.all(c["keypose"].numpy()[~key] == 0) and np.all(c["trajectory"].numpy()[~traj] == 0)
    c0 = condition_batch(w[:50], np.random.default_rng(1))
    assert c0["keypose_mask"].all() and c0["traj_mask"].numpy().any(axis=(1, 2)).all()


def test_smooth_basis_needs_x0_prediction(tmp_path):
    from physlab.motion.train import train

    with pytest.raises(ValueError, match="--smooth-basis 8 needs --prediction sample"):
        train(stage="base", smoke=True, progress=False, out=str(tmp_path / "b.pt"),
              representation="absolute", smooth_basis=8, prediction="epsilon")


def test_mirror_augmentation_doubles_the_windows_and_mirrors_the_texts(real_data):
    kw = {"max_clips": 3, "text_encoder": "hash", "progress": False}
    plain = prepare_data(TrainConfig(**kw), representation="absolute")
    both = prepare_data(TrainConfig(mirror=True, **kw), representation="absolute")
    n = len(plain["x0"])
    assert both["x0"].shape == (2 * n, *plain["x0"].shape[1:])
    np.testing.assert_array_equal(both["joints"][:n], plain["joints"])
    np.testing.assert_allclose(both["joints"][n:, ..., 0],
                               -plain["joints"][:, :, list(MIRROR_PERMUTATION), 0])
    texts = [both["texts"][i] for i in both["text_index"][n:]]
    assert texts == [mirror_text(plain["texts"][i]) for i in plain["text_index"]]
    assert dataclasses.asdict(TrainConfig(mirror=True))["mirror"] is True  # saved in the ckpt


def test_turn_augmentation_doubles_the_windows_and_keeps_the_texts(real_data):
    kw = {"max_clips": 3, "text_encoder": "hash", "progress": False}
    plain = prepare_data(TrainConfig(**kw))
    both = prepare_data(TrainConfig(turn_augment=45.0, **kw))
    n = len(plain["x0"])
    assert both["x0"].shape == (2 * n, *plain["x0"].shape[1:])
    np.testing.assert_array_equal(both["joints"][:n], plain["joints"])
    assert not np.allclose(both["joints"][n:], plain["joints"])
    assert [both["texts"][i] for i in both["text_index"][n:]] == \
        [plain["texts"][i] for i in plain["text_index"]]
    for bad in (-1.0, 181.0, float("nan"), True):
        with pytest.raises(ValueError, match="turn_augment"):
            TrainConfig(turn_augment=bad)


def test_action_weights_balance_the_actions():
    acts = ["walk"] * 6 + ["kick"] * 1 + ["bow"] * 3
    uniform = action_weights(acts, 0.0)
    np.testing.assert_allclose(uniform, np.full(10, 0.1))
    equal = action_weights(acts, 1.0)                 # every action drawn equally often
    per_action = {a: equal[[i for i, b in enumerate(acts) if b == a]].sum() for a in set(acts)}
    np.testing.assert_allclose(sorted(per_action.values()), [1 / 3] * 3)
    half = action_weights(acts, 0.5)                  # mass of an action ∝ sqrt(its windows)
    assert half.sum() == pytest.approx(1.0)
    assert half[:6].sum() / half[6] == pytest.approx(6 / np.sqrt(6))
    for bad in (-0.1, 1.5, True, "0.5"):
        with pytest.raises(ValueError, match="balance"):
            action_weights(acts, bad)
    with pytest.raises(ValueError, match="empty"):
        action_weights([], 0.5)
    with pytest.raises(ValueError, match="balance must be in"):
        TrainConfig(balance=2.0)


def test_balanced_sampling_draws_rare_actions_more_often(real_data, tmp_path, monkeypatch):
    """``balance`` reaches the sampler: with balance > 0 the training run draws its batches
    from the windows' action weights, with 0 it keeps its uniform ``randint`` stream."""
    data = prepare_data(TrainConfig(balance=1.0, max_clips=3, text_encoder="hash",
                                    progress=False), representation="absolute")
    w = data["sample_weights"].numpy()
    assert w.shape == (len(data["x0"]),) and w.sum() == pytest.approx(1.0)
    drawn = []
    real_multinomial = torch.multinomial

    def spy(weights, *args, **kwargs):
        drawn.append(weights)
        return real_multinomial(weights, *args, **kwargs)

    monkeypatch.setattr(torch, "multinomial", spy)
    train(stage="base", out=str(tmp_path / "bal.pt"), steps=2, balance=1.0, **SMOKE)
    assert len(drawn) == 2 and all(d.sum().item() == pytest.approx(1.0) for d in drawn)
    drawn.clear()
    train(stage="base", out=str(tmp_path / "uni.pt"), steps=2, **SMOKE)
    assert not drawn


def test_style_drop_trains_the_plain_action_text(real_data, tmp_path, monkeypatch):
    """``style_drop``: every window also knows its action's text without the style adverb;
    with p = 1 every batch is conditioned on those plain texts, with p = 0 on the windows'
    own texts."""
    from physlab.motion.dataset import ACTION_PHRASES, action_text
    from physlab.motion.model import MotionDenoiser

    data = prepare_data(TrainConfig(max_clips=3, text_encoder="hash", progress=False),
                        representation="absolute")
    texts = data["texts"]
    own = [texts[i] for i in data["text_index"]]
    plain = [texts[i] for i in data["plain_index"]]
    assert set(plain) <= {action_text(c) for c in ACTION_PHRASES}   # no adverb
    assert all(o.startswith(p) for o, p in zip(own, plain))          # the same action
    assert any(o != p for o, p in zip(own, plain))                   # these clips have styles
    E = data["text_emb"]
    plain_rows = E[sorted(set(data["plain_index"].tolist()))]
    seen = []
    forward = MotionDenoiser.forward

    def spy(self, x_t, t, text_emb, *args, **kwargs):
        seen.append(text_emb.detach().clone())
        return forward(self, x_t, t, text_emb, *args, **kwargs)

    monkeypatch.setattr(MotionDenoiser, "forward", spy)

    def batches(**kw):
        seen.clear()
        train(stage="base", out=str(tmp_path / f"{len(kw)}.pt"), steps=3, **kw, **SMOKE)
        rows = torch.cat(seen)
        return (torch.cdist(rows, plain_rows).min(1).values < 1e-6).float().mean().item()

    assert batches(style_drop=1.0) == 1.0                            # plain texts only
    assert batches() < 1.0                                           # own texts: styled too
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(ValueError, match="style_drop"):
            TrainConfig(style_drop=bad)


def test_skip_connection_trains_saves_and_reloads_its_schedule(real_data, tmp_path):
    """A ``--skip`` base trains, and :func:`load_model` restores the skip connection's ᾱ_t
    from the checkpoint's scheduler: the reloaded model gives the trained one's outputs."""
    with pytest.raises(ValueError, match="--skip needs --prediction sample"):
        train(stage="base", out=str(tmp_path / "e.pt"), steps=1, skip=True,
              prediction="epsilon", smooth_basis=0, **SMOKE)
    res = train(stage="base", out=str(tmp_path / "skip.pt"), steps=2, skip=True, snr_cap=10.0,
                **SMOKE)
    a = load_model(res["path"])
    assert a["config"].skip and a["model"].skip_scale.numel() == a["config"].max_timesteps
    np.testing.assert_allclose(a["model"].skip_scale.double() ** 2,
                               a["scheduler"].alphas_cumprod, rtol=1e-6)
    cfg = a["config"]
    x = torch.randn(2, cfg.n_frames, cfg.feature_dim, generator=torch.Generator().manual_seed(0))
    e = torch.tensor(a["text_cache"].embeddings[:1]).expand(2, -1)
    t = torch.tensor([0, 999])
    with torch.no_grad():
        y = a["model"](x, t, e)
        b = load_model(res["path"])["model"]
        torch.testing.assert_close(b(x, t, e), y)
    ctrl = train(stage="control", base_ckpt=res["path"], out=str(tmp_path / "c.pt"), steps=1,
                 **SMOKE)
    c = load_model(ctrl["path"])["model"]
    assert c.base.config.skip and c.base.skip_scale.numel() == cfg.max_timesteps


def test_paths_are_stored_as_strings():
    """A ``Path`` given for a path option is stored as ``str`` (a checkpoint holding a
    ``PosixPath`` would be refused by the weights-only loader)."""
    cfg = TrainConfig(stage="control", base_ckpt=Path("runs/base.pt"), out=Path("c.pt"),
                      text_cache=Path("cache.npz"), data_root=Path("data"))
    assert all(type(getattr(cfg, k)) is str
               for k in ("base_ckpt", "out", "text_cache", "data_root"))


def test_recon_loss_weights_low_noise_levels_up_to_the_cap():
    """``snr_cap = 0`` is the plain MSE; with a cap each window's MSE is weighted by
    ``min(1 / (1 − ᾱ_t), cap)``: 1 at the noisiest level, the cap near t = 0."""
    from physlab.motion.diffusion import NoiseScheduler, SchedulerConfig
    from physlab.motion.train import recon_loss

    sched = NoiseScheduler(SchedulerConfig())
    g = torch.Generator().manual_seed(0)
    out, target = torch.randn(3, 4, 5, generator=g), torch.randn(3, 4, 5, generator=g)
    t = torch.tensor([0, 500, 999])
    mse = ((out - target) ** 2).mean(dim=(1, 2))
    assert torch.allclose(recon_loss(out, target, t, sched), mse.mean())
    abar = sched.alphas_cumprod[t]
    w = torch.minimum(1 / (1 - abar), torch.tensor(10.0, dtype=torch.float64)).float()
    assert torch.allclose(recon_loss(out, target, t, sched, 10.0), (w * mse).mean())
    assert w[0] == 10.0 and 1.0 < w[2] < 1.01             # capped near 0, ~1 at the noisiest
    with pytest.raises(ValueError, match="snr_cap"):
        TrainConfig(snr_cap=0.5)
    with pytest.raises(ValueError, match="snr_cap"):
        TrainConfig(snr_cap=5.0, prediction="epsilon")


def test_cli_says_when_a_rerun_has_nothing_left_to_train(base_run, tmp_path, capsys):
    """`make motion-model` reruns every stage; a finished one must not print `loss nan`."""
    from physlab.motion.train import main

    done = tmp_path / "done.pt"
    save_checkpoint(done, load_checkpoint(base_run["path"]))               # step 2
    res = main(["--stage", "base", "--out", str(done), "--steps", "2", "--smoke",
                "--no-progress"])
    out = capsys.readouterr().out
    assert res["trained"] == 0 and "nothing left to train" in out and "nan" not in out, out


def test_pelvis_scale_divides_the_path_std_only(real_data, tmp_path, capsys):
    """``pelvis_scale`` F: the statistics of the pelvis x and z are the data's std / F (the
    features themselves F times larger), every other column as before; a control stage on
    that base keeps them; bad values and the relative representation are refused."""
    from physlab.motion.features import ABS_FEATURE_GROUPS

    cfg = {"max_clips": 3, "text_encoder": "hash", "progress": False}
    plain = prepare_data(TrainConfig(**cfg), representation="absolute")
    finer = prepare_data(TrainConfig(pelvis_scale=4, **cfg), representation="absolute")
    path = [ABS_FEATURE_GROUPS["pelvis"].start, ABS_FEATURE_GROUPS["pelvis"].start + 2]
    np.testing.assert_allclose(finer["stats"].std[path], plain["stats"].std[path] / 4)
    np.testing.assert_array_equal(np.delete(finer["stats"].std, path),
                                  np.delete(plain["stats"].std, path))
    np.testing.assert_allclose(finer["x0"][..., path], 4 * plain["x0"][..., path], rtol=1e-5,
                               atol=1e-5)
    base = train(stage="base", out=str(tmp_path / "b.pt"), steps=1, pelvis_scale=4,
                 representation="absolute", **SMOKE)["path"]
    std = load_checkpoint(base)["feature_stats"]["std"]
    ctrl = train(stage="control", base_ckpt=str(base), out=str(tmp_path / "c.pt"), steps=1,
                 pelvis_scale=2, **SMOKE)["path"]
    np.testing.assert_array_equal(load_checkpoint(ctrl)["feature_stats"]["std"], std)
    assert "--pelvis-scale 2 ignored" in capsys.readouterr().err
    for bad in (0.0, -1.0, float("nan"), 1000.0):
        with pytest.raises(ValueError, match="pelvis_scale must be"):
            TrainConfig(pelvis_scale=bad)
    with pytest.raises(ValueError, match="needs the 'absolute' representation"):
        prepare_data(TrainConfig(pelvis_scale=4, **cfg), representation="relative")


def test_pelvis_loss_weight_weights_the_path_columns_of_both_losses():
    """``column_weights``: 1 everywhere but the pelvis x and z; the reconstruction and
    velocity losses with them are the column-weighted means (a path error of e counts
    w·e² / D), and an error elsewhere counts as before; bad weights are refused."""
    from physlab.motion.diffusion import NoiseScheduler, SchedulerConfig
    from physlab.motion.features import ABS_PELVIS
    from physlab.motion.train import column_weights, recon_loss, velocity_loss

    assert column_weights(70, 1.0) is None
    w = column_weights(70, 0.25)
    path = [ABS_PELVIS.start, ABS_PELVIS.start + 2]
    assert w.shape == (70,) and torch.all(w[path] == 0.25) and w.sum() == 70 - 2 * 0.75
    sched = NoiseScheduler(SchedulerConfig())
    t = torch.tensor([0, 999])
    target = torch.zeros(2, 40, 70)
    on_path, elsewhere = target.clone(), target.clone()
    on_path[..., path[0]] = 2.0
    elsewhere[..., path[0] + 1] = 2.0                                      # the pelvis height
    for cap in (0.0, 10.0):
        plain = recon_loss(on_path, target, t, sched, cap)
        assert torch.allclose(recon_loss(on_path, target, t, sched, cap, w), 0.25 * plain)
        assert torch.allclose(recon_loss(elsewhere, target, t, sched, cap, w),
                              recon_loss(elsewhere, target, t, sched, cap))
    ramp = target.clone()
    ramp[..., path[1]] = torch.arange(40.0)                               # z moves 1 per frame
    assert torch.allclose(velocity_loss(ramp, target, w), 0.25 * velocity_loss(ramp, target))
    assert torch.allclose(velocity_loss(ramp, target), torch.tensor(1 / 70))
    for bad in (0.0, -1.0, float("nan"), 1000.0):
        with pytest.raises(ValueError, match="pelvis_loss_weight must be"):
            TrainConfig(pelvis_loss_weight=bad)


def _make_recipe(target):
    """The `physlab.motion.*` commands that `make -n TARGET` would run, as argv lists."""
    import shlex
    import shutil

    if shutil.which("make") is None:
        pytest.skip("make is not installed")
    root = Path(__file__).resolve().parents[2]
    out = subprocess.run(["make", "-n", "-s", "--no-print-directory", target,
                          "STAMP=Makefile"],                # never (re)install .venv here
                         cwd=root, capture_output=True, text=True, check=True).stdout
    cmds = []
    for line in out.replace("\\\n", " ").splitlines():
        argv = shlex.split(line)
        if "-m" in argv and argv[argv.index("-m") + 1].startswith("physlab.motion."):
            i = argv.index("-m")
            cmds.append(argv[i + 1:])
    return cmds


def test_quick_recipe_is_motion_models_first_stages_with_fewer_steps():
    """`make motion-model-quick` (README: retraining in 90 min) must stay the recipe of issue
    12's four models in `make motion-model` — the same evaluator and base, the control stage
    without its keypose continuations and the single ControlNet with at most as many steps —
    every other flag equal; every train command parses."""
    from physlab.motion.train import _parser

    def no_paths(argv):
        paths = {i + 1 for i, a in enumerate(argv) if a in ("--text-cache", "--out", "--export")}
        return [a for i, a in enumerate(argv) if i not in paths]

    def parse(argv):
        return vars(_parser().parse_args(argv[1:]))

    full = _make_recipe("motion-model")
    quick = _make_recipe("motion-model-quick")
    assert [c[:2] for c in quick] == [["physlab.motion.evaluator", "train"]] + \
        [["physlab.motion.train", "--num-threads"]] * 3 + [["physlab.motion.evaluate", "--control"]]
    full_evaluator = [c for c in full if c[0] == "physlab.motion.evaluator"]
    assert no_paths(quick[0]) == no_paths(full_evaluator[0])
    quick_train = [parse(c) for c in quick if c[0] == "physlab.motion.train"]
    full_train = [parse(c) for c in full if c[0] == "physlab.motion.train"]
    # base (same steps), first control stage and single ControlNet (at most as many)
    assert quick_train[0]["steps"] == full_train[0]["steps"]
    ignore = {"steps", "out", "base_ckpt", "export", "text_cache"}
    for q, f in zip(quick_train, [full_train[0], full_train[1], full_train[4]], strict=True):
        assert q["steps"] <= f["steps"], (q, f)
        assert {k: v for k, v in q.items() if k not in ignore} == \
            {k: v for k, v in f.items() if k not in ignore}, (q, f)
    assert full_train[4]["single_controlnet"] and full_train[5]["stage"] == "align"
